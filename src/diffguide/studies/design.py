r"""Design with gradients: the machine layout whose errors, over the Monte Carlo distribution of
its rails, are smallest — within bounds and constraints.

**The objective.** ``n`` random rail pairs (the rail model and mounting class of
:func:`~diffguide.studies.montecarlo.batched_sweep`) are drawn once and kept: *common random
numbers*, so that the objective is a deterministic, differentiable function of the design
``x`` and two designs are compared on the same rails. Each sample gives its measure ``m_i(x)``
(:mod:`~diffguide.studies.design_sweep`); the objective is a statistic of them:

- ``mean``: :math:`\bar m = \frac1n\sum_i m_i`, its 95 % interval
  :math:`\bar m \pm 1.96\,s/\sqrt n` (normal approximation of the mean);
- ``pNN`` (e.g. ``p95``): the Harrell–Davis estimate of the ``NN`` % quantile,
  :math:`\sum_k w_k m_{(k)}` with :math:`w_k = I_{k/n}(a, b) - I_{(k-1)/n}(a, b)`,
  :math:`a = p(n+1)`, :math:`b = (1-p)(n+1)` (``I`` the regularised incomplete beta function;
  Harrell & Davis, Biometrika 69 (1982) 635). Unlike one order statistic it weighs every
  sample smoothly, so its gradient does not jump from sample to sample as the design moves;
  its 95 % interval is the distribution-free order-statistic interval
  (:func:`~diffguide.studies.tolerance.order_statistic_bounds`).

Its gradient is :math:`\sum_i (\partial S/\partial m_i)\, \mathrm dm_i/\mathrm dx` with the
per-sample derivatives by forward-mode AD through the build and the equilibrium. Samples whose
equilibrium fails at an iterate are left out of that iterate's statistic and counted.

**The optimiser**: SciPy's SLSQP (sequential least squares programming: bounds, equality and
inequality constraints, our exact gradients) on the variables scaled to ``[0, 1]`` within their
bounds, the objective scaled by its starting value.

**Wide layout bounds: re-centring the mesh.** A traced ``carriage_spacing`` or
``rail_spacing`` moves the footprint lines of a fixed mesh topology, so it reaches only the
mesh's range around the specification's positions
(:func:`~diffguide.studies.design_space.carriage_spacing_range`). The bounds may be wider:
SLSQP runs on the intersection of the bounds and the current mesh's range; when its optimum
lies on a *mesh* end (not a bound of the user's), the specification's positions are moved
there (:func:`~diffguide.machine.morph.apply_layout`) — to the open end of the mesh's range,
:data:`~diffguide.studies.design_space.MIN_GAP` further, where the moving footprint line meets
the grid line that stopped it, so that the rebuilt mesh merges the two and its range reaches
past — the mesh is rebuilt around them (a new range) and SLSQP continues from that point, at
most :data:`MAX_RECENTRINGS` times; the optimum is then rebuilt on its own mesh. The
objective jumps slightly at a re-centring (another discretisation of the same design); the
optimum is the last stage's, on the last mesh. A start outside the specification's mesh range
re-centres first. The rails are drawn once, covering the widest carriage spacing of the bounds
(:func:`design_knots`), so every stage uses the same common random numbers.

**The check.** The original and the optimum are re-evaluated on *fresh* rails (another seed),
each with its interval, and their difference on those same rails with a paired interval
(:func:`paired_improvement`): the improvement counts (:attr:`DesignResult.improved`) when its
95 % interval lies above zero. Each is evaluated on its own mesh: the start on the first
stage's, the optimum on the last stage's.
"""

import dataclasses
import math
import time
from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ..inverse.problem import visited_range
from ..machine.build import build_machine, layout_ranges, with_overrides
from ..machine.morph import apply_layout
from ..machine.spec import MachineSpec
from .design_plan import PLAN_CRITERIA, MeasurementPlan, PlanSigma, on_plan_sites, plan_basis
from .design_space import CONSTRAINTS, VARIABLES, Constraint, apply_all, check_bounds, spec_values
from .design_sweep import DesignSweep
from .random_rails import GaussianRailModel, MountingTolerance, default_knots, sample_rails
from .tolerance import measure_unit, order_statistic_bounds, parse_range_measure

