r"""Tolerance allocation: the loosest rail grade for which an error measure stays within a limit
at a stated probability, for a given machine.

**The rails.** Each rail and plane gets a stationary Gaussian straightness error of RMS ``σ``
(:class:`~.random_rails.GaussianRailModel`: the grade) and rail 2 a mounting deviation within a
mounting class (:class:`~.random_rails.MountingTolerance`: fixed, not allocated). With common
random numbers — unit-grade draws ``Z_i`` (RMS 1 µm) and mounting deviations ``M_i``, drawn
once — the batch at grade ``σ`` is ``R_i(σ) = (σ / 1 µm) Z_i + M_i``, so every sample's
measure ``m_i(σ)`` is a continuous function of ``σ`` and so is their empirical quantile.

**The root.** ``m_i`` is the largest roll difference between corners over the sweep
(``"roll_difference"``) or one joint error's range at one point (``"range:EAX:P1"``); a sample
whose equilibrium fails at some position counts as exceeding every limit. With ``n`` samples
sorted, the ``p``-quantile is the order statistic ``m_{(k)}``, ``k = ⌈np⌉``; the allocated grade
``σ*`` solves ``m_{(k)}(σ) = L`` (the limit), found on ``ln σ``: bracketed by steps from the
proportional guess ``σ·L/m_{(k)}(σ)``, then the Illinois variant of regula falsi to
:data:`RTOL`. With a mounting class, straight rails (``σ = 0``) are tried first: where they
alone break the limit no grade can help, and the error says so.

**Its interval** (sampling error of the ``n`` draws): the ``p``-quantile lies between the
order statistics ``m_{(l)}`` and ``m_{(u)}`` with probability ≥ 95 % whatever the distribution
(``P(m_{(l)} ≤ ξ_p ≤ m_{(u)}) = P(l ≤ B < u)``, ``B ~ Binomial(n, p)``); ``σ`` where ``m_{(u)}``
meets the limit is the pessimistic end of the grade's interval, ``σ`` where ``m_{(l)}`` does the
optimistic one.

**The check.** A plain Monte Carlo at ``σ*`` on fresh draws (another seed): the fraction of
samples within the limit, with its Wilson 95 % interval. At ``σ*`` exactly ``k`` of the
search's ``n`` draws are within the limit, so the search itself claims the probability
``k/n`` with the Wilson interval of ``k`` in ``n``; the check holds when the two intervals
overlap (:attr:`ToleranceCheck.holds`): the fresh draws agree with the allocation within its
sampling error.
"""

import dataclasses
import math
import statistics
import time
from collections.abc import Callable

import numpy as np

from ..machine.errors import ERROR_NAMES
from .montecarlo import batched_sweep
from .random_rails import (
    GaussianRailModel,
    MountingTolerance,
    RailBatch,
    sample_rails,
)

#: Relative tolerance on the allocated grade σ.
RTOL = 1e-3
#: The grade the common random numbers are drawn at (m): 1 µm RMS.
UNIT = 1e-6
#: Relative tolerance on the ends of its interval.
END_RTOL = 1e-2
#: Grades searched (m RMS): 1 nm to 1 mm.
GRADE_RANGE = (1e-9, 1e-3)
#: Two-sided confidence of the quantile's order-statistic interval and of the check.
CONFIDENCE = 0.95
MAX_EVALUATIONS = 40


def measure_values(result, measure: str) -> np.ndarray:
    """Per-sample values (SI) of ``measure`` from a :class:`~.montecarlo.MonteCarloResult`:
    ``"roll_difference"`` (rad) or ``"range:ERR:POINT"`` (m or rad); a sample that did not
    converge is ``+inf``."""
    if measure == "roll_difference":
        if not result.pairs:
            raise ValueError("measure 'roll_difference' needs two corner points (off both "
                             f"table axes); the machine's points: {', '.join(result.point_names)}")
        v = np.asarray(result.max_roll_difference, float)
    else:
        err, point = parse_range_measure(measure)
        if point not in result.point_names:
            raise ValueError(f"measure {measure!r}: no control point {point!r}; the machine's "
                             f"points: {', '.join(result.point_names)}")
        v = np.asarray(result.ranges[:, result.point_names.index(point),
                                     ERROR_NAMES.index(err)], float)
    return np.where(np.asarray(result.converged, bool), v, np.inf)


