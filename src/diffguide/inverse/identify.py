r"""What the measurements determine: the identifiability report of a :class:`~.fit.RailFit`.

Three views, all on the whitened problem linearised at the solution:

1. **Gauge** — the Jacobian w.r.t. *all* coefficients, applied to each gauge mode (a unit offset
   of one profile; a common unit slope of both rails in a plane): ``‖J g‖ / (‖J‖₂ ‖g‖)`` ≈ 0
   confirms the mode is invisible, and the numerical rank deficiency is compared with the count
   of fixed modes.
2. **Singular values** of the gauge-fixed Jacobian ``J̃`` and the filter factors of the
   regularised solve (eigenvalues ``μ`` of the resolution matrix ``R = (J̃ᵀJ̃ + λΩ)⁻¹J̃ᵀJ̃``):
   ``μ ≈ 1`` data-determined, ``μ ≈ 0`` set by the smoothness prior; ``Σμ`` = effective
   parameters.
3. **Wavelength transfer** per profile combination — the mean and the difference of the two
   rails in each plane (pitch and yaw see mainly the mean; roll mainly the vertical difference):
   a sinusoid of wavelength ``λ`` put into that combination comes back (noise-free, linearised)
   as ``R`` applied to it; the transfer ``T(λ)`` is the recovered fraction, the worse of the two
   phases. ``T < ½`` means undetermined: the fit returns the prior's guess there, and the σ
   band is the prior's. For a *rigid* table on four carriages the blind spots are known in
   closed form: the carriage averages a sinusoid to zero at ``λ = n·p/m``; the two carriages ``l``
   apart cancel in pitch and yaw at ``λ = l/k`` (``sin(πl/λ) = 0``) and in roll at
   ``λ = 2l/(2k+1)`` (``cos(πl/λ) = 0``). The elastic table partly lifts them (the corners see
   single carriages); the table says how much.
"""

import numpy as np

from .basis import PLANES, PROFILES, profile_label

_COMBOS = (("vertical", "mean"), ("vertical", "difference"), ("horizontal", "mean"),
           ("horizontal", "difference"))


def _combo_profiles(plane, kind):
    """Weights of the four profiles for a combination (rail 1, rail 2 in ``plane``)."""
    w = np.zeros(4)
    for k, (rail, pl) in enumerate(PROFILES):
        if pl == plane:
            w[k] = 1.0 if kind == "mean" else (-0.5 if rail == 0 else 0.5)
    return w


def blind_wavelengths(machine, max_wavelength: float) -> dict:
    """The rigid-table blind wavelengths (m) up to ``max_wavelength`` (m).

    Returns:
        ``{"carriage_averaging_m": [n·p/m, m = 1..3], "carriage_spacing_m": l,
        "pitch_yaw_mean_m": [l/k ...], "roll_difference_m": [2l/(2k+1) ...]}``, all in metres
        (``n`` elements at pitch ``p`` per row, ``l`` the carriage spacing).
        :func:`identifiability` reports the same values in mm under ``..._mm`` keys.
    """
    xi = np.asarray(machine.carriage.xi, float)
    n = len(xi)
    p = (xi[-1] - xi[0]) / max(n - 1, 1)
    xc = np.asarray(machine.carriage_x, float)
    l = float(xc.max() - xc.min())
    out = {
        "carriage_averaging_m": [n * p / m for m in range(1, 4)],
        "carriage_spacing_m": l,
        "pitch_yaw_mean_m": [l / k for k in range(1, 20) if l / k <= max_wavelength],
        "roll_difference_m": [2 * l / (2 * k + 1) for k in range(0, 20)
                              if 2 * l / (2 * k + 1) <= max_wavelength],
    }
    return out