#: Two-sided confidence of the objective's intervals.
CONFIDENCE = 0.95
#: The most re-centrings of the mesh in one :func:`design` (module docstring).
MAX_RECENTRINGS = 8
#: The traced layout variables, whose range is the mesh's.
LAYOUT = ("carriage_spacing", "rail_spacing")
_Z = 1.959963984540054


@dataclasses.dataclass(frozen=True)
class Objective:
    """A statistic (``"mean"`` or ``"pNN"``, ``0 < NN < 100``) of a per-sample measure
    (``"roll_difference"`` or ``"range:ERR:POINT"``, :mod:`~diffguide.studies.tolerance`), or
    the fit's predicted σ for a measurement plan: measure ``"plan"``, statistic a criterion of
    :data:`~diffguide.studies.design_plan.PLAN_CRITERIA` (``A``, ``worst``, ``work``; the plan
    itself is :func:`design`'s ``plan``)."""

    measure: str
    statistic: str = "mean"

    def __post_init__(self):
        if self.measure == "plan":
            if self.statistic not in PLAN_CRITERIA:
                raise ValueError(f"objective plan:CRITERION: CRITERION must be one of "
                                 f"{', '.join(PLAN_CRITERIA)}, got {self.statistic!r}")
            return
        if self.measure != "roll_difference":
            parse_range_measure(self.measure)
        if self.statistic != "mean":
            p = _percent(self.statistic)
            if p is None:
                raise ValueError(f"objective statistic must be 'mean' or 'pNN' with 0 < NN < 100 "
                                 f"(a percentile, e.g. p95), got {self.statistic!r}")

    @property
    def unit(self) -> str:
        """The user unit (SI × 1e6); a ``plan:work`` objective's is its plan's
        (:meth:`~diffguide.studies.design_plan.MeasurementPlan.unit`)."""
        return "µm" if self.measure == "plan" else measure_unit(self.measure)

    @property
    def quantile(self) -> float | None:
        if self.measure == "plan" or self.statistic == "mean":
            return None
        return _percent(self.statistic) / 100

    def text(self) -> str:
        return f"{self.measure}:{self.statistic}"


def _percent(text: str) -> float | None:
    if not text.startswith("p"):
        return None
    try:
        p = float(text[1:])
    except ValueError:
        return None
    return p if 0 < p < 100 else None


def parse_objective(text: str) -> Objective:
    """``"roll-difference:mean"``, ``"roll_difference:p95"``, ``"range:EBX:P1:mean"``,
    ``"plan:A"`` → :class:`Objective` (``ValueError`` naming the allowed forms)."""
    measure, _, stat = text.replace("roll-difference", "roll_difference").rpartition(":")
    if not measure:
        raise ValueError(f"objective must be MEASURE:STATISTIC (MEASURE 'roll-difference' or "
                         f"'range:ERR:POINT', STATISTIC 'mean' or 'pNN') or plan:CRITERION "
                         f"(CRITERION one of {', '.join(PLAN_CRITERIA)}), got {text!r}")
    return Objective(measure, stat)


def harrell_davis_weights(n: int, p: float) -> np.ndarray:
    """Weights ``w_k`` (``k = 1..n``, summing to 1) of the Harrell–Davis ``p``-quantile
    estimate ``Σ w_k m_(k)`` (module docstring)."""
    from scipy.special import betainc

    a, b = p * (n + 1), (1 - p) * (n + 1)
    return np.diff(betainc(a, b, np.arange(n + 1) / n))


@dataclasses.dataclass(frozen=True)
class Estimate:
    """The objective's value on a set of samples (SI: rad or m): ``value``, its 95 %
    ``interval``, ``n`` samples, ``failed`` of them left out (equilibrium failed)."""

    value: float
    interval: tuple[float, float]
    n: int
    failed: int