def measure_unit(measure: str) -> str:
    """The user unit of ``measure`` (its SI value × 1e6): ``"µrad"`` or ``"µm"``."""
    if measure == "roll_difference":
        return "µrad"
    return "µm" if parse_range_measure(measure)[0] in ERROR_NAMES[:3] else "µrad"


def parse_range_measure(measure: str) -> tuple[str, str]:
    """``"range:ERR:POINT"`` → ``(ERR, POINT)``; ``ValueError`` naming the allowed forms."""
    parts = measure.split(":")
    if len(parts) != 3 or parts[0] != "range" or parts[1] not in ERROR_NAMES or not parts[2]:
        raise ValueError(f"measure must be 'roll_difference' or 'range:ERR:POINT' with ERR one "
                         f"of {', '.join(ERROR_NAMES)}, got {measure!r}")
    return parts[1], parts[2]


def order_statistic_bounds(n: int, p: float, confidence: float = CONFIDENCE) -> tuple[int, int]:
    """1-based ranks ``(l, u)`` with ``P(m_{(l)} ≤ ξ_p ≤ m_{(u)}) ≥ confidence`` for ``n`` draws
    (``P(l ≤ B < u)``, ``B ~ Binomial(n, p)``, equal tails); ``ValueError`` when ``n`` is too
    small for that confidence."""
    k = np.arange(n + 1)
    logpmf = np.array([math.lgamma(n + 1) - math.lgamma(i + 1) - math.lgamma(n - i + 1)
                       for i in k]) + k * math.log(p) + (n - k) * math.log1p(-p)
    cdf = np.cumsum(np.exp(logpmf))  # P(B <= k)
    tail = (1.0 - confidence) / 2
    below = np.nonzero(cdf <= tail)[0]  # P(B < l) = cdf[l - 1] <= tail
    l_rank = int(below[-1]) + 1 if below.size else 0
    above = np.nonzero(1.0 - cdf <= tail)[0]  # P(B >= u) = 1 - cdf[u - 1] <= tail
    u_rank = int(above[0]) + 1 if above.size else n + 1
    if l_rank < 1 or u_rank > n:
        raise ValueError(f"{n} samples are too few for a {confidence:.0%} interval of the "
                         f"{p:.3g} quantile: use more samples")
    return l_rank, u_rank


