r"""Straightness of the fitted rails (ISO 230-1) with its expanded uncertainty, and a verdict
against a tolerance (ISO 14253-1).

**Straightness.** A profile ``e(s)`` sampled on a grid ``s`` is compared with a reference
straight line; its straightness is the peak-to-valley of the deviations from that line
(ISO 230-1:2012, 3.4.8 and annex A):

- ``"least-squares"`` (the default, the usual choice for the straightness of a measured
  profile): the line minimising ``Σ (e_i − a − b s_i)²``;
- ``"end-point"``: the line through the first and last point.

Either way a profile's offset and slope do not change it, so the fit's gauge (each profile's
mean and the common slope of both rails, which the data cannot see) does not either.

**Uncertainty.** The peak-to-valley is not a linear function of the profile, so its
uncertainty is propagated by sampling the fit's posterior (GUM Supplement 1, the Monte Carlo
method): ``N`` draws of each profile's spline coefficients from ``N(ĉ, Cov c)`` (the fit's
covariance, :attr:`~diffguide.inverse.RailFit.cov`, which holds the structure's uncertainty),
each draw's straightness ``t_j``; the estimate ``t̂`` is the fitted profile's straightness, its
standard uncertainty

.. math::  u = \Bigl(\tfrac1N \sum_j (t_j - t̂)^2\Bigr)^{1/2}

(the spread of the draws *and* their offset from ``t̂``: noise raises a peak-to-valley, so the
draws lie above ``t̂`` on average), and ``U = k u`` with ``k = 2``. The 95 % interval of the
draws (2.5 % and 97.5 % quantiles) is reported beside it. Rail content shorter than the knot
grid resolves (the fit's stated waviness) is not in ``U``.

**Verdict** (ISO 14253-1 decision rules, conformance zone shrunk and non-conformance zone
widened by ``U``): ``"pass"`` where ``t̂ + U ≤ T``, ``"fail"`` where ``t̂ − U > T``, otherwise
``"not decidable"``; ``T`` the stated tolerance.
"""

import numpy as np

from ..inverse.basis import PROFILES

#: The reference lines of :func:`deviations`.
REFERENCES = ("least-squares", "end-point")
#: Coverage factor of the expanded uncertainty.
K_COVERAGE = 2.0
#: Posterior draws per profile (the Monte Carlo's ``N``); u then carries ~1.6 % sampling
#: scatter (``1/√(2N)``).
N_SAMPLES = 2000
#: Verdicts of :func:`verdict`.
VERDICTS = ("pass", "fail", "not decidable")


def deviations(s, e, reference: str = "least-squares") -> np.ndarray:
    """Deviations of profiles ``e`` (``(..., len(s))``, any length unit) from their
    ``reference`` line (:data:`REFERENCES`) over ``s`` (1-D, strictly increasing, any unit);
    same shape and unit as ``e``."""
    s = np.asarray(s, float)
    e = np.asarray(e, float)
    if s.ndim != 1 or len(s) < 2 or not np.all(np.diff(s) > 0):
        raise ValueError(f"s must be 1-D, strictly increasing, with >= 2 points; got shape "
                         f"{s.shape}")
    if e.shape[-1] != len(s):
        raise ValueError(f"e's last axis must have len(s) = {len(s)} points, got {e.shape}")
    if reference == "least-squares":
        sc = s - s.mean()
        b = (e @ sc) / (sc @ sc)
        a = e.mean(axis=-1)
        return e - a[..., None] - b[..., None] * sc
    if reference == "end-point":
        b = (e[..., -1] - e[..., 0]) / (s[-1] - s[0])
        return e - e[..., :1] - b[..., None] * (s - s[0])
    raise ValueError(f"reference must be one of {', '.join(REFERENCES)}, got {reference!r}")


def straightness(s, e, reference: str = "least-squares") -> np.ndarray:
    """Peak-to-valley of :func:`deviations` (same unit as ``e``; shape ``e.shape[:-1]``)."""
    d = deviations(s, e, reference)
    return d.max(axis=-1) - d.min(axis=-1)


def verdict(value: float, U: float, tolerance: float | None) -> str | None:
    """ISO 14253-1's decision for a straightness ``value`` with expanded uncertainty ``U``
    against ``tolerance`` (same unit; None: no tolerance, no verdict): ``"pass"`` if
    ``value + U ≤ tolerance``, ``"fail"`` if ``value − U > tolerance``, else
    ``"not decidable"``."""
    if tolerance is None:
        return None
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"tolerance must be a finite length > 0, got {tolerance!r}")
    if value + U <= tolerance:
        return "pass"
    if value - U > tolerance:
        return "fail"
    return "not decidable"