def statistic(objective: Objective, m: np.ndarray, dm: np.ndarray | None, ok: np.ndarray):
    """``(Estimate, gradient)`` of ``objective`` over per-sample measures ``m`` (with
    derivatives ``dm`` ``(n, k)``, or None), the samples with ``ok``."""
    y = np.asarray(m, float)[ok]
    n = y.size
    if n < 2:
        raise ValueError(f"only {n} of {len(m)} samples converged: no objective")
    q = objective.quantile
    if q is None:
        w = np.full(n, 1 / n)
        s = float(np.std(y, ddof=1))
        v = float(y.mean())
        interval = (v - _Z * s / math.sqrt(n), v + _Z * s / math.sqrt(n))
        order = np.arange(n)
    else:
        order = np.argsort(y)
        w = harrell_davis_weights(n, q)
        v = float(w @ y[order])
        lo, hi = order_statistic_bounds(n, q, CONFIDENCE)
        interval = (float(y[order][lo - 1]), float(y[order][hi - 1]))
    g = None if dm is None else w @ np.asarray(dm, float)[ok][order]
    return Estimate(v, interval, n, int(len(m) - n)), g


#: Resamples of the paired bootstrap of a percentile's improvement.
BOOTSTRAP = 2000


def paired_improvement(objective: Objective, before: np.ndarray, after: np.ndarray,
                       ok: np.ndarray) -> Estimate:
    """``S(before) − S(after)`` over the same samples (``ok``: converged in both) with its
    95 % interval: for the mean, the normal approximation of the mean of the paired differences
    ``m_i(start) − m_i(optimum)``; for a percentile, the paired bootstrap (:data:`BOOTSTRAP`
    resamples of the samples, percentile interval; fixed seed)."""
    b, a = np.asarray(before, float)[ok], np.asarray(after, float)[ok]
    n = b.size
    if n < 2:
        raise ValueError(f"only {n} samples converged at both designs: no improvement estimate")
    q = objective.quantile
    if q is None:
        d = b - a
        v, s = float(d.mean()), float(d.std(ddof=1))
        return Estimate(v, (v - _Z * s / math.sqrt(n), v + _Z * s / math.sqrt(n)), n,
                        int(len(ok) - n))
    w = harrell_davis_weights(n, q)
    v = float(w @ np.sort(b) - w @ np.sort(a))
    idx = np.random.default_rng(0).integers(0, n, size=(BOOTSTRAP, n))
    boot = np.sort(b[idx], axis=1) @ w - np.sort(a[idx], axis=1) @ w
    lo, hi = np.percentile(boot, [100 * (1 - CONFIDENCE) / 2, 100 * (1 + CONFIDENCE) / 2])
    return Estimate(v, (float(lo), float(hi)), n, int(len(ok) - n))


@dataclasses.dataclass(frozen=True)
class DesignResult:
    """The optimum of :func:`design` (SI inside; ``units``/``scales`` convert to user units).

    Attributes:
        variables: names. units, scales: each variable's user unit and SI per user unit.
        bounds: ``(lo, hi)`` (SI). start, optimum: the variables (SI).
        objective: what was minimised. before, after: its :class:`Estimate` at ``start`` and
            ``optimum`` on the optimisation samples; fresh_before, fresh_after: on fresh rails
            (``fresh_seed``; None without a check). improvement: ``before − after`` on those
            fresh rails with its paired 95 % interval (:func:`paired_improvement`); improved:
            its interval lies above 0. sensitivities: ``d objective / d variable`` at the optimum
            (SI per SI). constraints: ``(text, value at the optimum (SI), active)``.
            active_bounds: ``(name, "lower" | "upper")``. history: one dict per evaluation
            (``x`` SI, ``objective``, ``gradient``, ``failed``, ``iteration``). evaluations:
            objective-and-gradient evaluations; sample_sweeps: sample sweeps (each with its
            derivatives) in them. success, message: SLSQP's (last stage). seconds: wall time.
            stages: one dict per mesh (module docstring): ``stage``, ``carriage_x``,
            ``rail_y`` (the mesh's positions, m), ``bounds`` (SI, the bounds within that mesh's
            range), ``start``, ``optimum`` (SI), ``objective`` at the optimum, ``recentred``
            (the next stage re-centres at this optimum), ``message``; history rows carry their
            ``stage``. unit: the objective's user unit (its SI value × 1e6).
    """

    variables: tuple[str, ...]
    units: tuple[str, ...]
    scales: tuple[float, ...]
    bounds: tuple[tuple[float, float], ...]
    start: np.ndarray
    optimum: np.ndarray
    objective: Objective
    before: Estimate
    after: Estimate
    fresh_before: Estimate | None
    fresh_after: Estimate | None
    improvement: Estimate | None
    sensitivities: np.ndarray
    constraints: tuple
    active_bounds: tuple
    history: tuple
    evaluations: int
    sample_sweeps: int
    n_samples: int
    seed: int
    fresh_seed: int | None
    success: bool
    message: str
    seconds: float
    stages: tuple = ()
    unit: str = ""

    @property
    def improved(self) -> bool | None:
        """The improvement on fresh rails exceeds its 95 % interval (its lower end > 0)."""
        if self.improvement is None:
            return None
        return self.improvement.interval[0] > 0


