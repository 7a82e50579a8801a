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

**Uncertainty** (GUM Supplement 1, the Monte Carlo method). The peak-to-valley is not a
linear function of the profile, so its distribution is found by sampling the fit's posterior:
``N`` draws of each profile's spline coefficients from ``N(ĉ, Cov c)`` (the fit's covariance,
:attr:`~diffguide.inverse.RailFit.cov`, which holds the structure's uncertainty), each draw's
straightness ``t_j``. From the draws:

- the **estimate** ``t̂``: their median;
- the **standard uncertainty** ``u``: their standard deviation;
- the **95 % coverage interval**: probabilistically symmetric, their 2.5 % and 97.5 %
  quantiles (GUM S1, 7.7). It is asymmetric about ``t̂``: a peak-to-valley's distribution is
  skewed, so no symmetric ``t̂ ± U`` describes it.

The fitted (mean) profile's own peak-to-valley ``t(ĉ)`` is reported beside ``t̂``, and the
**bias** ``t̂ − t(ĉ)``: the draws are rougher than the mean profile, so they lie above its
peak-to-valley (a maximum of noisy values is biased up). Rail content shorter than the knot
grid resolves (the fit's stated waviness) is not in the interval.

**Why the draws' own interval, not a bias-corrected one.** For an *unregularised* estimate,
``ĉ ~ N(c_true, Σ)``, the draws ``c_j − ĉ`` mirror ``ĉ − c_true``, so the draws lie above
``t(ĉ)`` as ``t(ĉ)`` lies above ``t(c_true)``: their interval is too high, and the basic
bootstrap interval ``[2t(ĉ) − q_hi, 2t(ĉ) − q_lo]`` (Davison & Hinkley 1997, §5.2.1;
:func:`basic_interval`) corrects it (on a cubic profile, σ 0.3 µm: 90 % coverage against
the draws' 45 %). The fit is regularised: ``ĉ`` is its posterior mean, smoothed towards the
prior, so ``t(ĉ)`` is not raised by the noise as an unregularised estimate's is (on the
battery below it: ``t(ĉ)`` under the truth's in 48 of 80 rows, median ratio 0.98) and the
reflection about it comes out too low. The draws are the posterior of the profile, and their
interval is a Bayesian 95 % interval for the straightness whatever its nonlinearity (truths
drawn from a smoothing prior: 93 % covered, the basic interval 68 %;
``tests/test_straightness.py``). On the identification
battery (``bench/battery_straightness.py``: 20 cases × 2 rails × 2 planes = 80 rows, truths
not drawn from the prior, several beyond the fit's model) the draws' interval covered the
truth's straightness in 76 of 80 rows (95 %), the 4 misses all *above* the truth (never a
false "pass"); the basic interval covered 67 (84 %), and in 13 rows its upper end lay below
the truth (down to 0.55 × it): a "pass" at a tolerance between the two would have been false.
So the verdict uses the draws' interval; the basic one is reported beside it
(``interval_95_basic``), for comparison only.

**Verdict** (ISO 14253-1 with the coverage interval ``[t_lo, t_hi]``): ``"pass"``
(conformance proved) where ``t_hi ≤ T``, ``"fail"`` (non-conformance proved) where
``t_lo > T``, otherwise ``"not decidable"``; ``T`` the stated tolerance. Data that carry no
information beyond the prior are never decided: when every channel is constant (a stuck
instrument: :func:`~diffguide.inverse.validity.null_data`), or when the draws' spread is at
least :data:`INFORMATIVE_RATIO` of the prior's own (the rails drawn from the fit's prior,
``c = Zθ``, ``θ ~ N(0, (λΩ)⁻¹)``: :func:`prior_cov`), the interval is the prior's, however
narrow, and the verdict is ``"not decidable"``.
"""

import numpy as np

from ..inverse.basis import PROFILES

#: The reference lines of :func:`deviations`.
REFERENCES = ("least-squares", "end-point")
#: Coverage probability of the reported interval.
COVERAGE = 0.95
#: Posterior draws per profile (the Monte Carlo's ``N``); u then carries ~0.7 % sampling
#: scatter (``1/√(2N)``), the interval's ends ~0.5 % (the bundled data's rail 2 horizontal:
#: 1.2 % and 0.95 % over 30 seeds at N = 2000, so about √5 less here).
N_SAMPLES = 10000
#: Verdicts of :func:`decide`.
VERDICTS = ("pass", "fail", "not decidable")
#: The data are taken to carry information on a profile's straightness only when the
#: posterior draws' spread is below this fraction of the prior draws' (the bundled data:
#: 0.36–0.57; constant data: 0.95–1.03, the sampling scatter about 1).
INFORMATIVE_RATIO = 0.9


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


def coverage_interval(draws, p: float = COVERAGE) -> tuple[float, float]:
    """The probabilistically symmetric coverage interval of probability ``p`` of ``draws``
    (1-D): their ``(1 − p)/2`` and ``(1 + p)/2`` quantiles (GUM Supplement 1, 7.7), same unit."""
    if not 0.0 < p < 1.0:
        raise ValueError(f"the coverage probability must be in (0, 1), got {p!r}")
    lo, hi = np.quantile(np.asarray(draws, float), [(1 - p) / 2, (1 + p) / 2])
    return float(lo), float(hi)


def basic_interval(draws, t0: float, p: float = COVERAGE) -> tuple[float, float]:
    """The basic (reflected) bootstrap interval of probability ``p`` (Davison & Hinkley 1997,
    §5.2.1) for a straightness whose fitted (mean) profile gives ``t0`` and whose posterior draws
    give ``draws`` (1-D): ``[2 t0 − q_hi, 2 t0 − q_lo]`` with ``q_lo, q_hi`` the draws'
    :func:`coverage_interval`, each end clipped at 0 below (a straightness is ≥ 0).

    The draws' departures from the fitted profile, ``c_j − ĉ``, stand for the fit's error
    ``ĉ − c_true``; so ``t(c_j) − t(ĉ)`` stands for ``t(ĉ) − t(c_true)``, and the truth lies
    below ``t0`` by what the draws lie above it (module docstring)."""
    lo, hi = coverage_interval(draws, p)
    return max(2 * t0 - hi, 0.0), max(2 * t0 - lo, 0.0)


def decide(interval, tolerance: float | None, *, informative: bool = True) -> str | None:
    """ISO 14253-1's decision for a straightness whose coverage interval is ``interval``
    ``(lo, hi)`` against ``tolerance`` (same unit; None: no tolerance, no verdict): ``"pass"``
    if ``hi ≤ tolerance``, ``"fail"`` if ``lo > tolerance``, else ``"not decidable"``; always
    ``"not decidable"`` when the data are not ``informative`` (the interval is the prior's)."""
    if tolerance is None:
        return None
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"tolerance must be a finite length > 0, got {tolerance!r}")
    lo, hi = (float(v) for v in interval)
    if not lo <= hi:
        raise ValueError(f"the interval must be (lo, hi) with lo <= hi, got {interval!r}")
    if not informative:
        return "not decidable"
    if hi <= tolerance:
        return "pass"
    if lo > tolerance:
        return "fail"
    return "not decidable"


def prior_cov(fit) -> np.ndarray | None:
    """The fit's prior covariance of the stacked rail coefficients (m², the order of
    :attr:`~diffguide.inverse.RailFit.cov`): ``Z (λΩ)⁻¹ Zᵀ`` with ``θ`` in µm; None when the
    fit does not carry its prior (``Z``, ``lam``, ``Omega``) or the prior is improper (a
    direction ``λΩ`` does not charge: no width to compare with)."""
    Z, lam, Omega = (getattr(fit, a, None) for a in ("Z", "lam", "Omega"))
    if Z is None or lam is None or Omega is None or not np.size(Omega):
        return None
    P = float(lam) * np.asarray(Omega, float)
    w, V = np.linalg.eigh(0.5 * (P + P.T))
    if not (np.all(np.isfinite(w)) and w.min() > 1e-12 * max(w.max(), 0.0)):
        return None
    return np.asarray(Z) @ ((V / w) @ V.T) @ np.asarray(Z).T * 1e-12


def sample_gaussian(mean, cov, n: int, rng) -> np.ndarray:
    """``n`` draws ``(n, len(mean))`` from ``N(mean, cov)``; ``cov`` symmetric positive
    semi-definite (the gauge leaves it singular: negative round-off eigenvalues are set to 0)."""
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    L = V * np.sqrt(np.clip(w, 0.0, None))
    return np.asarray(mean, float) + rng.standard_normal((n, len(w))) @ L.T


def uncertain_straightness(s, B, mean, cov, *, prior=None, reference: str = "least-squares",
                           n_samples: int = N_SAMPLES, seed: int = 0) -> dict:
    """The straightness of the profile ``B @ c`` with ``c ~ N(mean, cov)`` (module docstring).

    Arguments:
        s: the evaluation grid (m), 1-D increasing. B: the basis at ``s``, ``(len(s), n)``.
        mean: coefficients ``(n,)`` (m). cov: their covariance ``(n, n)`` (m²).
        prior: the coefficients' prior covariance ``(n, n)`` (m², zero mean), or None: to
            compare the draws' spread with the prior's. reference: the reference line
            (:data:`REFERENCES`). n_samples, seed: the Monte Carlo.
    Returns:
        ``{value, mean_profile, bias, u, interval_95, interval_95_basic, prior_ratio,
        informative}``: the estimate (the draws' median), the mean profile's straightness
        ``t(ĉ)``, ``value − mean_profile``, the draws' standard deviation, their 95 % interval
        (:func:`coverage_interval`: the verdict's) and the basic bootstrap interval
        (:func:`basic_interval`: reported, not used; module docstring), lengths in m; the
        draws' spread over the prior draws' (None without ``prior``) and whether it is below
        :data:`INFORMATIVE_RATIO`.
    """
    if n_samples < 10:
        raise ValueError(f"n_samples must be >= 10, got {n_samples}")
    rng = np.random.default_rng(seed)
    # the deviations are linear in the coefficients, d = A B c: the reference line is taken
    # out of each basis function once, and each draw's deviations are one product
    AB = deviations(s, np.asarray(B, float).T, reference)  # (n, len(s))
    mean_profile = float(np.ptp(mean @ AB))
    draws = np.ptp(sample_gaussian(mean, cov, n_samples, rng) @ AB, axis=-1)
    value = float(np.median(draws))
    u = float(draws.std())
    ratio = None
    if prior is not None:
        base = np.ptp(sample_gaussian(np.zeros(len(mean)), prior, n_samples, rng) @ AB, axis=-1)
        spread = float(base.std())
        ratio = u / spread if spread > 0 else float("inf")  # a prior without spread: none
    return {"value": value, "mean_profile": mean_profile, "bias": value - mean_profile,
            "u": u, "interval_95": list(coverage_interval(draws)),
            "interval_95_basic": list(basic_interval(draws, mean_profile)),
            "prior_ratio": ratio, "informative": ratio is None or ratio < INFORMATIVE_RATIO}


def rail_straightness(fit, s, *, rail_y=None, tolerance: float | None = None,
                      informative: bool = True, reference: str = "least-squares",
                      n_samples: int = N_SAMPLES, seed: int = 0) -> list[dict]:
    """Per rail and plane (the order of :data:`~diffguide.inverse.basis.PROFILES`): the
    straightness of the fitted profile over ``s`` (m, within the fitted range) with its
    uncertainty (:func:`uncertain_straightness`, the fit's prior from :func:`prior_cov`) and
    the verdict (:func:`decide`) against ``tolerance`` (m; None: none).

    ``rail_y``: the rails' Y (m), rail 1 first, to say which side each is on.
    ``informative``: False when the data carry no information at all (every channel
    constant): every verdict is then "not decidable". Returns dicts in SI (m): ``{rail, side,
    y, plane, value, mean_profile, bias, u, interval_95, interval_95_basic, prior_ratio,
    informative, verdict, verdict_reason}``.
    """
    s = np.asarray(s, float)
    B = fit.basis.matrix(s)
    n = fit.basis.per_profile
    prior = prior_cov(fit)
    rows = []
    for k, (r, plane) in enumerate(PROFILES):
        block = slice(k * n, (k + 1) * n)
        res = uncertain_straightness(s, B, fit.coeffs[r, 0 if plane == "vertical" else 1],
                                     fit.cov[block, block],
                                     prior=None if prior is None else prior[block, block],
                                     reference=reference, n_samples=n_samples, seed=seed + k)
        y = None if rail_y is None else float(rail_y[r])
        side = None if y is None else ("+y" if y > 0 else "−y" if y < 0 else "y = 0")
        res["informative"] = bool(res["informative"] and informative)
        v = decide(res["interval_95"], tolerance, informative=res["informative"])
        rows.append({"rail": r + 1, "side": side, "y": y, "plane": plane, **res, "verdict": v,
                     "verdict_reason": _reason(v, res, informative, tolerance)})
    return rows


def _reason(v, res, informative: bool, tolerance) -> str | None:
    """Why the verdict is what it is, in words (None without a verdict)."""
    if v is None:
        return None
    lo, hi = (x * 1e6 for x in res["interval_95"])
    if not informative:
        return ("the data carry no information (every channel constant): the interval is the "
                "prior's")
    if not res["informative"]:
        return (f"the posterior draws' spread is {res['prior_ratio'] * 100:.0f} % of the "
                "prior's: the data carry no information on this profile beyond the prior")
    t = tolerance * 1e6
    if v == "pass":
        return f"the 95 % interval's upper end {hi:.2f} µm <= {t:g} µm"
    if v == "fail":
        return f"the 95 % interval's lower end {lo:.2f} µm > {t:g} µm"
    return f"the 95 % interval {lo:.2f} … {hi:.2f} µm contains {t:g} µm"


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
