r"""The rails' bands where the data see nothing: a floor on the prior's scale there.

The rails' prior ``θ ~ N(0, (λΩ)⁻¹)`` has one scale, chosen by the marginal likelihood from the
content the data *see* (:mod:`.weight`); its shape (curvature plus a small amplitude term)
extrapolates that scale to the wavelengths the layout cannot see (around the carriage spacing,
where pitch and yaw cancel). There the posterior is the prior, and its σ says "as small as the
visible content's smoothness suggests" — a guess the data cannot check. Seen: the wrong-structure
case measured with the planned layout came back 16/26 % off with ±2σ coverage 85/74 % per plane,
its content at 285–363 mm undetermined.

**The directions the data do not determine.** In the generalised eigenbasis of the data's
information ``D = J̃ᵀJ̃`` (nuisances projected out) and the prior's precision ``P = λΩ``,
``D v_i = μ_i P v_i``, ``v_iᵀPv_i = 1``, the posterior variance of the coordinate
``a_i = v_iᵀPθ`` is ``1/(1 + μ_i)`` (prior: 1) and its filter factor ``μ_i/(1 + μ_i)``.
Undetermined: filter factor below :data:`THRESHOLD` (½, the identifiability report's) and a
wavelength — read off the direction's curvature over its amplitude, a sinusoid's
``∫e''² / ∫e² = (2π/L)⁴`` — of at least :data:`MIN_WAVELENGTH_KNOTS` knot spacings: shorter
content is the stated short-wave waviness' (``waviness=``), not resolved by the knots.

**The floor** (per plane ``p``, a hierarchical scale): the content these directions carry has an
unknown scale ``τ²`` (its mean square over the plane's two profiles). The data bound it only
from outside: at least ``E_p``, what the prior extrapolates (``Σ_i m_{ip}``, ``m_{ip}`` the
mean square that ``v_i`` puts into plane ``p``), at most ``R_p²``, the mean square of everything
the fit found in that plane — a band the layout cannot see holding as much as all the content
it sees. With a scale-invariant (log-uniform) hyperprior on ``τ²`` over ``[E_p, R_p²]`` the
marginal variance of that content is

.. math::  V_p = \frac{R_p² − E_p}{\ln(R_p²/E_p)},

so the prior over the undetermined directions is widened by ``g_p = V_p/E_p ≥ 1`` in each plane
(each plane's coefficients scaled by ``√g_p``) and their posterior taken under that prior,
``(T_a⁻¹ + diag μ)⁻¹`` in the coordinates ``a`` (``T_a`` the widened prior there); the
covariance gains the positive part of its difference from the posterior under the chosen
prior, ``(I + diag μ)⁻¹`` (never lowered). Where the prior's extrapolation is already as large
as the visible content (``E_p ≥ R_p²``, ``g_p = 1``) nothing changes. Only the σ change, never
the profiles.
"""

import dataclasses

import numpy as np

#: Filter factor below which a direction is undetermined (the identifiability report's).
THRESHOLD = 0.5
#: Shortest wavelength (knot spacings) of a direction the floor widens; shorter content is the
#: stated waviness' (:func:`~.fit.fit_rails`, ``waviness=``).
MIN_WAVELENGTH_KNOTS = 4.0


@dataclasses.dataclass(frozen=True)
class Floor:
    """What :func:`undetermined_floor` found. extra: ``(n_θ, n_θ)`` covariance to add (µm²);
    n_directions: the undetermined directions widened; wavelengths_m: their wavelengths;
    factor: ``g_p`` per plane (vertical, horizontal); prior_rms_um, visible_rms_um: ``√E_p``,
    ``R_p`` per plane; band_rms_um: ``√V_p``."""

    extra: np.ndarray
    n_directions: int
    wavelengths_m: np.ndarray
    factor: np.ndarray
    prior_rms_um: np.ndarray
    visible_rms_um: np.ndarray
    band_rms_um: np.ndarray

    def note(self) -> str:
        """One line for the log and the fit's message."""
        if not self.n_directions:
            return ""
        lo, hi = 1e3 * self.wavelengths_m.min(), 1e3 * self.wavelengths_m.max()
        return (f"{self.n_directions} rail direction(s) the data do not determine ({lo:.0f}–"
                f"{hi:.0f} mm): their σ not set by the visible content's prior alone but by a "
                "scale between it and the visible content (vertical, horizontal: "
                + ", ".join(f"{a:.2g} → {b:.2g} µm RMS" for a, b in
                            zip(self.prior_rms_um, self.band_rms_um)) + ")")