def design_knots(spec: MachineSpec, positions, correlation_length: float, bounds_spacing=None):
    """Rail knots ``(start, spacing, n)`` covering what the rolling elements visit over
    ``positions`` (m) at every carriage spacing up to ``bounds_spacing[1]`` (m; None: the
    machine's)."""
    machine = build_machine(spec)
    lo, hi = visited_range(machine, positions)
    if bounds_spacing is not None:
        cx = spec.guideway.carriage_x
        grow = max(0.0, (bounds_spacing[1] - (cx[1] - cx[0])) / 2)
        lo, hi = lo - grow, hi + grow
    knots = default_knots(correlation_length)
    if lo < knots[0] or hi > knots[0] + (knots[2] - 3) * knots[1]:
        knots = default_knots(correlation_length, start=lo - 0.05, end=hi + 0.05)
    return knots


def _rails(seed, n, rms, correlation_length, kernel, planes, mounting, knots):
    model = GaussianRailModel(rms, correlation_length, kernel, planes)
    return sample_rails(seed, n, model, None if mounting in (None, "none") else mounting,
                        knots=knots)


def _checked(spec, names, bounds, obj, n_samples, check_samples, constraints):
    """The bounds (SI) after checking :func:`design`'s arguments (``ValueError`` naming them)."""
    if not names or len(set(names)) != len(names):
        raise ValueError(f"variables must be distinct names from {', '.join(VARIABLES)}, got "
                         f"{list(names)}")
    if bounds is not None and len(bounds) != len(names):
        raise ValueError(f"bounds: one (lo, hi) per variable ({len(names)}), got {len(bounds)}")
    bounds = check_bounds(spec, names, [None] * len(names) if bounds is None else bounds)
    if not (int(n_samples) == n_samples and n_samples >= 8):
        raise ValueError(f"n_samples must be an integer >= 8, got {n_samples!r}")
    if not (int(check_samples) == check_samples and check_samples >= 0):
        raise ValueError(f"check_samples must be an integer >= 0, got {check_samples!r}")
    if obj.quantile is not None:  # enough samples for the percentile's interval (or an error)
        for what, n in (("n_samples", n_samples), ("check_samples", check_samples)):
            try:
                if n:
                    order_statistic_bounds(int(n), obj.quantile, CONFIDENCE)
            except ValueError as exc:
                raise ValueError(f"{what}: {exc}") from None
    for c in constraints:
        if not isinstance(c, Constraint):
            raise ValueError(f"constraints must be Constraint objects, got {c!r}")
    return bounds


