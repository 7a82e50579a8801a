r"""The fit's predicted σ for a measurement plan as a design objective: how well a stated plan
(instruments at stated places on the table, read at stated positions) will determine the rails
of a machine, as a differentiable function of the machine's design.

**The criterion** is the measurement planner's (:mod:`~diffguide.planning.plan`) with the
structure known (the design fixes the table and the preload): for the design ``x`` the model's
Jacobian w.r.t. the gauge-fixed rail coefficients ``θ`` (µm) at straight rails, ``J_c(x)``, one
block per channel ``c`` (placement and quantity) over the positions, each channel's zero (and a
straightness channel's alignment slope) projected out and whitened by the merged σ
``σ_c = σ_reading/√(runs·directions)``, gives

.. math::  H(x) = λΩ + \sum_c J_c(x)^T J_c(x),\qquad \mathrm{Cov}_θ = H(x)^{-1},

``λΩ`` the prior of an expected rail RMS ``ρ`` (:func:`~diffguide.planning.planner.rail_prior`).
The objective is then

- ``plan:A``: the RMS σ of the four gauge-fixed profiles over the basis length,
  :math:`\sqrt{\mathrm{tr}(W H^{-1} W^T)/n}` (m);
- ``plan:worst``: their largest σ, :math:`\sqrt{\max \mathrm{diag}(W H^{-1} W^T)}` (m);
- ``plan:work``: the largest σ over the positions of the predicted errors at a work point,
  :math:`\sqrt{\max \mathrm{diag}(J_w H^{-1} J_w^T)}` (m or rad), ``J_w`` the work point's
  rows (not centred: the prediction's own zero is the model's).

``W`` samples the profiles (:data:`~diffguide.planning.design.N_S` per profile) in the one gauge
the planner reports every plan in (:func:`~diffguide.planning.planner.gauge_projector`). The rail
basis is fixed for the whole design: it covers what the rolling elements visit over the
positions at the widest carriage spacing of the bounds, so every design is judged on the same
unknowns (a narrower design leaves the ends to the prior, and its σ says so).

**Derivatives**: ``J(x)`` is a forward-mode Jacobian through the equilibrium's implicit tangent;
``dσ/dx`` differentiates it once more (forward over forward, exact second derivatives of the
equilibrium). The maxima (``worst``, ``work``) are differentiable where the maximising sample
is unique, as the Monte Carlo measures are.
"""

import dataclasses
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..inverse.basis import RailBasis
from ..inverse.data import QUANTITIES, Measurements
from ..inverse.model import _model
from ..inverse.problem import _as_family, _problem, visited_range
from ..machine.build import build_machine, with_overrides
from ..machine.spec import MachineSpec
from ..planning.design import N_S
from ..planning.instruments import Instrument
from ..planning.planner import rail_prior
from .design_space import apply_all

#: The planner criteria a design can minimise (``plan:CRITERION``).
PLAN_CRITERIA = ("A", "worst", "work")
_UM = 1e-6
_ANGLES = ("EAX", "EBX", "ECX")


