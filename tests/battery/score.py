r"""Score a fit against its truth: profile error and ±2σ coverage, gauge removed, ends trimmed.

On a uniform grid ``s`` (:data:`N_GRID` points) over the fitted basis' rail range
``[start, end]``:

1. the gauge is removed from the truth *and* from the fitted profiles exactly as
   :meth:`diffguide.inverse.RailBasis.gauge_fix` does with the fit's ``fix_slope`` (each profile
   less its mean; in a plane whose straightness is not measured, less the two rails' common
   least-squares slope) — on the whole range, because that is the gauge in which the fit reports
   its profiles and their σ: the fit's σ (of its gauge-fixed profiles) is used unchanged
   (removing the gauge again from the fit's own profiles is then an identity up to the
   quadrature of the constraints);
2. only the points inside the range trimmed by :data:`TRIM` (10 %) of its length at each end are
   scored (the ends are seen by few positions and few carriages);
3. per profile (rail 1/2 × vertical/horizontal): the RMS error ``√mean(e_fit − e_true)²``, the
   RMS of the (gauge-fixed) truth, their ratio, the RMS of σ, and the ±2σ coverage — the fraction
   of points with ``|e_fit − e_true| ≤ 2σ``; overall: the same over all four profiles.
"""

import dataclasses

import numpy as np

#: Grid points over the basis range, fraction trimmed at each end.
N_GRID = 401
TRIM = 0.10
PLANES = ("vertical", "horizontal")


@dataclasses.dataclass(frozen=True)
class Score:
    """Per-profile arrays are ``(2 rails, 2 planes [vertical, horizontal])``; lengths in µm.

    Attributes:
        rms_um: RMS error. truth_rms_um: RMS of the gauge-fixed truth. rel: their ratio.
        sigma_rms_um: RMS of the fit's σ. coverage: fraction of points inside ±2σ.
        overall_rms_um, overall_truth_rms_um, overall_rel, overall_sigma_rms_um,
            overall_coverage: over all four profiles together. combination_rel: ``(2 planes,
            2 [mean, half-difference])`` RMS error of the two rails' combination over the
            plane's truth RMS (item 4 of the module docstring). s: the scored grid (m).
    """

    rms_um: np.ndarray
    truth_rms_um: np.ndarray
    rel: np.ndarray
    sigma_rms_um: np.ndarray
    coverage: np.ndarray
    overall_rms_um: float
    overall_truth_rms_um: float
    overall_rel: float
    overall_sigma_rms_um: float
    overall_coverage: float
    combination_rel: np.ndarray
    s: np.ndarray

    @property
    def worst_coverage(self) -> float:
        return float(self.coverage.min())

    @property
    def worst_rel(self) -> float:
        return float(self.rel.max())

    def label(self, r: int, p: int) -> str:
        return f"rail {r + 1} {PLANES[p]}"


def gauge_fixed(basis, s, profiles, fix_slope) -> np.ndarray:
    """``profiles`` ``(2, 2, len(s))`` less the gauge (``RailBasis.gauge_fix``), same shape."""
    return basis.gauge_fix(s, np.reshape(profiles, (4, -1)), fix_slope).reshape(2, 2, -1)


def score_profiles(basis, fix_slope, values, sigma, truth, s) -> Score:
    """Score sampled profiles (m, ``(2, 2, len(s))``, ``s`` uniform over the basis range)."""
    fitted = gauge_fixed(basis, s, values, fix_slope)
    true = gauge_fixed(basis, s, truth, fix_slope)
    lo = basis.start + TRIM * (basis.end - basis.start)
    hi = basis.end - TRIM * (basis.end - basis.start)
    keep = (s >= lo - 1e-12) & (s <= hi + 1e-12)
    err = (fitted - true)[..., keep] * 1e6
    tru = true[..., keep] * 1e6
    sig = np.asarray(sigma)[..., keep] * 1e6
    rms = np.sqrt(np.mean(err**2, axis=-1))
    truth_rms = np.sqrt(np.mean(tru**2, axis=-1))
    inside = np.abs(err) <= 2 * sig
    combination_rel = np.zeros((2, 2))
    for p in range(2):
        plane_rms = np.sqrt(np.mean(tru[:, p] ** 2))
        for k, e in enumerate((0.5 * (err[0, p] + err[1, p]), 0.5 * (err[1, p] - err[0, p]))):
            combination_rel[p, k] = np.sqrt(np.mean((e - e.mean()) ** 2)) / plane_rms
    return Score(
        rms_um=rms,
        truth_rms_um=truth_rms,
        rel=rms / truth_rms,
        sigma_rms_um=np.sqrt(np.mean(sig**2, axis=-1)),
        coverage=inside.mean(axis=-1),
        overall_rms_um=float(np.sqrt(np.mean(err**2))),
        overall_truth_rms_um=float(np.sqrt(np.mean(tru**2))),
        overall_rel=float(np.sqrt(np.mean(err**2)) / np.sqrt(np.mean(tru**2))),
        overall_sigma_rms_um=float(np.sqrt(np.mean(sig**2))),
        overall_coverage=float(inside.mean()),
        combination_rel=combination_rel,
        s=s[keep],
    )


def score_fit(fit, truth, n: int = N_GRID) -> Score:
    """Score ``fit`` (``profiles(s)``, ``basis``, ``fix_slope``) against ``truth(s)`` (m →
    ``(2, 2, len(s))`` m)."""
    s = np.linspace(fit.basis.start, fit.basis.end, n)
    values, sigma = fit.profiles(s)
    return score_profiles(fit.basis, fit.fix_slope, values, sigma, truth(s), s)


def combination_sigma_rel(fit, truth, n: int = N_GRID) -> np.ndarray:
    """The fit's own posterior σ of each combination of the two rails — ``(2 planes, 2 [mean,
    half-difference])``, RMS over the scored range (:data:`TRIM`) — over the plane's truth RMS
    (gauge removed), the denominator of :attr:`Score.combination_rel`: what the data (and the
    prior) leave of each combination, next to what the fit got wrong."""
    basis = fit.basis
    s = np.linspace(basis.start, basis.end, n)
    lo = basis.start + TRIM * (basis.end - basis.start)
    hi = basis.end - TRIM * (basis.end - basis.start)
    keep = (s >= lo - 1e-12) & (s <= hi + 1e-12)
    true = gauge_fixed(basis, s, truth(s), fit.fix_slope)[..., keep]
    B = basis.matrix(s[keep])
    k = basis.n_coeffs
    out = np.zeros((2, 2))
    for p in range(2):
        plane_rms = np.sqrt(np.mean(true[:, p] ** 2))
        for j, sign in enumerate((1.0, -1.0)):  # mean (e₁ + e₂)/2, half-difference (e₂ − e₁)/2
            T = np.zeros((k, 4 * k))  # profile order: rail 1 v, rail 1 h, rail 2 v, rail 2 h
            T[:, p * k:(p + 1) * k] = 0.5 * sign * np.eye(k)
            T[:, (2 + p) * k:(3 + p) * k] = 0.5 * np.eye(k)
            var = np.einsum("sk,kl,sl->s", B, T @ fit.cov @ T.T, B)
            out[p, j] = np.sqrt(np.mean(np.maximum(var, 0.0))) / plane_rms
    return out