def design(spec: MachineSpec, positions, *, variables: Sequence[str], bounds=None,
           objective: Objective | str = "roll_difference:mean",
           constraints: Sequence[Constraint] = (), rail_rms: float = 1e-6,
           correlation_length: float = 0.2, kernel: str = "squared_exponential",
           planes: tuple[str, ...] = ("vertical", "horizontal"),
           mounting: MountingTolerance | str | None = None, n_samples: int = 64,
           check_samples: int = 64, seed: int = 0, x_ref: float = 0.0, knots=None,
           chunk_size: int | None = None, devices=None, max_iterations: int = 30,
           ftol: float = 1e-6, plan: MeasurementPlan | None = None,
           progress: Callable[[str], None] | None = None) -> DesignResult:
    """Minimise ``objective`` over the design ``variables`` of ``spec`` (module docstring).

    Arguments:
        spec: the machine (:class:`~diffguide.machine.spec.MachineSpec`, SI; its mesh as
            given). positions: table positions (m). variables: names from
            :data:`~diffguide.studies.design_space.VARIABLES`. bounds: one ``(lo, hi)`` per
            variable (SI), or None for its default; None: all defaults. The start is the
            machine's own values, clipped into the bounds.
        objective: an :class:`Objective` or its text (:func:`parse_objective`).
        constraints: :class:`~diffguide.studies.design_space.Constraint` s (SI).
        rail_rms (m), correlation_length (m), kernel, planes, mounting: the random rails
            (:class:`~diffguide.studies.random_rails.GaussianRailModel`, mounting class of rail
            2). n_samples: common random draws of the optimisation; check_samples: fresh draws
            (seed ``seed + 1``) re-evaluating the start and the optimum (0: none).
        x_ref: reference position (m). knots: the rails' ``(start, spacing, n)`` (default
            :func:`design_knots`). chunk_size: samples per compiled call. devices: JAX devices
            to shard the samples over (default ``jax.devices()``).
        max_iterations, ftol: SLSQP's (per mesh).
        plan: the :class:`~diffguide.studies.design_plan.MeasurementPlan` of a ``plan:``
            objective (its sites become the machine's control points, its positions replace
            ``positions``; no random rails: the objective is deterministic, its interval a
            point and the improvement exact). progress: called with one line per evaluation
            and per re-centring.
    """
    t0 = time.perf_counter()
    obj = parse_objective(objective) if isinstance(objective, str) else objective
    names = tuple(variables)
    if (obj.measure == "plan") != (plan is not None):
        raise ValueError("a plan:CRITERION objective needs plan=MeasurementPlan(...), and a plan "
                         f"is read only by such an objective (objective {obj.text()!r})")
    if plan is not None:
        spec, positions, check_samples = on_plan_sites(spec, plan), plan.positions, 0
    bounds = _checked(spec, names, bounds, obj, n_samples, check_samples, constraints)
    x0 = np.clip(spec_values(spec, names), [b[0] for b in bounds], [b[1] for b in bounds])
    sb = bounds[names.index("carriage_spacing")] if "carriage_spacing" in names else None
    say = progress or (lambda line: None)
    if plan is None:
        if knots is None:
            knots = design_knots(spec, positions, correlation_length, sb)
        rails = _rails(seed, int(n_samples), rail_rms, correlation_length, kernel, planes,
                       mounting, knots)
        run = _Run(obj, names, rails, positions, x_ref, chunk_size, devices, say)
    else:
        run = _Run(obj, names, None, positions, x_ref, chunk_size, devices, say,
                   plan=plan, basis=plan_basis(spec, plan, None if sb is None else sb[1]))
    mesh = spec
    if any(n in LAYOUT and not (VARIABLES[n].bounds(spec)[0] <= v <= VARIABLES[n].bounds(spec)[1])
           for n, v in zip(names, x0)):  # a start off the specification's mesh range
        mesh = _recentred(spec, names, x0)
        say("  re-centred the mesh at the start (" + ", ".join(
            f"{n.replace('_', ' ')} {v * 1e3:.5g} mm" for n, v in zip(names, x0) if n in LAYOUT)
            + "): range " + _range_text(mesh, names, bounds))
    start_mesh = mesh
    mesh, stages, res, x_opt = _stages(run, mesh, names, bounds, x0, constraints,
                                       max_iterations, ftol, say)
    after, grad = run.evaluate(x_opt)
    final = [(c.text(), float(c.slack(apply_all(spec, names, jnp.asarray(x_opt)))))
             for c in constraints]
    constraint_rows = tuple((t, s, abs(s) <= 1e-6 * max(1.0, abs(c.value)))
                            for (t, s), c in zip(final, constraints))
    active_bounds = tuple(
        (n, "lower") if xi <= b[0] + 1e-6 * (b[1] - b[0]) else (n, "upper")
        for n, xi, b in zip(names, x_opt, bounds)
        if xi <= b[0] + 1e-6 * (b[1] - b[0]) or xi >= b[1] - 1e-6 * (b[1] - b[0]))
    fresh_before = fresh_after = improvement = None
    if check_samples:
        fresh = _rails(seed + 1, int(check_samples), rail_rms, correlation_length, kernel,
                       planes, mounting, knots)
        check = DesignSweep(start_mesh, names, fresh, positions, obj.measure, x0=x0,
                            x_ref=x_ref, chunk_size=run.chunk, devices=devices)
        mb, _, okb = check(x0)
        if mesh is not start_mesh:  # the optimum on its own (the last) mesh
            check = DesignSweep(mesh, names, fresh, positions, obj.measure, x0=x_opt,
                                x_ref=x_ref, chunk_size=run.chunk, devices=devices)
        ma, _, oka = check(x_opt)
        fresh_before = statistic(obj, mb, None, okb)[0]
        fresh_after = statistic(obj, ma, None, oka)[0]
        improvement = paired_improvement(obj, mb, ma, okb & oka)
        say(f"  fresh rails (seed {seed + 1}, {check_samples} samples): start "
            f"{_text(fresh_before)}, optimum {_text(fresh_after)}, improvement "
            f"{_text(improvement)} {run.unit}")
    elif plan is not None:  # deterministic: the improvement is exact
        d = run.before.value - after.value
        improvement = Estimate(d, (d, d), 0, 0)
    history = run.history
    n_samples = 0 if plan is not None else n_samples
    return DesignResult(
        names, tuple(VARIABLES[n].unit for n in names), tuple(VARIABLES[n].scale for n in names),
        bounds, x0, x_opt, obj, run.before, after, fresh_before, fresh_after, improvement,
        np.asarray(grad),
        constraint_rows, active_bounds, tuple(history), len(history),
        len(history) * int(n_samples) + (2 * int(check_samples) if check_samples else 0),
        int(n_samples), int(seed), seed + 1 if check_samples else None, bool(res.success),
        str(res.message), time.perf_counter() - t0, tuple(stages), run.unit)