@dataclasses.dataclass(frozen=True)
class MeasurementPlan:
    """A measurement plan to design a machine for (SI).

    Attributes:
        placements: ``(kind, x, y)`` — an instrument kind (``level``, ``interferometer``,
            ``straightness``) at ``(x, y)`` (m from the table centre).
        positions: table positions read (m), at least 4 distinct.
        runs: runs per direction. bidirectional: forward and backward runs.
        sigma: σ of one reading per kind (rad, or m for straightness); missing kinds take
            :data:`~diffguide.planning.instruments.DEFAULT_READING_SIGMA`.
        reads: the quantities one placement of a kind reads; missing kinds read all of
            :data:`~diffguide.planning.instruments.KINDS` ``[kind]``.
        rail_rms: expected RMS of the gauge-fixed rail profiles (m; the prior).
        work_point: ``(x, y, quantities)`` for ``plan:work`` (m), or None.
    """

    placements: tuple[tuple[str, float, float], ...]
    positions: tuple[float, ...]
    runs: int = 5
    bidirectional: bool = True
    sigma: dict = dataclasses.field(default_factory=dict)
    reads: dict = dataclasses.field(default_factory=dict)
    rail_rms: float = 1e-6
    work_point: tuple[float, float, tuple[str, ...]] | None = None

    def __post_init__(self):
        rows = tuple((str(k), float(x), float(y)) for k, x, y in self.placements)
        object.__setattr__(self, "placements", rows)
        if not rows:
            raise ValueError("a measurement plan needs at least one placement")
        if len(set(rows)) != len(rows):
            raise ValueError("a measurement plan: the same instrument twice on one site")
        pos = np.unique(np.round(np.asarray(self.positions, float), 9))
        if pos.size < 4 or not np.all(np.isfinite(pos)):
            raise ValueError("a measurement plan needs at least 4 distinct finite positions")
        object.__setattr__(self, "positions", tuple(map(float, pos)))
        if int(self.runs) != self.runs or self.runs < 1:
            raise ValueError(f"runs must be an integer >= 1, got {self.runs!r}")
        self.instruments()  # each kind's reads and σ checked as the planner's instruments
        if not (np.isfinite(self.rail_rms) and self.rail_rms > 0):
            raise ValueError(f"rail_rms must be > 0 m, got {self.rail_rms!r}")
        if self.work_point is not None:
            wq = tuple(self.work_point[2])
            bad = [q for q in wq if q not in ("EYX", "EZX", *_ANGLES)]
            if not wq or bad:
                raise ValueError(f"work point quantities must be among EYX, EZX, EAX, EBX, ECX, "
                                 f"got {wq}")

    def sites(self) -> dict:
        """The plan's sites ``{name: (x, y)}`` (m): ``S1, S2, …`` in order of first use, and
        ``WORK`` where there is a work point."""
        out: dict = {}
        for _, x, y in self.placements:
            if (x, y) not in out.values():
                out[f"S{len(out) + 1}"] = (x, y)
        if self.work_point is not None:
            out["WORK"] = (float(self.work_point[0]), float(self.work_point[1]))
        return out

    def instruments(self) -> dict:
        """``{kind: Instrument}`` of every kind the plan names (its reads and reading σ, the
        instruments' defaults where not given)."""
        kinds = dict.fromkeys([k for k, _, _ in self.placements] + [*self.reads, *self.sigma])
        return {k: Instrument(k, 1, self.reads.get(k), self.sigma.get(k)) for k in kinds}

    def channels(self) -> list[tuple[str, str, float]]:
        """``(site, quantity, merged σ)`` of every channel the plan reads."""
        names = {xy: n for n, xy in self.sites().items() if n != "WORK"}
        per = self.runs * (2 if self.bidirectional else 1)
        inst = self.instruments()
        out = []
        for k, x, y in self.placements:
            s = inst[k].sigma / np.sqrt(per)
            out += [(names[(x, y)], q, s) for q in inst[k].quantities]
        return out

    def unit(self, criterion: str) -> str:
        """The user unit of ``criterion``'s value."""
        if criterion != "work" or self.work_point is None:
            return "µm"
        wq = set(self.work_point[2])
        return "µrad" if wq <= set(_ANGLES) else "µm" if not wq & set(_ANGLES) else "µm|µrad"


def on_plan_sites(spec: MachineSpec, plan: MeasurementPlan) -> MachineSpec:
    """``spec`` with the plan's sites as its control points (each puts grid lines through
    itself; a site off the table is refused naming it)."""
    return with_overrides(spec, points=plan.sites())


def plan_basis(spec: MachineSpec, plan: MeasurementPlan, widest_spacing=None,
               knot_spacing: float | None = None) -> RailBasis:
    """The rail basis of the objective: what the rolling elements visit over the plan's
    positions, at a carriage spacing up to ``widest_spacing`` (m; None: the machine's), knots
    at most ``knot_spacing`` apart (default the carriage's loaded length, as the fit)."""
    machine = build_machine(spec)
    lo, hi = visited_range(machine, plan.positions)
    if widest_spacing is not None:
        cx = spec.guideway.carriage_x
        grow = max(0.0, (float(widest_spacing) - float(cx[1] - cx[0])) / 2)
        lo, hi = lo - grow, hi + grow
    return RailBasis.covering(lo, hi, knot_spacing or float(machine.carriage.length))


def _channel_problem(machine, plan: MeasurementPlan, basis: RailBasis, x_ref: float):
    """The fit's problem with one zero-valued row per (channel or work quantity, position),
    channel-major, and the rows' layout: ``(read channels, work quantities)``."""
    sites = plan.sites()
    names = tuple(machine.point_names)
    chans = plan.channels()
    work = [("WORK", q) for q in plan.work_point[2]] if plan.work_point else []
    pos = np.asarray(plan.positions)
    keys = [(s, q) for s, q, _ in chans] + work
    point = np.repeat([names.index(s) for s, _ in keys], len(pos))
    quantity = np.repeat([QUANTITIES.index(q) for _, q in keys], len(pos))
    n = len(point)
    meas = Measurements(names, np.asarray([sites.get(p, (0.0, 0.0)) for p in names], float),
                        np.tile(pos, len(keys)), point, quantity, np.zeros(n), np.ones(n),
                        np.ones(n, int), np.full(n, np.nan), ("level",) * n, ("column",) * n)
    return _problem(_as_family(machine), meas, basis, np.zeros((n, 0)), x_ref)


