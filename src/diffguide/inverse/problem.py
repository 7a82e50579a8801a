r"""The fit as a problem: data, model, prior and gauge in one object, built once from
:func:`~.fit.fit_rails`' arguments and read by the short functions that solve it
(:mod:`.solve`, :mod:`.structure_stage`, :mod:`.posterior`).

**Unknowns** ``x = (θ, q, ℓ)``: the gauge-fixed rail coefficients ``θ`` (µm, ``c = Zθ``,
:mod:`.basis`), the structural unknowns ``q`` (prior σ, :mod:`.structure`) and the nuisances
``ℓ`` (µm): the lead error's B-spline on the EXX rows (:data:`LEAD_KNOT_SPACING`), then one
alignment slope (µm/m) per straightness channel. The forward model maps ``v = Mx = (Zθ, q, ℓ)``
to the whitened residual (:mod:`.model`).

**Prior.** ``xᵀPx = λθᵀ(Ω_curv + κΩ_amp)θ + ‖q‖² + ε²‖ℓ‖²`` (``ε`` = :data:`LEAD_RIDGE` µm⁻¹),
λ and κ fixed or chosen by the data (:mod:`.weight`) on the problem linearised at the current
estimate with the nuisance columns projected out.
"""

import logging

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.checks import length
from ..fe.table import THICKNESS_RANGE
from ..guideway.rails import JOINT_WIDTH, bspline_matrix
from ..machine.equilibrium import Machine
from ..machine.kinematics import POSITION_RANGE
from .basis import RailBasis, null_space_basis
from .data import QUANTITIES, Measurements
from .model import _linearise, _Problem
from .structure import MachineFamily, StructurePriors
from .weight import WeightChoice, choose_prior, fixed_weight, project_out

_log = logging.getLogger("diffguide")
#: Knot spacing of the lead-error spline (m), at most; at least 4 coefficients over the stroke.
LEAD_KNOT_SPACING = 0.1
#: Ridge on the lead-error coefficients (1/µm): a prior σ of 1 mm, i.e. none in practice.
LEAD_RIDGE = 1e-3
#: Plausible knot spacings (m): from 1 mm (finer than any carriage resolves) to 5 m.
KNOT_SPACING_RANGE = (1e-3, 5.0)
#: Plausible range of a preload prior (fraction of the carriage's dynamic capacity C), the
#: machine file's ``[carriage] preload_fraction`` range.
PRELOAD_RANGE = (1e-4, 0.5)
#: Plausible range of an imported table's stiffness-scale prior (the machine file's ``[fit]
#: stiffness_prior`` range).
STIFFNESS_RANGE = (0.01, 100.0)
_EXX = QUANTITIES.index("EXX")
_STRAIGHTNESS = (QUANTITIES.index("EYX"), QUANTITIES.index("EZX"))
#: What a failed equilibrium raises inside the compiled model (equinox's runtime checks under
#: ``EQX_ON_ERROR=raise``, the default outside the CLI; XLA's runtime error).
_RUNTIME_ERRORS = (eqx.EquinoxRuntimeError, jax.errors.JaxRuntimeError)


#: Per plane (vertical, horizontal), whether every fit fixes the common slope of both rails at
#: zero: it is invisible (pitch and yaw are relative to their reference position, and a
#: straightness channel's slope is its alignment, fitted).
FIX_SLOPE = (True, True)