def _stages(run, mesh, names, bounds, x, constraints, max_iterations, ftol, say):
    """SLSQP on ``mesh`` from ``x``, re-centred while its optimum lies on a mesh end that is not
    a bound (module docstring): (the last mesh, one row per mesh (:class:`DesignResult`), the
    last SLSQP result, the optimum (SI))."""
    stages = []
    while True:
        sb = _mesh_bounds(mesh, names, bounds)
        start = np.clip(x, *np.transpose(sb))
        res, x_opt, u = run.stage(mesh, sb, start, constraints, max_iterations, ftol)
        ends = [n for n, ui, b, m in zip(names, u, bounds, sb) if n in LAYOUT and (
            (ui <= 1e-6 and m[0] > b[0] + 1e-9 * b[0])
            or (ui >= 1 - 1e-6 and m[1] < b[1] - 1e-9 * b[1]))]
        stages.append(_row(len(stages), mesh, sb, start, x_opt, run.evaluate(x_opt)[0].value,
                           str(res.message)))
        if not ends:
            break
        if len(stages) > MAX_RECENTRINGS:
            say(f"  stopped after {MAX_RECENTRINGS} re-centrings with {', '.join(ends)} at a "
                "mesh end")
            break
        x = _recentre_point(mesh, names, x_opt, u, bounds, ends)
        try:
            new = _recentred(mesh, names, x)
            text = _range_text(new, names, bounds)
        except ValueError as exc:  # e.g. a footprint line onto another patch's
            say(f"  could not re-centre the mesh: {exc}")
            break
        stages[-1]["recentred"], mesh = True, new
        say("  re-centred the mesh at " + ", ".join(
            f"{n.replace('_', ' ')} {xi * 1e3:.5g} mm" for n, xi in zip(names, x)
            if n in LAYOUT) + ": new range " + text)
    if len(stages) > 1:  # the optimum rebuilt on its own mesh
        mesh = _recentred(mesh, names, x_opt)
        run.use(mesh, x_opt)
        stages.append(_row(len(stages), mesh, _mesh_bounds(mesh, names, bounds), x_opt, x_opt,
                           run.evaluate(x_opt)[0].value, "the optimum rebuilt on its own mesh"))
    return mesh, stages, res, x_opt