def identifiability(fit, machine=None, *, n_wavelengths: int = 40, threshold: float = 0.5) -> dict:
    """The identifiability report of ``fit`` (a JSON-ready dict; lengths in mm, σ in µm).

    Arguments:
        fit: a :class:`~.fit.RailFit`.
        machine: the machine (for the rigid-table blind wavelengths); optional.
        n_wavelengths: wavelengths between twice the knot spacing and twice the rail length.
        threshold: transfer below which a component is called undetermined.
    """
    basis, Z, J = fit.basis, fit.Z, fit.jacobian
    nt = fit.n_theta
    M = J.T @ J
    R_all = np.linalg.solve(M + fit.penalty, M)
    R = R_all[:nt, :nt]  # the rails' resolution, the structure and lead marginalised
    gauge, sv_full = _gauge_report(fit)
    sv = np.linalg.svd(J[:, :nt], compute_uv=False)
    mu = np.clip(np.sort(np.real(np.linalg.eigvals(R)))[::-1], 0.0, 1.0)  # filter factors
    L = basis.end - basis.start
    report = {
        "gauge": gauge,
        "singular_values": {
            "whitened_gauge_fixed": sv.tolist(),
            "condition_number": float(sv[0] / sv[-1]) if sv[-1] > 0 else None,
            "all_coefficients_smallest": sv_full[-8:].tolist(),
        },
        "regularisation": {
            "criterion": {"ml": "marginal likelihood", "gcv": "GCV",
                          "fixed": "given"}[fit.weight.criterion],
            "lambda": fit.lam,
            "lambda_at_search_bound": bool(fit.weight.at_bound),
            "effective_parameters": float(np.trace(R_all)),
            "effective_rail_parameters": float(np.sum(mu)),
            "unknowns": int(Z.shape[1]),
            "data_determined_directions": int(np.sum(mu >= threshold)),
            "prior_determined_directions": int(np.sum(mu < threshold)),
        },
        "wavelengths": _wavelength_transfer(fit, R, n_wavelengths, threshold),
        "profiles": _profile_sigma(fit),
        "knot_spacing_mm": basis.spacing * 1e3,
        "threshold": threshold,
    }
    if machine is not None:
        # blind_wavelengths() is in metres with '_m' keys; the report is in mm, keys and all
        report["rigid_table_blind_wavelengths_mm"] = {
            k.removesuffix("_m") + "_mm": (np.asarray(v) * 1e3).tolist()
            for k, v in blind_wavelengths(machine, 2 * L).items()
        }
    return report


def _gauge_modes(basis):
    """The gauge modes as coefficient vectors: each profile's offset, each plane's common
    slope of both rails (linear functions exactly, on the Greville abscissae)."""
    n = basis.per_profile  # a joint's step is no part of a gauge mode: its entries stay 0
    greville = basis.start + basis.spacing * (np.arange(basis.n_coeffs) - 1.0)
    modes = []
    for k in range(4):
        g = np.zeros(4 * n)
        g[k * n:k * n + basis.n_coeffs] = 1.0
        modes.append((f"offset of {profile_label(k)}", g))
    for plane in PLANES:
        g = np.zeros(4 * n)
        for k, (_, pl) in enumerate(PROFILES):
            if pl == plane:
                g[k * n:k * n + basis.n_coeffs] = greville - greville.mean()
        modes.append((f"common {plane} slope of both rails", g))
    return modes


def _gauge_report(fit):
    """The gauge section (each mode's relative visibility ``‖J g‖ / (‖J‖₂ ‖g‖)`` and the
    numerical null-space dimension) and the singular values of the full Jacobian."""
    Jc = fit.jacobian_full
    norm_J = np.linalg.norm(Jc, 2)
    sv_full = np.linalg.svd(Jc, compute_uv=False)
    rows = []
    for name, g in _gauge_modes(fit.basis):
        vis = float(np.linalg.norm(Jc @ g) / (norm_J * np.linalg.norm(g)))
        rows.append({"mode": name, "relative_visibility": vis, "fixed": name in fit.gauge})
    tol = 1e-8 * sv_full[0]
    rank_def = int(np.sum(sv_full < tol)) + max(Jc.shape[1] - Jc.shape[0], 0)
    return {
        "fixed_modes": list(fit.gauge),
        "modes": rows,
        "numerical_null_space_dim": rank_def,
        "note": "the profiles are reported with each profile's mean zero and, where fixed, "
                "the common slope zero; compare a known truth only after removing the same",
    }, sv_full