class FitProblem(eqx.Module):
    """One fit's data, model, prior and gauge (host-side arrays; never traced itself).

    Attributes:
        meas: the merged measurements (SI). weights: ``(N,)`` 0/1 per merged row (0: an
            outlier). chan: each row's channel.
        family: the machine family (structure as unknowns). residual: the traced model's
            arrays (:class:`.model._Problem`). M: ``v = Mx``, ``(basis.size + n_q + n_l, n_x)``.
        Om_curv, Om_amp: the rail prior's curvature and amplitude matrices on ``θ`` (λ, κ
            excluded). lam: a given λ, or None (chosen by ``criterion``, ``"ml"``/``"gcv"``).
        q_bounds: ``(n_q, 2)`` range of ``q`` (prior σ).
        basis: the knot grid (m). Z: ``c = Zθ``. gauge: the fixed modes' names. fix_slope:
            which planes have the common slope fixed. lead_basis: ``(start, spacing, n)`` (m)
            of the lead spline, or ``()``. alignment_channels: the straightness channels with
            an alignment slope. n_lead: lead coefficients; n_l: all nuisance coefficients.
    """

    meas: Measurements
    weights: np.ndarray
    chan: np.ndarray
    family: MachineFamily
    residual: _Problem
    M: np.ndarray
    Om_curv: np.ndarray
    Om_amp: np.ndarray
    q_bounds: np.ndarray
    basis: RailBasis
    Z: np.ndarray
    lam: float | None = eqx.field(static=True)
    criterion: str = eqx.field(static=True)
    gauge: tuple[str, ...] = eqx.field(static=True)
    fix_slope: tuple[bool, bool] = eqx.field(static=True)
    lead_basis: tuple = eqx.field(static=True)
    alignment_channels: tuple[int, ...] = eqx.field(static=True)
    n_lead: int = eqx.field(static=True)
    n_l: int = eqx.field(static=True)

    @property
    def n_theta(self) -> int:
        return self.Z.shape[1]

    @property
    def n_q(self) -> int:
        return self.family.n_params

    @property
    def n_x(self) -> int:
        return self.n_theta + self.n_q + self.n_l

    @property
    def n_chan(self) -> int:
        return self.residual.n_chan

    @property
    def iq(self) -> np.ndarray:
        """Columns of the structural unknowns."""
        return np.arange(self.n_theta, self.n_theta + self.n_q)

    @property
    def ic(self) -> np.ndarray:
        """Columns of the rails and nuisances: solved by LM at a given structure."""
        return np.setdiff1d(np.arange(self.n_x), self.iq)

    def with_weights(self, weights) -> "FitProblem":
        """The same problem with the rows' weights replaced (0: an outlier)."""
        weights = np.array(weights, float)
        residual = eqx.tree_at(lambda p: p.weight, self.residual, jnp.asarray(weights))
        return eqx.tree_at(lambda p: (p.weights, p.residual), self, (weights, residual))

    def linearise(self, x):
        """``(r, J, pred, ok, Jc)`` at ``x``: whitened residual ``(N,)``, its Jacobian in ``x``
        ``(N, n_x)``, model values (SI), whether every equilibrium converged, and the Jacobian
        in all rail coefficients ``c`` (µm). A model that fails at ``x`` gives NaN and
        ``ok = False`` (the trial point is then rejected like a non-converged one)."""
        M, n = self.M, self.meas.n
        try:
            r, Jv, pred, ok = (np.asarray(a) for a in _linearise(jnp.asarray(M @ x),
                                                                  self.residual))
        except _RUNTIME_ERRORS as exc:  # an equilibrium's check raised (EQX_ON_ERROR=raise)
            _log.info("fit: the model failed at a trial point (%s)", type(exc).__name__)
            nan = np.full(n, np.nan)
            return nan, np.full((n, self.n_x), np.nan), nan, False, None
        return r, Jv @ M, pred, ok, Jv[:, :self.basis.size]

    def penalty(self, choice: WeightChoice) -> np.ndarray:
        """``P`` of the objective ``‖r‖² + xᵀPx`` for the weight ``choice``, ``(n_x, n_x)``."""
        n_theta, n_q, n_x = self.n_theta, self.n_q, self.n_x
        P = np.zeros((n_x, n_x))
        P[:n_theta, :n_theta] = choice.lam * (self.Om_curv + choice.kappa * self.Om_amp)
        P[n_theta:n_theta + n_q, n_theta:n_theta + n_q] = np.eye(n_q)
        P[n_theta + n_q:, n_theta + n_q:] = LEAD_RIDGE**2 * np.eye(self.n_l)
        return P

    def rail_data(self, J, r, x):
        """The data in the rail unknowns at the structure in ``x``, nuisance columns projected
        out: ``(J̃, ỹ, rank of the nuisance columns)``; ``r(x + δ) ≈ r − J_c x_c + J_c(x_c +
        δ_c)``, so ``y = −(r − J_c x_c)``."""
        ic, n_theta, n_q = self.ic, self.n_theta, self.n_q
        y = -(r - J[:, ic] @ x[ic])
        return project_out(J[:, n_theta + n_q:], J[:, :n_theta], y)

    def choose(self, J, r, x, weights, criterion: str | None = None) -> WeightChoice:
        """λ (and κ) on the problem linearised at ``x`` (nuisance columns projected out): the
        given λ, else by ``criterion`` (default the problem's)."""
        used = int(np.sum(weights > 0))
        Jt, yp, rank_f = self.rail_data(J, r, x)
        n_eff = used - self.n_chan - rank_f
        if self.lam is not None:
            return fixed_weight(self.lam, Jt, yp, self.Om_curv + self.Om_amp, n_eff)
        return choose_prior(Jt, yp, self.Om_curv, self.Om_amp, n_eff,
                            criterion or self.criterion)