def _row(k, mesh, sb, start, optimum, objective, message) -> dict:
    g = mesh.guideway
    return {"stage": k, "carriage_x": tuple(map(float, g.carriage_x)),
            "rail_y": tuple(map(float, g.rail_y)), "bounds": tuple(sb), "start": start,
            "optimum": optimum, "objective": objective, "recentred": False, "message": message}


def _mesh_bounds(mesh: MachineSpec, names, bounds) -> list[tuple[float, float]]:
    """``bounds`` (SI) with each layout variable's cut to ``mesh``'s range."""
    out = []
    for n, (lo, hi) in zip(names, bounds):
        if n in LAYOUT:
            mlo, mhi = VARIABLES[n].bounds(mesh)
            lo, hi = max(lo, mlo), min(hi, mhi)
            if not lo < hi:
                raise ValueError(f"{n}: the mesh's range {mlo * 1e3:.5g} .. {mhi * 1e3:.5g} mm "
                                 "around the positions is empty within the bounds; choose "
                                 "another --mesh")
        out.append((float(lo), float(hi)))
    return out


def _recentre_point(mesh: MachineSpec, names, x_opt, u, bounds, ends) -> np.ndarray:
    """Where to re-centre (SI): each variable of ``ends`` at its mesh end moved :data:`MIN_GAP`
    on to the open end of :func:`~diffguide.machine.build.layout_ranges`, where its footprint
    line meets the fixed grid line that bounded it (the rebuilt mesh merges the two, so its range
    extends past it), within ``bounds``; the others at ``x_opt``."""
    x = np.array(x_opt, float)
    ranges = layout_ranges(mesh)
    for i, n in enumerate(names):
        if n in ends:
            x[i] = np.clip(ranges[n][0] if u[i] <= 0.5 else ranges[n][1], *bounds[i])
    return x


def _recentred(mesh: MachineSpec, names, x) -> MachineSpec:
    """``mesh`` with its positions moved to the layout variables' values in ``x`` (SI)."""
    layout = {n: float(xi) for n, xi in zip(names, x) if n in LAYOUT}
    return apply_layout(with_overrides(mesh, **layout))


def _range_text(mesh: MachineSpec, names, bounds) -> str:
    return ", ".join(f"{m[0] * 1e3:.5g} .. {m[1] * 1e3:.5g} mm" for n, m in
                     zip(names, _mesh_bounds(mesh, names, bounds)) if n in LAYOUT)