def _wavelength_transfer(fit, R, n_wavelengths: int, threshold: float) -> list[dict]:
    """Per profile combination, the transfer ``T(λ)`` of a sinusoid (the worse of two phases)
    through the resolution matrix ``R`` and the undetermined bands (``T < threshold``)."""
    basis, Z = fit.basis, fit.Z
    s = basis.grid(801)
    lams = np.geomspace(2 * basis.spacing, 2 * (basis.end - basis.start), n_wavelengths)
    BZ = np.kron(np.eye(4), basis.matrix(s)) @ Z
    pinv = np.linalg.pinv(BZ)
    combos = []
    for plane, kind in _COMBOS:
        w = _combo_profiles(plane, kind)
        rows = [{"wavelength_mm": float(lam_w * 1e3), "transfer": t}
                for lam_w, t in zip(lams, _transfers(BZ, pinv, R, w, s, lams))]
        bad = [r["wavelength_mm"] for r in rows if r["transfer"] is not None
               and r["transfer"] < threshold]
        combos.append({
            "combination": f"{plane} {kind}" + (" (rail 2 − rail 1)" if kind == "difference"
                                                else " ((rail 1 + rail 2)/2)"),
            "transfer": rows,
            "undetermined_wavelengths_mm": _bands(bad, lams * 1e3),
            "determined": not bad,
        })
    return combos


def _transfers(BZ, pinv, R, w, s, lams) -> list:
    """The recovered fraction of a sinusoid of each wavelength of ``lams`` (m) in the
    combination ``w``, the worse of two phases; None where both phases are gauge modes. Every
    wavelength and phase in one product per step (the sinusoids as the columns of one matrix)."""
    phases = np.array([0.0, 0.5 * np.pi])
    wave = np.sin(2 * np.pi * (s - s.mean()) / np.asarray(lams)[:, None, None]
                  + phases[None, :, None])  # (wavelength, phase, s)
    target = np.concatenate([wi * wave for wi in w], axis=-1).reshape(-1, 4 * len(s)).T
    theta = pinv @ target
    e_in = BZ @ theta
    e_out = BZ @ (R @ theta)
    size = np.einsum("ij,ij->j", e_in, e_in)
    gauge = size < 1e-6 * np.einsum("ij,ij->j", target, target)  # nothing to recover
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(gauge, np.inf, np.einsum("ij,ij->j", e_in, e_out) / size)
    worst = ratio.reshape(len(lams), len(phases)).min(axis=1)
    return [float(v) if np.isfinite(v) else None for v in worst]


def _profile_sigma(fit) -> list[dict]:
    """Per profile: σ RMS and maximum (µm) and the determined ``s`` range (mm), where σ stays
    within twice its median."""
    grid = fit.basis.grid(401)
    _, sig = fit.profiles(grid)
    profiles = []
    for k, (rail, plane) in enumerate(PROFILES):
        sg = sig[rail, PLANES.index(plane)]
        idx = np.flatnonzero(sg <= 2 * np.median(sg))
        profiles.append({
            "profile": profile_label(k),
            "sigma_rms_um": float(np.sqrt(np.mean(sg**2)) * 1e6),
            "sigma_max_um": float(sg.max() * 1e6),
            "determined_s_mm": [float(grid[idx[0]] * 1e3), float(grid[idx[-1]] * 1e3)],
        })
    return profiles


def _bands(bad, all_mm):
    """Group undetermined wavelengths into [lo, hi] bands of consecutive grid values."""
    bands, cur = [], None
    grid = list(all_mm)
    for b in bad:
        i = int(np.argmin(np.abs(np.asarray(grid) - b)))
        if cur is not None and i == cur[1] + 1:
            cur = [cur[0], i]
        else:
            if cur is not None:
                bands.append(cur)
            cur = [i, i]
    if cur is not None:
        bands.append(cur)
    return [[float(grid[a]), float(grid[b])] for a, b in bands]