def sample_gaussian(mean, cov, n: int, rng) -> np.ndarray:
    """``n`` draws ``(n, len(mean))`` from ``N(mean, cov)``; ``cov`` symmetric positive
    semi-definite (the gauge leaves it singular: negative round-off eigenvalues are set to 0)."""
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    L = V * np.sqrt(np.clip(w, 0.0, None))
    return np.asarray(mean, float) + rng.standard_normal((n, len(w))) @ L.T


def uncertain_straightness(s, B, mean, cov, *, reference: str = "least-squares",
                           n_samples: int = N_SAMPLES, seed: int = 0) -> dict:
    """The straightness of the profile ``B @ c`` with ``c ~ N(mean, cov)`` (module docstring).

    Arguments:
        s: the evaluation grid (m), 1-D increasing. B: the basis at ``s``, ``(len(s), n)``.
        mean: coefficients ``(n,)`` (m). cov: their covariance ``(n, n)`` (m²).
        reference: the reference line (:data:`REFERENCES`). n_samples, seed: the Monte Carlo.
    Returns:
        ``{value, u, U, k, interval_95, samples_mean}``, lengths in m.
    """
    if n_samples < 10:
        raise ValueError(f"n_samples must be >= 10, got {n_samples}")
    rng = np.random.default_rng(seed)
    value = float(straightness(s, B @ mean, reference))
    draws = straightness(s, sample_gaussian(mean, cov, n_samples, rng) @ B.T, reference)
    u = float(np.sqrt(np.mean((draws - value) ** 2)))
    lo, hi = np.quantile(draws, [0.025, 0.975])
    return {"value": value, "u": u, "U": K_COVERAGE * u, "k": K_COVERAGE,
            "interval_95": [float(lo), float(hi)], "samples_mean": float(draws.mean())}


def rail_straightness(fit, s, *, rail_y=None, tolerance: float | None = None,
                      reference: str = "least-squares", n_samples: int = N_SAMPLES,
                      seed: int = 0) -> list[dict]:
    """Per rail and plane (the order of :data:`~diffguide.inverse.basis.PROFILES`): the
    straightness of the fitted profile over ``s`` (m, within the fitted range) with ``U``
    (:func:`uncertain_straightness`) and the verdict against ``tolerance`` (m; None: none).

    ``rail_y``: the rails' Y (m), rail 1 first, to say which side each is on. Returns dicts in
    SI (m): ``{rail, side, y, plane, value, u, U, k, interval_95, samples_mean, verdict}``.
    """
    s = np.asarray(s, float)
    B = fit.basis.matrix(s)
    n = fit.basis.per_profile
    rows = []
    for k, (r, plane) in enumerate(PROFILES):
        block = slice(k * n, (k + 1) * n)
        res = uncertain_straightness(s, B, fit.coeffs[r, 0 if plane == "vertical" else 1],
                                     fit.cov[block, block], reference=reference,
                                     n_samples=n_samples, seed=seed + k)
        y = None if rail_y is None else float(rail_y[r])
        side = None if y is None else ("+y" if y > 0 else "−y" if y < 0 else "y = 0")
        rows.append({"rail": r + 1, "side": side, "y": y, "plane": plane, **res,
                     "verdict": verdict(res["value"], res["U"], tolerance)})
    return rows


def deviation_bands(fit, s, reference: str = "least-squares") -> tuple[np.ndarray, np.ndarray]:
    """The fitted profiles' deviations from their ``reference`` line over ``s`` (m) and the
    posterior σ of those deviations (the line's own uncertainty included: the deviations are
    a linear map ``A B c`` of the coefficients, so ``σ² = diag(A B Cov Bᵀ Aᵀ)``); two arrays
    ``(2 rails, 2 planes, len(s))`` (m)."""
    s = np.asarray(s, float)
    B = fit.basis.matrix(s)
    AB = deviations(s, B.T, reference).T  # the reference line removed from each basis function
    n = fit.basis.per_profile
    dev = np.zeros((2, 2, len(s)))
    sig = np.zeros_like(dev)
    for k, (r, plane) in enumerate(PROFILES):
        p = 0 if plane == "vertical" else 1
        C = fit.cov[k * n:(k + 1) * n, k * n:(k + 1) * n]
        dev[r, p] = AB @ fit.coeffs[r, p]
        sig[r, p] = np.sqrt(np.maximum(np.einsum("sk,kl,sl->s", AB, C, AB), 0.0))
    return dev, sig
