r"""The regularisation weight λ of the rail profiles' smoothness prior.

The linearised, whitened problem: data ``y`` (``N'`` values after the channel zeros and the other
unpenalised nuisance terms are projected out), ``y ≈ J θ + e``, ``e ~ N(0, s² I)``, with the
smoothness prior ``θ ~ N(0, (s²/λ) Ω⁻¹)`` (:mod:`.basis`: curvature plus a small amplitude
term, so ``Ω`` is positive definite). With ``Ω = LLᵀ`` and the thin SVD ``J L⁻ᵀ = U S Vᵀ``
(singular values ``s_i``, ``b = Uᵀy``, ``y_⊥`` the part of ``y`` outside ``U``) everything is a
closed form in λ, exact for any λ and never ill-conditioned:

- filter factors ``f_i = s_i² / (s_i² + λ)``, effective parameters ``edf = Σ f_i ∈ [0, rank J]``;
- residual ``‖r_λ‖² = ‖y_⊥‖² + Σ (1 − f_i)² b_i²``;
- **marginal likelihood** (type-II maximum likelihood, "REML" in the smoothing-spline literature;
  the default) with the noise scale ``s²`` profiled out:

  .. math::  -2\log p(y\,|\,λ) = N' \log Q(λ) + \sum_i \log(1 + s_i²/λ),\qquad
             Q(λ) = ‖y_⊥‖² + \sum_i \frac{λ}{s_i² + λ} b_i²;

- **GCV** (generalised cross-validation): ``N'‖r_λ‖² / (N' − edf)²``.

Why the marginal likelihood by default. Both need no trust in the stated σ (the scale ``s²`` is
profiled out). GCV has a known failure: when the data determine few directions (one
interferometer, pitch and yaw only) its minimum runs to λ → 0, where the undetermined directions
are left to round-off (seen: λ = 3.6e-18, negative degrees of freedom). The marginal likelihood
has the log-determinant term, which grows without bound as λ → 0 for every direction the data
touch, so its minimum stays interior; it is also less variable than GCV and prone to
over- rather than under-smoothing (Wahba 1985, Ann. Stat. 13, 1378; Reiss & Ogden 2009,
J. R. Stat. Soc. B 71, 505), and it is the λ under which the posterior bands are the Bayesian
bands of a prior whose scale the data chose. λ is searched over ``λ₀·10^[-12, 6]`` (``λ₀`` the
mean ``s_i²``), capped at :func:`detectable_weight`; a minimum on the edge of that range is
reported (``at_bound``).

**The prior is never narrower than the data could detect.** The prior predicts the rails' signal
in the whitened data ``Jθ`` with the expected energy ``E‖Jθ‖² = (s²/λ)·tr(J̃ᵀJ̃) =
(s²/λ)·Σ s_i²``. A λ above ``λ_max = Σ s_i²`` claims rails whose whole signal, summed over every
datum, stays below one stated σ² — rails the data could not see at their stated noise. Data
that show nothing (constant channels, round-off after the channel zeros: the profiled noise scale
runs to zero and the marginal likelihood to λ → ∞) cannot establish that, so λ is never chosen
above ``λ_max``: there the rails' σ are those of a prior just at the data's detection limit,
the σ that data with no signal at the stated noise give, instead of a prior collapsed onto zero.
Data with signal choose λ far below ``λ_max`` (the bundled example: ``~10⁻⁵ λ_max``) and are
not affected.
"""

import dataclasses

import numpy as np

CRITERIA = ("ml", "gcv")
_GRID = np.logspace(-12, 6, 145)


@dataclasses.dataclass(frozen=True)
class WeightChoice:
    """The chosen λ and how it was chosen.

    Attributes:
        lam: the weight. criterion: ``"ml"``, ``"gcv"`` or ``"fixed"``. score: the criterion's
            value at ``lam``. edf: effective parameters of the rail unknowns at ``lam``.
        n_eff: data count after the projections. at_bound: the minimum lies on the search
            range's edge. table: ``(λ, score, edf)`` rows tried. kappa: the weight of the
            amplitude term in the prior (:func:`choose_prior`).
    """

    lam: float
    criterion: str
    score: float
    edf: float
    n_eff: int
    at_bound: bool
    table: np.ndarray
    kappa: float = 1.0


class _Spectrum:
    """The whitened problem's SVD (module docstring), from ``J``, ``y``, ``Ω``."""

    def __init__(self, J, y, Omega):
        L = np.linalg.cholesky(Omega + 1e-14 * np.trace(Omega) / len(Omega) * np.eye(len(Omega)))
        Jt = np.linalg.solve(L, J.T).T  # J L^{-T}
        U, s, _ = np.linalg.svd(Jt, full_matrices=False)
        keep = s > 1e-12 * max(s.max(initial=0.0), 1e-300)
        self.s2 = s[keep] ** 2
        self.b = U[:, keep].T @ y
        self.y_perp2 = max(float(y @ y - self.b @ self.b), 0.0)

    # each a function of λ, vectorised: a scalar gives a scalar, an array of λ an array

    def edf(self, lam):
        f = self.s2 / (self.s2 + np.asarray(lam, float)[..., None])
        return np.sum(f, axis=-1)

    def residual2(self, lam):
        f = self.s2 / (self.s2 + np.asarray(lam, float)[..., None])
        return self.y_perp2 + np.sum((1 - f) ** 2 * self.b**2, axis=-1)

    def score(self, lam, criterion, n_eff):
        lam = np.asarray(lam, float)
        if criterion == "gcv":
            return n_eff * self.residual2(lam) / np.maximum(n_eff - self.edf(lam), 1e-9) ** 2
        return ml_score(*self.ml_parts(lam), n_eff)

    def ml_parts(self, lam):
        """The marginal likelihood's two terms at ``λ``: the quadratic form
        ``Q = y_⊥² + Σ λ/(s²+λ) b²`` (``Q/N'`` is the noise variance the profile takes) and
        ``log det(I + λ⁻¹ J̃ᵀJ̃) = Σ log(1 + s²/λ)``."""
        lam = np.asarray(lam, float)
        Q = self.y_perp2 + np.sum(lam[..., None] / (self.s2 + lam[..., None]) * self.b**2,
                                  axis=-1)
        return Q, np.sum(np.log1p(self.s2 / lam[..., None]), axis=-1)