def _content(basis, Z, vecs, n_grid: int = 201) -> np.ndarray:
    """Mean square (µm², per unit coordinate) that each column of ``vecs`` (θ, µm) puts into
    each plane, over both rails: ``(n_vecs, 2 planes)``."""
    B = basis.matrix(basis.grid(n_grid))
    n = basis.per_profile
    c = (Z @ vecs).reshape(2, 2, n, -1)  # rail, plane, coefficient, vector
    e = np.einsum("sk,rpkv->rpsv", B, c)
    return np.mean(e**2, axis=(0, 2)).T


def wavelengths(basis, Z, Om_curv, Om_amp, vecs) -> np.ndarray:
    """The wavelength (m) of each column of ``vecs`` (θ): a sinusoid of wavelength ``L`` has
    ``∫e''² / ∫e² = (2π/L)⁴``, and ``θᵀΩ_ampθ`` holds ``∫e²/ℓ⁴`` (:mod:`.basis`)."""
    ell = basis.end - basis.start
    curv = np.einsum("iv,ij,jv->v", vecs, Om_curv, vecs)
    amp = np.einsum("iv,ij,jv->v", vecs, Om_amp, vecs) * ell**4
    k = (np.maximum(curv, 1e-300) / np.maximum(amp, 1e-300)) ** 0.25
    return 2 * np.pi / k


def undetermined_floor(J_theta, prior, basis, Z, Om_curv, Om_amp, coeffs_um) -> Floor:
    """The covariance (µm², ``(n_θ, n_θ)``) to add to the rails' posterior so that the
    undetermined directions carry the hierarchical floor of the module docstring.

    Arguments:
        J_theta: ``(N, n_θ)`` whitened Jacobian in the rail unknowns, nuisances projected out.
        prior: ``λΩ`` ``(n_θ, n_θ)``.
        basis, Z: the knot grid and ``c = Zθ``. Om_curv, Om_amp: the prior's two matrices
        (λ, κ excluded). coeffs_um: the fitted ``θ`` (µm).
    """
    nt = prior.shape[0]
    w, Lv = np.linalg.eigh(0.5 * (prior + prior.T))
    Linv = Lv / np.sqrt(np.maximum(w, 1e-300 * w.max()))  # P^{-1/2}: columns v with vᵀPv = 1
    D = Linv.T @ (J_theta.T @ J_theta) @ Linv
    mu, U = np.linalg.eigh(0.5 * (D + D.T))
    V = Linv @ U  # D v = μ P v, vᵀPv = 1
    filt = mu / (1.0 + mu)
    lam_w = wavelengths(basis, Z, Om_curv, Om_amp, V)
    sel = (filt < THRESHOLD) & (lam_w >= MIN_WAVELENGTH_KNOTS * basis.spacing)
    zero = np.zeros(2)
    fitted = _content(basis, Z, np.asarray(coeffs_um, float)[:, None])[0]  # R_p²
    if not np.any(sel):
        return Floor(np.zeros((nt, nt)), 0, np.zeros(0), np.ones(2), zero,
                     np.sqrt(fitted), zero)
    Vs = V[:, sel]
    m = _content(basis, Z, Vs)  # (n_sel, 2): each direction's mean square per plane
    E = m.sum(axis=0)
    R2 = np.maximum(fitted, E)
    with np.errstate(divide="ignore", invalid="ignore"):
        Vp = np.where(R2 > E * (1 + 1e-9), (R2 - E) / np.log(R2 / np.where(E > 0, E, 1.0)), E)
    g_plane = np.where(E > 0, Vp / np.where(E > 0, E, 1.0), 1.0)
    # the prior over these directions, each plane's coefficients scaled by √g_p (a scaling per
    # profile keeps the gauge: zero means, and a common slope scaled alike on both rails)
    n = basis.per_profile
    d = np.sqrt(np.repeat(np.tile(g_plane, 2), n))  # profiles: r1 v, r1 h, r2 v, r2 h
    T = Z.T @ (d[:, None] * (Z @ Vs))  # (n_θ, n_sel): θ of the scaled directions
    K = (prior @ Vs).T @ T  # a = V_sᵀPθ of the scaled directions: the floor's prior K Kᵀ
    M = np.diag(mu[sel])  # the data's (small) information in a
    widened = K @ np.linalg.solve(np.eye(len(M)) + K.T @ M @ K, K.T)  # (Ta⁻¹ + M)⁻¹
    w_, U_ = np.linalg.eigh(0.5 * (widened + widened.T) - np.diag(1.0 / (1.0 + mu[sel])))
    add = (U_ * np.maximum(w_, 0.0)) @ U_.T  # positive part: never narrowed
    extra = Vs @ add @ Vs.T
    return Floor(0.5 * (extra + extra.T), int(sel.sum()), lam_w[sel], g_plane, np.sqrt(E),
                 np.sqrt(fitted), np.sqrt(Vp))