def _check_stroke(machine, position) -> None:
    """Refuse measured positions (m) beyond the machine's stroke ``±stroke/2``, where the
    machine knows it (built from a specification), naming the range in m and mm."""
    stroke = getattr(machine, "stroke", None)
    x = np.asarray(position, dtype=float)
    if stroke is None or x.size == 0 or np.max(np.abs(x)) <= stroke / 2 + 1e-9:
        return
    worst = float(x[np.argmax(np.abs(x))])
    hint = "" if abs(worst) < 1.0 else f": did you mean {worst:g} mm = {worst * 1e-3:g} m?"
    raise ValueError(
        f"meas.position reaches {worst:g} m, beyond the machine's stroke "
        f"[{-stroke / 2:g}, {stroke / 2:g}] m (±{stroke / 2 * 1e3:g} mm){hint}"
    )


def build_problem(machine, meas: Measurements, *, knot_spacing: float | None,
                  lam: float | None, criterion: str, x_ref: float, joints=(),
                  joint_width: float = JOINT_WIDTH) -> FitProblem:
    """The :class:`FitProblem` of :func:`~.fit.fit_rails`' arguments (their units): the knot
    grid over the visited rail length with a step at each rail joint (m), the gauge, the prior
    matrices, the nuisance columns.
    ``ValueError`` when the machine's points are not the measurements' or the data are fewer
    than the channels and nuisances."""
    family = _as_family(machine)
    base = family.base
    if tuple(base.point_names) != tuple(meas.point_names):
        raise ValueError(
            f"the machine's points {base.point_names} differ from the measurement points "
            f"{meas.point_names}; build the machine with points=... from the measurements"
        )
    length("x_ref", x_ref, *POSITION_RANGE)
    length("meas.position", meas.position, *POSITION_RANGE)
    _check_stroke(base, meas.position)
    if knot_spacing is None:
        knot_spacing = base.carriage.length
        if not knot_spacing >= KNOT_SPACING_RANGE[0]:
            raise ValueError(
                f"the default knot spacing, the carriage's loaded length, is {knot_spacing:g} m "
                f"(a carriage of {base.carriage.n_elements} element(s) per row; at least 2 are "
                "needed): give knot_spacing (m) or a carriage with elements_per_row >= 2"
            )
    else:
        length("knot_spacing", knot_spacing, *KNOT_SPACING_RANGE)
    _check_priors(family)
    basis = RailBasis.covering(*visited_range(base, meas.position), knot_spacing, joints,
                               joint_width)
    fix_slope = FIX_SLOPE
    C, gauge = basis.gauge_functionals(fix_slope)
    Z = null_space_basis(C, basis.size)
    G2, G0 = basis.penalty_factor() @ Z, basis.amplitude_factor() @ Z
    lead_B, lead_basis = _lead_basis(meas)
    align_S, align_chan = _alignment_columns(meas)
    nuisance_B = np.hstack([lead_B, align_S])  # the ℓ columns: lead, then alignment slopes
    n_theta, n_q, n_l = Z.shape[1], family.n_params, nuisance_B.shape[1]
    prob = _problem(family, meas, basis, nuisance_B, x_ref)
    M = np.zeros((basis.size + n_q + n_l, n_theta + n_q + n_l))  # v = M x
    M[:basis.size, :n_theta] = Z
    M[basis.size:, n_theta:] = np.eye(n_q + n_l)
    if meas.n - prob.n_chan - n_l <= 0:
        raise ValueError(f"{meas.n} measurements in {prob.n_chan} channels: nothing to fit")
    q_bounds = family.bounds() / family.prior_sigma()[:, None] if n_q else np.zeros((0, 2))
    return FitProblem(
        meas=meas, weights=np.ones(meas.n), chan=meas.channel_index(), family=family,
        residual=prob, M=M, Om_curv=G2.T @ G2, Om_amp=G0.T @ G0, q_bounds=q_bounds,
        basis=basis, Z=Z, lam=lam, criterion=criterion, gauge=tuple(gauge),
        fix_slope=fix_slope, lead_basis=lead_basis, alignment_channels=align_chan,
        n_lead=lead_B.shape[1], n_l=n_l,
    )