def ml_score(Q, logdet, n_eff):
    """``−2 log p`` of the marginal likelihood from its two terms (:meth:`_Spectrum.ml_parts`),
    the noise scale profiled out: ``N' log Q + log det``."""
    return n_eff * np.log(np.maximum(Q, 1e-300)) + logdet


def project_out(F, *arrays):
    """``(I − QQᵀ)`` applied to each array (rows = data), ``Q`` an orthonormal basis of the
    columns of ``F``; returns the projected arrays and ``rank F``."""
    if F is None or F.shape[1] == 0:
        return (*arrays, 0)
    U, s, _ = np.linalg.svd(F, full_matrices=False)
    Q = U[:, s > 1e-10 * s.max()] if s.size and s.max() > 0 else U[:, :0]
    out = [a - Q @ (Q.T @ a) for a in arrays]
    return (*out, Q.shape[1])


def detectable_weight(sp: "_Spectrum") -> float:
    """``λ_max = Σ s_i² = tr(J̃ᵀJ̃)`` (whitened units): the largest weight whose prior's rails
    still show in the data with at least one stated σ² of signal energy in all (module
    docstring); the weight search never goes above it."""
    return float(np.sum(sp.s2))


def choose_weight(J, y, Omega, n_eff: int, criterion: str = "ml") -> WeightChoice:
    """λ for the whitened linear problem ``y ≈ J θ`` with prior precision ``λΩ``.

    Arguments:
        J: ``(N, n)`` Jacobian of the rail unknowns, nuisance directions already projected out.
        y: ``(N,)`` data to explain (the negated residual at θ = 0), projected alike.
        Omega: ``(n, n)`` penalty matrix (positive definite).
        n_eff: data count after the projections (channel zeros, nuisance terms).
        criterion: ``"ml"`` (marginal likelihood, default) or ``"gcv"``.
    """
    if criterion not in CRITERIA:
        raise ValueError(f"criterion must be one of {CRITERIA}, got {criterion!r}")
    sp = _Spectrum(np.asarray(J, float), np.asarray(y, float), np.asarray(Omega, float))
    if sp.s2.size == 0:
        return WeightChoice(1.0, criterion, float("nan"), 0.0, n_eff, True, np.zeros((0, 3)))
    lam0 = float(np.mean(sp.s2))
    cap = detectable_weight(sp)
    grid = lam0 * _GRID
    grid = np.append(grid[grid < cap], cap)
    scores = sp.score(grid, criterion, n_eff)
    k = int(np.nanargmin(scores))
    at_bound = k in (0, len(grid) - 1)
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    fine = np.geomspace(lo, hi, 21)
    fs = sp.score(fine, criterion, n_eff)
    j = int(np.nanargmin(fs))
    lam = float(fine[j])
    lams = np.concatenate([grid, fine])
    table = np.stack([lams, np.concatenate([scores, fs]),
                      sp.edf(lams)], axis=1)
    return WeightChoice(lam, criterion, float(fs[j]), float(sp.edf(lam)), n_eff, at_bound,
                        table[np.argsort(table[:, 0])])


#: Weights tried for the amplitude term of the prior, relative to the curvature term's
#: normalisation (:func:`choose_prior`).
KAPPAS = tuple(10.0 ** k for k in range(0, 11))


def choose_prior(J, y, Omega_curv, Omega_amp, n_eff: int, criterion: str = "ml") -> WeightChoice:
    """The prior's shape and weight: ``λ(Ω_curv + κ Ω_amp)``.

    With the marginal likelihood, ``κ`` is chosen too, over :data:`KAPPAS`: ``κ`` small gives the
    curvature prior (content falls as wavelength⁴: smooth rails), ``κ`` large a prior nearly
    flat in wavelength. The data choose how much short-wave content to expect from the wavelengths
    they do see, and the wavelengths they cannot see (the carriage-averaging and
    carriage-spacing blind spots) get the σ of that prior instead of the curvature prior's
    near-zero σ. GCV keeps ``κ = 1`` (a second hyperparameter overfits GCV).
    """
    if criterion != "ml":
        return choose_weight(J, y, Omega_curv + Omega_amp, n_eff, criterion)
    best = None
    for kappa in KAPPAS:
        c = choose_weight(J, y, Omega_curv + kappa * Omega_amp, n_eff, criterion)
        if best is None or c.score < best.score:
            best = dataclasses.replace(c, kappa=kappa)
    return best


def fixed_weight(lam: float, J, y, Omega, n_eff: int) -> WeightChoice:
    """A user-given λ, with its effective parameters (for the report)."""
    if not (np.isfinite(lam) and lam > 0):
        raise ValueError(f"lambda must be a finite number > 0, got {lam!r}")
    sp = _Spectrum(np.asarray(J, float), np.asarray(y, float), np.asarray(Omega, float))
    return WeightChoice(float(lam), "fixed", float("nan"), float(sp.edf(lam)), n_eff, False,
                        np.zeros((0, 3)))