class _Run:
    """The evaluations of one :func:`design`: the sweep of the current mesh, a cache per mesh,
    the history (every stage) and SLSQP on one mesh (:meth:`stage`)."""

    def __init__(self, obj, names, rails, positions, x_ref, chunk_size, devices, say,
                 plan=None, basis=None):
        self.obj, self.names, self.rails, self.positions = obj, names, rails, positions
        self.x_ref, self.chunk, self.devices, self.say = x_ref, chunk_size, devices, say
        self.plan, self.basis = plan, basis
        self.unit = obj.unit if plan is None else plan.unit(obj.statistic)
        self.history: list[dict] = []
        self.iteration, self.n_stage, self.sweep, self.cache = 0, -1, None, {}
        self.before, self.f0 = None, 1.0

    def evaluate(self, x):
        key = np.asarray(x, float).tobytes()
        if key not in self.cache:
            if self.plan is None:
                m, dm, ok = self.sweep(x)
                est, g = statistic(self.obj, m, dm, ok)
            else:
                v, g, ok = self.sweep(x)
                if not ok:
                    raise ValueError("the machine's equilibrium at straight rails did not "
                                     "converge at the design " + ", ".join(
                                         f"{n} {xi / VARIABLES[n].scale:.5g} {VARIABLES[n].unit}"
                                         for n, xi in zip(self.names, x)))
                est = Estimate(v, (v, v), 0, 0)
            self.cache[key] = (est, g)
            self.history.append({"x": np.array(x, float), "objective": est.value,
                                 "gradient": g, "interval": est.interval,
                                 "failed": est.failed, "iteration": self.iteration,
                                 "stage": self.n_stage})
            self.say(f"  evaluation {len(self.history)} (iteration {self.iteration}): "
                     + ", ".join(f"{n} {v / VARIABLES[n].scale:.5g} {VARIABLES[n].unit}"
                                 for n, v in zip(self.names, x))
                     + f": {self.obj.text()} {est.value * 1e6:.5g} {self.unit}"
                     + (f" ({est.failed} samples failed)" if est.failed else ""))
        return self.cache[key]

    def use(self, mesh, x):
        """Evaluate on ``mesh`` (a new stage) from now on; ``x`` (SI) the build's start."""
        self.n_stage += 1
        self.cache = {}
        if self.plan is not None:
            self.sweep = PlanSigma(mesh, self.names, self.plan, self.obj.statistic, x0=x,
                                   basis=self.basis, x_ref=self.x_ref)
            return
        self.sweep = DesignSweep(mesh, self.names, self.rails, self.positions, self.obj.measure,
                                 x0=x, x_ref=self.x_ref, chunk_size=self.chunk,
                                 devices=self.devices)
        self.chunk = self.sweep.chunk

    def stage(self, mesh, sb, x_start, constraints, max_iterations, ftol):
        """SLSQP on ``mesh`` within ``sb`` (SI) from ``x_start``: (its result, the optimum
        (SI), the optimum scaled to [0, 1])."""
        from scipy.optimize import minimize

        self.use(mesh, x_start)
        lo = np.array([b[0] for b in sb])
        width = np.array([b[1] - b[0] for b in sb])
        est, _ = self.evaluate(x_start)
        if self.before is None:
            self.before, self.f0 = est, max(abs(est.value), 1e-30)

        def fun(u):
            return self.evaluate(lo + width * u)[0].value / self.f0

        def jac(u):
            return self.evaluate(lo + width * u)[1] * width / self.f0

        def advance(_):
            self.iteration += 1

        cons = [_scipy_constraint(mesh, self.names, c, lo, width) for c in constraints]
        res = minimize(fun, (x_start - lo) / width, jac=jac, method="SLSQP",
                       bounds=[(0.0, 1.0)] * len(self.names), constraints=cons,
                       callback=advance,
                       options={"maxiter": int(max_iterations), "ftol": float(ftol)})
        u = np.clip(res.x, 0.0, 1.0)
        return res, lo + width * u, u


def _text(e: Estimate) -> str:
    return f"{e.value * 1e6:.4g} ({e.interval[0] * 1e6:.4g} .. {e.interval[1] * 1e6:.4g})"


def _scipy_constraint(spec, names, c: Constraint, lo, width) -> dict:
    """SLSQP's form of ``c`` on the scaled variables ``u``: ``slack(u) ≥ 0`` (or ``= 0``),
    scaled by the constraint's value, with its Jacobian by forward mode."""
    scale = max(abs(c.value), 1e-12)

    def slack(x):
        return c.slack(apply_all(spec, names, x)) / scale

    d = jax.jacfwd(slack)

    return {"type": "eq" if c.kind == "=" else "ineq",
            "fun": lambda u: float(slack(jnp.asarray(lo + width * u))),
            "jac": lambda u: np.asarray(d(jnp.asarray(lo + width * u))) * width}


__all__ = ["CONSTRAINTS", "DesignResult", "Estimate", "Objective", "design",
           "harrell_davis_weights", "paired_improvement", "parse_objective", "statistic"]