def wilson_interval(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion ``k / n`` (two-sided)."""
    z = statistics.NormalDist().inv_cdf(0.5 + confidence / 2)
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


@dataclasses.dataclass(frozen=True)
class ToleranceCheck:
    """A plain Monte Carlo at the allocated grade on fresh draws: ``fraction`` of ``n`` samples
    within the limit, its Wilson ``interval``, the ``seed``; ``claimed``: the search's own
    interval of that probability at the grade (the ``k`` of its ``n`` draws within the limit,
    Wilson); ``holds``: the two intervals overlap — the fresh draws agree with the allocation
    within its sampling error."""

    fraction: float
    interval: tuple[float, float]
    n: int
    seed: int
    claimed: tuple[float, float]

    @property
    def holds(self) -> bool:
        return self.interval[0] <= self.claimed[1] and self.claimed[0] <= self.interval[1]


@dataclasses.dataclass(frozen=True)
class ToleranceResult:
    """The allocated grade (SI).

    Attributes:
        grade: ``σ*``, the rails' RMS straightness (m) at which the ``probability``-quantile of
            ``measure`` equals ``limit`` (m or rad). interval: ``(pessimistic, optimistic)``
            grade (m), the quantile's 95 % order-statistic interval. n_samples: draws.
            evaluations: ``(σ, m_(l), m_(k), m_(u))`` of every batched sweep, in order.
            failed: samples that did not converge at ``σ*``. check: the plain Monte Carlo at
            ``σ*`` (``None`` when not asked for). seconds: wall time.
    """

    measure: str
    limit: float
    probability: float
    grade: float
    interval: tuple[float, float]
    n_samples: int
    evaluations: tuple
    failed: int
    check: ToleranceCheck | None
    seconds: float


def _root(g: Callable[[float], float], x0: float, limit: float, what: str,
          rtol: float = RTOL) -> float:
    """``x`` with ``g(x) = 0`` on ``ln x``, ``g(x) = m(x) − limit`` increasing: bracket from
    ``x0`` (steps from the proportional guess ``x·limit/m(x)``, ×1.1 to ×16) within
    :data:`GRADE_RANGE`, then the Illinois variant of regula falsi to :data:`RTOL` (bisection
    where a side is ``+inf``: samples that did not converge)."""
    a, ga = x0, g(x0)
    if ga == 0:
        return a
    up = ga < 0
    b, gb = a, ga
    while (gb < 0) == up and gb != 0:
        a, ga = b, gb
        m = gb + limit
        f = limit / m if np.isfinite(m) and m > 0 else (16.0 if up else 1 / 16)
        b = b * (min(max(1.02 * f, 1.1), 16.0) if up else min(max(0.98 * f, 1 / 16), 1 / 1.1))
        if not GRADE_RANGE[0] <= b <= GRADE_RANGE[1]:
            edge = ("the measure stays within the limit even at the loosest grade searched"
                    if up else "even the finest grade breaks the limit (the mounting deviation "
                    "or samples that do not converge break it alone)")
            raise ValueError(f"{what}: no grade in {GRADE_RANGE[0] * 1e6:g} .. "
                             f"{GRADE_RANGE[1] * 1e6:g} µm RMS meets it: {edge}")
        gb = g(b)
    la, lb, side = math.log(a), math.log(b), 0
    for _ in range(MAX_EVALUATIONS):
        if gb == 0 or abs(lb - la) < rtol:
            break
        if np.isfinite(ga) and np.isfinite(gb):
            w = abs(lb - la)
            lc = (la * gb - lb * ga) / (gb - ga)
            lc = min(max(lc, min(la, lb) + 1e-3 * w), max(la, lb) - 1e-3 * w)
        else:
            lc = 0.5 * (la + lb)
        gc = g(math.exp(lc))
        if gc == 0:
            return math.exp(lc)
        if (gc > 0) == (gb > 0):
            lb, gb = lc, gc
            if side == -1:
                ga *= 0.5
            side = -1
        else:
            la, ga = lc, gc
            if side == 1:
                gb *= 0.5
            side = 1
    return math.exp(lb if gb == 0 else 0.5 * (la + lb))


def allocate_grade(machine, positions, *, measure: str, limit: float, probability: float,
                   correlation_length: float, kernel: str = "squared_exponential",
                   planes: tuple[str, ...] = ("vertical", "horizontal"),
                   mounting: MountingTolerance | str | None = None, n_samples: int = 256,
                   check_samples: int = 256, seed: int = 0, knots=None, guess: float = UNIT,
                   chunk_size: int | None = None,
                   progress: Callable[[str], None] | None = None) -> ToleranceResult:
    """The loosest rail grade σ* (m RMS) for which ``measure`` stays within ``limit`` at
    ``probability`` on ``machine`` over ``positions`` (m) (module docstring).

    Arguments:
        measure: ``"roll_difference"`` or ``"range:ERR:POINT"``. limit: in SI (m or rad), > 0.
        probability: in (0, 1). correlation_length (m), kernel, planes: the rails' Gaussian
            model (:class:`~.random_rails.GaussianRailModel`). mounting: rail 2's mounting
            class (a :data:`~.random_rails.MOUNTING_CLASSES` key or a tolerance), fixed.
        n_samples: common random draws of the search; check_samples: fresh draws of the check
            (0: none). seed: of the search (the check uses ``seed + 1``). knots: the rails'
            ``(start, spacing, n)`` (default :func:`~.random_rails.default_knots`). guess: the
            search's first grade (m). progress: called with one line per batched sweep.
    """
    if not (np.isfinite(limit) and limit > 0):
        raise ValueError(f"limit must be a finite value > 0, got {limit!r}")
    if not 0 < probability < 1:
        raise ValueError(f"probability must be in (0, 1), got {probability!r}")
    unit = measure_unit(measure)
    n_samples = int(n_samples)
    l_rank, u_rank = order_statistic_bounds(n_samples, probability)
    k_rank = max(1, math.ceil(n_samples * probability))
    t0 = time.perf_counter()
    model = GaussianRailModel(UNIT, correlation_length, kernel, planes)
    unit_rails = sample_rails(seed, n_samples, model, None, knots=knots)
    knots = (unit_rails.start, unit_rails.spacing, unit_rails.n_coeffs)
    mount = sample_rails(seed + 10_000, n_samples, None, mounting, knots=knots)
    say = progress or (lambda line: None)
    cache: dict[float, np.ndarray] = {}
    log = []

    def sorted_measure(sigma: float) -> np.ndarray:
        if sigma not in cache:
            res = batched_sweep(machine, _scaled(unit_rails, mount, sigma / UNIT), positions,
                                chunk_size=chunk_size)
            m = np.sort(measure_values(res, measure))
            cache[sigma] = m
            log.append((sigma, m[l_rank - 1], m[k_rank - 1], m[u_rank - 1]))
            q = [v * 1e6 for v in (m[l_rank - 1], m[k_rank - 1], m[u_rank - 1])]
            say(f"  grade {sigma * 1e6:.4g} µm: {probability:.3g} quantile {q[1]:.4g} {unit} "
                f"(95 % interval {q[0]:.4g} .. {q[2]:.4g}; limit {limit * 1e6:.4g})")
        return cache[sigma]

    what = f"{measure} <= {limit * 1e6:g} {unit} at probability {probability:g}"
    if mounting is not None and sorted_measure(0.0)[k_rank - 1] > limit:
        name = getattr(mounting, "name", mounting)
        raise ValueError(f"{what}: straight rails mounted within {name!r} alone give "
                         f"{sorted_measure(0.0)[k_rank - 1] * 1e6:.4g} {unit} at that probability: "
                         "no rail "
                         "grade meets the limit; choose a tighter mounting class")
    grade = _root(lambda s: sorted_measure(s)[k_rank - 1] - limit, guess, limit, what)
    ends = [_root(lambda s, r=r: sorted_measure(s)[r - 1] - limit, grade, limit, what, END_RTOL)
            for r in (u_rank, l_rank)]
    failed = int(np.sum(~np.isfinite(sorted_measure(grade))))
    check = None
    if check_samples:
        fresh_unit = sample_rails(seed + 1, int(check_samples), model, None, knots=knots)
        fresh_mount = sample_rails(seed + 10_001, int(check_samples), None, mounting,
                                   knots=knots)
        res = batched_sweep(machine, _scaled(fresh_unit, fresh_mount, grade / UNIT), positions,
                            chunk_size=chunk_size)
        inside = int(np.sum(measure_values(res, measure) <= limit))
        check = ToleranceCheck(inside / int(check_samples),
                               wilson_interval(inside, int(check_samples)),
                               int(check_samples), seed + 1, wilson_interval(k_rank, n_samples))
        say(f"  check on {check_samples} fresh draws at {grade * 1e6:.4g} µm: "
            f"{check.fraction:.1%} within the limit (95 % interval {check.interval[0]:.1%} .. "
            f"{check.interval[1]:.1%})")
    return ToleranceResult(measure, float(limit), float(probability), float(grade),
                           (float(ends[0]), float(ends[1])), n_samples, tuple(log),
                           failed, check, time.perf_counter() - t0)


def _scaled(unit: RailBatch, mount: RailBatch, a: float) -> RailBatch:
    """``a·unit + mount`` (the batch at grade ``a`` µm)."""
    return RailBatch(unit.start, unit.spacing, a * np.asarray(unit.vertical)
                     + np.asarray(mount.vertical),
                     a * np.asarray(unit.horizontal) + np.asarray(mount.horizontal))