class PlanSigma:
    """The objective ``plan:CRITERION`` (module docstring) of a design ``x`` (SI) and its
    gradient: ``objective(x) -> (value (SI), d value/d x, converged)``.

    Arguments:
        spec: the machine, its control points the plan's sites (:func:`on_plan_sites`).
        names: the design variables (:data:`~diffguide.studies.design_space.VARIABLES`).
        plan: the :class:`MeasurementPlan`. criterion: one of :data:`PLAN_CRITERIA`.
        x0: the design the problem is laid out at (SI). basis: the rail basis (default
            :func:`plan_basis` of ``spec``). x_ref: reference position (m).
    """

    def __init__(self, spec: MachineSpec, names: Sequence[str], plan: MeasurementPlan,
                 criterion: str, *, x0, basis: RailBasis | None = None, x_ref: float = 0.0):
        if criterion not in PLAN_CRITERIA:
            raise ValueError(f"plan criterion must be one of {', '.join(PLAN_CRITERIA)}, got "
                             f"{criterion!r}")
        if criterion == "work" and plan.work_point is None:
            raise ValueError("objective plan:work needs the plan's work point")
        missing = [n for n in plan.sites() if n not in dict(spec.points)]
        if missing:
            raise ValueError(f"the machine lacks the plan's sites {missing}: build it with "
                             "on_plan_sites(spec, plan)")
        self.spec, self.names, self.plan, self.criterion = spec, tuple(names), plan, criterion
        x0 = jnp.asarray(np.asarray(x0, float))
        machine = build_machine(apply_all(spec, self.names, x0))
        self.basis = basis if basis is not None else plan_basis(spec, plan)
        prior = rail_prior(self.basis, plan.rail_rms, 0)
        self.Z = jnp.asarray(prior["Z"])
        self.H0 = jnp.asarray(prior["P"])
        self.W = jnp.asarray(np.kron(np.eye(4), self.basis.matrix(self.basis.grid(N_S)))
                             @ prior["Pi"] @ prior["Z"])
        self.prob = _channel_problem(machine, plan, self.basis, x_ref)
        chans = plan.channels()
        self.n_pos, self.n_read = len(plan.positions), len(chans)
        self.sig = jnp.asarray([s for _, _, s in chans])
        self.straight = jnp.asarray([q in ("EYX", "EZX") for _, q, _ in chans])
        self.calls = 0

    def __call__(self, x, *, grad: bool = True):
        """``(value (SI), gradient (SI per SI; None without grad), converged)``."""
        self.calls += 1
        x = jnp.asarray(np.asarray(x, float))
        v, g, ok = (_value_and_gradient if grad else _value)(
            self.spec, self.names, x, self.prob, self.Z, self.H0, self.W, self.sig,
            self.straight, self.n_pos, self.n_read, self.criterion)
        return float(v), None if g is None else np.asarray(g), bool(ok)


def plan_criterion(machine, prob, Z, H0, W, sig, straight, n_pos, n_read, criterion):
    """The criterion (SI) of the plan's rows ``prob`` on ``machine`` (traced), and whether its
    straight-rail equilibrium converged (module docstring)."""
    prob = eqx.tree_at(lambda p: p.family.base, prob, machine)
    J, ok = jax.jacfwd(lambda c: _model(c, prob), has_aux=True)(jnp.zeros(prob.n_c))
    J = (J @ Z).reshape(-1, n_pos, Z.shape[1])  # (channels, positions, θ), SI per µm
    Jr = J[:n_read] - J[:n_read].mean(axis=1, keepdims=True)
    pos = prob.positions - prob.positions.mean()
    u = pos / jnp.linalg.norm(pos)
    slope = jnp.einsum("p,cpi->ci", u, Jr)
    Jr = jnp.where(straight[:, None, None], Jr - u[None, :, None] * slope[:, None, :], Jr)
    Jr = Jr / sig[:, None, None]
    H = H0 + jnp.einsum("cpi,cpj->ij", Jr, Jr)
    if criterion == "work":
        Jw = J[n_read:].reshape(-1, Z.shape[1])
        var = jnp.sum(Jw * jnp.linalg.solve(H, Jw.T).T, axis=1)  # SI²
        return jnp.sqrt(jnp.max(var)), ok
    var = jnp.sum(W * jnp.linalg.solve(H, W.T).T, axis=1) * _UM**2  # m²
    return jnp.sqrt(jnp.mean(var) if criterion == "A" else jnp.max(var)), ok


@eqx.filter_jit
def _value(spec, names, x, prob, Z, H0, W, sig, straight, n_pos, n_read, criterion):
    machine = build_machine(apply_all(spec, names, x))
    v, ok = plan_criterion(machine, prob, Z, H0, W, sig, straight, n_pos, n_read, criterion)
    return v, None, ok


@eqx.filter_jit
def _value_and_gradient(spec, names, x, prob, Z, H0, W, sig, straight, n_pos, n_read,
                        criterion):
    def f(x):
        machine = build_machine(apply_all(spec, names, x))
        v, ok = plan_criterion(machine, prob, Z, H0, W, sig, straight, n_pos, n_read, criterion)
        return v, (v, ok)

    g, (v, ok) = jax.jacfwd(f, has_aux=True)(x)
    return v, g, ok


__all__ = ["PLAN_CRITERIA", "MeasurementPlan", "PlanSigma", "on_plan_sites", "plan_basis",
           "plan_criterion"]