def _check_priors(family: MachineFamily) -> None:
    """Refuse structure priors outside the plausible ranges (thickness in m, preload as a
    fraction of C), naming the prior and the range."""
    priors = family.priors
    if priors is None:
        return
    for name, (lo, hi), unit in (("thickness", THICKNESS_RANGE, "m"),
                                 ("preload", PRELOAD_RANGE, "of C"),
                                 ("stiffness", STIFFNESS_RANGE, "(a scale)")):
        prior = getattr(priors, name, None)
        if prior is None:
            continue
        if name == "thickness":
            for part in ("value", "lo", "hi"):
                length(f"the thickness prior's {part}", getattr(prior, part), lo, hi)
        elif not (lo <= prior.lo and prior.hi <= hi):
            raise ValueError(
                f"the {name} prior's range ({prior.lo:g}, {prior.hi:g}) must lie within "
                f"[{lo:g}, {hi:g}] {unit}"
            )


def visited_range(machine: Machine, positions) -> tuple[float, float]:
    """Rail length ``[lo, hi]`` (m) the rolling elements visit over ``positions`` (m) and x = 0."""
    x = np.concatenate([np.asarray(positions, float), [0.0]])
    xc = np.asarray(machine.carriage_x, float)
    xi = np.asarray(machine.carriage.xi, float)
    return float(x.min() + xc.min() + xi.min()), float(x.max() + xc.max() + xi.max())


def _lead_basis(meas: Measurements):
    """The lead-error spline over the positions of the EXX rows: ``(B (N, n), (start, h, n))``;
    no columns without EXX data."""
    exx = np.asarray(meas.quantity) == _EXX
    if not exx.any():
        return np.zeros((meas.n, 0)), ()
    x = np.asarray(meas.position)[exx]
    lo, hi = float(x.min()), float(x.max())
    if hi - lo < 1e-9:
        return np.zeros((meas.n, 0)), ()
    basis = RailBasis.covering(lo, hi, min(LEAD_KNOT_SPACING, (hi - lo) / 1.0))
    B = np.zeros((meas.n, basis.n_coeffs))
    B[exx] = bspline_matrix(x, basis.start, basis.spacing, basis.n_coeffs)
    return B, (basis.start, basis.spacing, basis.n_coeffs)


def _alignment_columns(meas: Measurements):
    """One column per straightness channel (EYX, EZX): ``x − x̄_c`` (m) on its rows, 0 elsewhere,
    so that its coefficient (µm) is the channel's alignment slope in µm/m; and the channels."""
    chan = meas.channel_index()
    straight = np.isin(np.asarray(meas.quantity), _STRAIGHTNESS)
    cs = np.unique(chan[straight])
    S = np.zeros((meas.n, len(cs)))
    for k, c in enumerate(cs):
        rows = chan == c
        x = np.asarray(meas.position)[rows]
        S[rows, k] = x - x.mean()
    return S, tuple(int(c) for c in cs)


def _problem(family: MachineFamily, meas: Measurements, basis: RailBasis, lead_B, x_ref):
    """The traced model's arrays (:class:`.model._Problem`) for ``meas`` on ``basis``, with the
    nuisance columns ``lead_B`` ``(N, n_l)`` and the reference position ``x_ref`` (m)."""
    positions, pos_idx = np.unique(np.round(meas.position, 9), return_inverse=True)
    chan = meas.channel_index()
    return _Problem(
        family=family, positions=jnp.asarray(positions),
        pos_idx=jnp.asarray(pos_idx), pt_idx=jnp.asarray(meas.point),
        q_idx=jnp.asarray(meas.quantity), value=jnp.asarray(meas.value),
        sigma=jnp.asarray(meas.sigma), weight=jnp.ones(meas.n), z=jnp.asarray(meas.z),
        lead=jnp.asarray(lead_B), chan=jnp.asarray(chan),
        prior_sigma=jnp.asarray(family.prior_sigma()), x_ref=jnp.asarray(float(x_ref)),
        basis=basis, n_chan=int(chan.max()) + 1, n_q=family.n_params,
    )


def _as_family(machine) -> MachineFamily:
    """``machine`` as a :class:`.structure.MachineFamily` (a plain machine: no unknowns)."""
    if isinstance(machine, MachineFamily):
        return machine
    return MachineFamily(machine, None, (), 0.0, 1.0, StructurePriors())


