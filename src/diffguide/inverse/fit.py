r"""Rail profiles — and the machine's unknown structure — from measured joint kinematic errors:
regularised Levenberg–Marquardt through the differentiable machine model.

**Unknowns** ``x = (θ, q, ℓ)``:

- ``θ``: the rail profiles' B-spline coefficients (µm, :mod:`.basis`) in the gauge-fixed
  parametrisation ``c = Zθ``;
- ``q``: the structural parameters (:mod:`.structure`: ``ln`` of the table's equivalent
  thickness and of the preload relative to their prior values), scaled by their prior σ
  (``q ~ N(0, 1)``);
- ``ℓ``: the feed screw's lead error (µm), a cubic B-spline in the table position added to every
  EXX channel — the model has no lead error, and a positioning channel without this term would
  bend the rails to explain it (:data:`LEAD_KNOT_SPACING`) — and each straightness channel's
  alignment slope ``a_c`` (µm/m): straightness optics read against a reference line (a laser
  beam, a straightedge) that is never exactly parallel to the axis, and ISO 230-1 removes that
  slope from every straightness curve; without the term it would tilt the rails. The rails'
  common slope in each plane is then invisible and fixed by the gauge (:mod:`.basis`).

**Residuals**, one per merged measurement ``i`` of channel ``c(i)`` (point, quantity,
instrument):

.. math::  r_i = w_i\bigl(m_i(x) - y_i - o_{c(i)}\bigr)/σ_i,\qquad
           m_i = E_{q_i}(P_i) + z_i\,A_{q_i}(P_i) + [q_i = \mathrm{EXX}]\,ℓ(x_i)
                 + [q_i ∈ \{\mathrm{EYX}, \mathrm{EZX}\}]\,a_{c(i)}(x_i - \bar x_{c(i)}),

``E`` the model's joint errors (:func:`~diffguide.kinematics.joint_errors` of the machine at
``q``, every equilibrium differentiated implicitly), ``z_i`` the sensing point's height above
the table top with the Abbe terms ``A_EXX = EBX``, ``A_EYX = −EAX`` (0 otherwise), ``o_c`` each
channel's zero — profiled out as the channel's weighted mean misfit — and ``w_i ∈ {0, 1}`` (0 for
merged values rejected as outliers, below). The fit minimises

.. math::  ‖r(x)‖² + λθᵀΩθ + ‖q‖² + ε²‖ℓ‖²,\qquad
           θᵀΩθ = Σ∫e''² ds + κ ℓ_r⁻⁴Σ∫e² ds

(``ℓ`` there stands for the lead coefficients and the alignment slopes; ``ε`` = 1e-3 µm⁻¹
keeps them proper; λ and κ chosen by the data, :mod:`.weight`).

**The structure by marginal likelihood** (:mod:`.marginal`). ``q`` is not taken from the joint
minimum of that objective — the joint mode of a scale-like parameter under a shrinkage prior is
biased (a structure that makes the data more sensitive to the rails lets smaller rails explain
them) — but from the marginal likelihood, with the rails integrated out under their prior:
``q̂ = argmin −2 log p(y | q) + ‖q‖²``, Newton steps on central differences of the problem
linearised in the rails (first at straight rails, then again at the fitted rails); data with no
content (zero to round-off once the channel zeros and the lead are removed: all-zero readings,
constant channels) leave ``q`` at its prior, value and σ, with a message
(:func:`.marginal.carries_information`). At ``q̂`` the
rails and lead minimise the objective above by Levenberg–Marquardt (:func:`_levenberg_marquardt`:
one compiled linearisation — residual and ``jacfwd`` Jacobian through the implicit equilibria —
per step, the damped normal equations solved in NumPy), started from the Gauss–Newton step. λ
is chosen on the problem linearised at the current estimate (:mod:`.weight`: marginal likelihood
by default, GCV on request, or given), with the lead unknowns projected out, then re-chosen at
the solution and the fit repeated once if it moved by more than a factor 1.5.

**Outliers.** Gross outliers among the readings are set aside when merging
(:mod:`diffguide.measurements`); a merged value whose standardised residual still exceeds
:data:`OUTLIER_Z` after the fit is given zero weight and the fit repeated once (reported).

**Uncertainty.** The rails and lead given the structure: the Gauss–Newton posterior
``s²H_c⁻¹``, ``H_c = J_cᵀJ_c + P_c``, ``P_c = diag(λΩ, ε²I)``; the structure's own posterior
``Cov q`` (the Laplace approximation of the marginal likelihood, :mod:`.marginal`) carried into
them by the delta method,

.. math::  \mathrm{Cov}\,c = s²H_c⁻¹ + G\,\mathrm{Cov}\,q\,Gᵀ,\qquad
           G = ∂ĉ/∂q,

so the rails' bands include the structure's uncertainty and widen where the structure is not
determined. ``G`` is a secant over ``±σ_q`` along each unknown: the rails solved again on the
model linearised at ``q ± σ_q`` (:func:`_structure_sensitivity`, two linearisations per
unknown). The Gauss–Newton tangent ``−H_c⁻¹J_cᵀJ_q`` it replaces leaves out that the structure
scales how strongly the rails show in the data (a stiffer table shows a rail difference less):
on the battery's straightness case its thickness column was a third of what refitting moves
the rails. ``s² = max(1, χ²/dof)``: when the model does not explain the data to their stated σ,
the bands widen accordingly (never narrow). ``χ²/dof = ‖r‖² / (N − n_channels − edf)``,
``edf = tr(H_c⁻¹J_cᵀJ_c) + tr(I − Cov q)``.

**Always an answer.** The fit returns its best estimate whatever happens after the first
linearisation: ``converged`` is False with the reason in ``message`` when LM stops on its step
limit or an equilibrium fails.
"""

import logging

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.aot import cached_program
from .._core.precision import require_x64
from ..guideway.rails import SplineRail, bspline_matrix
from ..machine.equilibrium import Machine
from ..machine.kinematics import joint_errors_traced
from .basis import RailBasis, null_space_basis
from .data import QUANTITIES, Measurements
from .marginal import (
    carries_information,
    laplace,
    marginal_parts,
    maximise_marginal,
    score_of_parts,
)
from .structure import DETERMINED_RATIO, MachineFamily, StructurePriors
from .weight import WeightChoice, choose_prior, fixed_weight, project_out

_UM = 1e-6
_log = logging.getLogger("diffguide")
#: Knot spacing of the lead-error spline (m), at most; at least 4 coefficients over the stroke.
LEAD_KNOT_SPACING = 0.1
#: Ridge on the lead-error coefficients (1/µm): a prior σ of 1 mm, i.e. none in practice.
LEAD_RIDGE = 1e-3
#: Standardised residual beyond which a merged value is an outlier.
OUTLIER_Z = 5.0
_EXX, _EYX = QUANTITIES.index("EXX"), QUANTITIES.index("EYX")
_STRAIGHTNESS = (QUANTITIES.index("EYX"), QUANTITIES.index("EZX"))
#: What a failed equilibrium raises inside the compiled model (equinox's runtime checks under
#: ``EQX_ON_ERROR=raise``, the default outside the CLI; XLA's runtime error).
_RUNTIME_ERRORS = (eqx.EquinoxRuntimeError, jax.errors.JaxRuntimeError)
_EAX, _EBX = QUANTITIES.index("EAX"), QUANTITIES.index("EBX")


class _Problem(eqx.Module):
    """Everything the residual needs; arrays travel as arguments (never closed over)."""

    family: MachineFamily
    positions: jax.Array
    pos_idx: jax.Array
    pt_idx: jax.Array
    q_idx: jax.Array
    value: jax.Array
    sigma: jax.Array
    weight: jax.Array
    z: jax.Array
    lead: jax.Array
    chan: jax.Array
    prior_sigma: jax.Array
    x_ref: jax.Array
    start: float = eqx.field(static=True)
    spacing: float = eqx.field(static=True)
    n_coeffs: int = eqx.field(static=True)
    n_chan: int = eqx.field(static=True)
    n_q: int = eqx.field(static=True)

    @property
    def n_c(self) -> int:
        return 4 * self.n_coeffs


def _rails(c_um, prob: _Problem):
    c = c_um.reshape(2, 2, prob.n_coeffs) * _UM
    return tuple(SplineRail(prob.start, prob.spacing, c[r, 0], c[r, 1]) for r in range(2))


def _model(v, prob: _Problem):
    """Model values (SI) at every merged measurement, and whether every equilibrium converged;
    ``v = (c, q, ℓ)``: all rail coefficients (µm), structure, lead (µm)."""
    c = v[: prob.n_c]
    q = v[prob.n_c: prob.n_c + prob.n_q]
    ell = v[prob.n_c + prob.n_q:]
    machine = prob.family.machine(q * prob.prior_sigma)
    # Newton on all 30 DOF: the smaller program (this one is traced, differentiated and
    # compiled for a few calls, where the condensed solve's run time does not pay its compile)
    je = joint_errors_traced(
        machine, _rails(c, prob), prob.positions, prob.x_ref, condensed=False
    )
    E = je.errors[prob.pos_idx, prob.pt_idx]  # (N, 6)
    base = jnp.take_along_axis(E, prob.q_idx[:, None], axis=1)[:, 0]
    abbe = jnp.where(prob.q_idx == _EXX, E[:, _EBX], jnp.where(prob.q_idx == _EYX, -E[:, _EAX],
                                                                0.0))
    pred = base + prob.z * abbe + (prob.lead @ ell) * _UM
    return pred, jnp.all(je.converged)


def _data_residual_full(x, prob: _Problem):
    """Whitened residuals with the channel zeros profiled out, model values, convergence."""
    pred, ok = _model(x, prob)
    d = pred - prob.value
    w = prob.weight / prob.sigma**2
    off = jax.ops.segment_sum(w * d, prob.chan, prob.n_chan) / jnp.maximum(
        jax.ops.segment_sum(w, prob.chan, prob.n_chan), 1e-300)
    return prob.weight * (d - off[prob.chan]) / prob.sigma, pred, ok


def _linearise_traced(v, prob: _Problem):
    """Residual, Jacobian w.r.t. ``v = (c, q, ℓ)``, model values, convergence."""

    def f(t):
        r, pred, ok = _data_residual_full(t, prob)
        return r, (r, pred, ok)

    J, (r, pred, ok) = jax.jacfwd(f, has_aux=True)(v)
    return r, J, pred, ok


#: The compiled linearisation; with an export folder set (the command line sets one,
#: :mod:`diffguide._core.aot`) a later process reads the traced program back instead of
#: tracing it again (seconds); without one, the ``filter_jit`` function itself.
_linearise = cached_program(eqx.filter_jit(_linearise_traced), "inverse.fit._linearise")


#: Floor of the noise scale ``ŝ²`` (objective per datum) in Levenberg–Marquardt's stop rule.
_SCALE_FLOOR = 1e-24


def _levenberg_marquardt(x, r, J, pred, Jc, linearise, P, rtol, max_steps):
    """Minimise ``‖r(x)‖² + xᵀPx`` from ``x`` (with ``r``, ``J`` there) by Levenberg–Marquardt
    with Marquardt's diagonal scaling; one compiled linearisation per step (the model is nearly
    linear in µm-sized rail errors, so the Gauss–Newton step, μ = 0, is tried first).

    Stops when the Gauss–Newton decrement ``δᵀHδ`` (the χ² a full step would still gain) is below
    ``rtol·ŝ²`` — a change of the objective far below the noise scale means nothing
    statistically. ``ŝ²`` is the objective per datum at the start (≈ 1 when the stated σ are
    right; with σ all stated 10⁹× too large it is 10⁻¹⁸, and the rule stays the same rule),
    floored at :data:`_SCALE_FLOOR` (data that are zero to round-off stop at once).
    Returns ``(x, r, J, pred, Jc, converged, steps, reason)``.
    """
    cost = float(r @ r + x @ P @ x)
    rtol = rtol * max(cost / max(len(r), 1), _SCALE_FLOOR)
    mu = 0.0
    for step in range(1, max_steps + 1):
        H = J.T @ J + P
        g = J.T @ r + P @ x
        D = np.diag(np.diag(H))
        try:
            delta = -np.linalg.solve(H + mu * D, g)
        except np.linalg.LinAlgError:
            mu = max(mu * 10, 1e-6)
            continue
        decrement = float(-g @ delta)
        if decrement < rtol and mu == 0.0:
            return x, r, J, pred, Jc, True, step - 1, "converged"
        r_t, J_t, pred_t, ok_t, Jc_t = linearise(x + delta)
        cost_t = (float(r_t @ r_t + (x + delta) @ P @ (x + delta))
                  if ok_t and np.all(np.isfinite(J_t)) else np.inf)
        if cost_t <= cost:
            x, r, J, pred, Jc, cost = x + delta, r_t, J_t, pred_t, Jc_t, cost_t
            if decrement < rtol:
                return x, r, J, pred, Jc, True, step, "converged"
            mu = 0.0 if mu <= 1e-6 else mu / 10
        else:
            mu = max(mu * 10, 1e-6)
            if mu > 1e12:
                return x, r, J, pred, Jc, False, step, (
                    "Levenberg-Marquardt cannot decrease the objective further (the damping "
                    "reached 1e12); the best estimate so far is returned")
    return x, r, J, pred, Jc, False, max_steps, (
        f"Levenberg-Marquardt stopped after {max_steps} steps without meeting its tolerance; "
        "the best estimate so far is returned")


class RailFit(eqx.Module):
    """Result of :func:`fit_rails` (SI unless stated).

    Attributes:
        basis: the knot grid. coeffs: ``(2 rails, 2 planes, n)`` spline coefficients (m),
            planes ``(vertical, horizontal)``. cov: posterior covariance of the stacked
            coefficients (order of :data:`~.basis.PROFILES`; m²), marginal over the structure
            and lead unknowns, scaled by ``sigma_scale²``.
        Z: the gauge-fixed parametrisation (``c = Zθ``). gauge: names of the fixed modes.
        fix_slope: which planes have the common slope fixed.
        lam: regularisation weight. weight: how it was chosen (:class:`.weight.WeightChoice`).
        structure: per structural unknown ``{value, sigma, prior_value, prior_sigma,
            determined, at_bound}`` (thickness in m, preload as a fraction; σ of the value).
        lead: lead-error coefficients (m) and ``lead_basis`` ``(start, spacing, n)`` (m);
            empty without EXX data. alignment: each straightness channel's alignment slope
            (rad), for the channels ``alignment_channels`` (indices into ``meas.channels``).
        fitted: model at every merged measurement, shifted by its channel zero (m or rad).
        residual: measured − fitted. offsets: each channel's zero (model − measured).
        outliers: merged rows given zero weight. chi2, dof, edf: χ² of the used rows, degrees
            of freedom ``N − n_channels − edf``, effective parameters (all unknowns).
        sigma_scale: ``max(1, χ²/dof)^½``, applied to every σ. converged: LM and every
            equilibrium converged. message: what happened, in words. steps: LM steps.
        jacobian: whitened data Jacobian ``∂r/∂x`` at the solution (all unknowns);
            jacobian_full: the same w.r.t. all rail coefficients ``c`` (µm), gauge modes
            included. penalty: ``P``. n_theta: rail unknowns (first columns of ``jacobian``).
            Omega: the rail prior's matrix ``Ω`` (λ excluded). rigid: fitted with the rigid-table
            model. waviness: the stated RMS (m) of rail content shorter than the knot grid
            resolves, in every σ of :meth:`profiles` (:func:`fit_rails`).
            structure_sensitivity: the delta method's ``G = ∂ĉ/∂q`` — how the fitted spline
            coefficients move (m) per prior σ of each structural unknown (its log), ``(2 rails,
            2 planes, n, n_q)``; structure_cov: ``Cov q`` in the same units ``(n_q, n_q)``
            (empty without structural unknowns).
    """

    basis: RailBasis
    coeffs: np.ndarray
    cov: np.ndarray
    Z: np.ndarray
    gauge: tuple[str, ...] = eqx.field(static=True)
    fix_slope: tuple[bool, bool] = eqx.field(static=True)
    lam: float
    weight: WeightChoice
    structure: dict
    lead: np.ndarray
    lead_basis: tuple
    fitted: np.ndarray
    residual: np.ndarray
    offsets: np.ndarray
    outliers: np.ndarray
    chi2: float
    dof: float
    edf: float
    sigma_scale: float
    converged: bool
    message: str
    steps: int
    jacobian: np.ndarray
    jacobian_full: np.ndarray
    penalty: np.ndarray
    n_theta: int
    Omega: np.ndarray
    rigid: bool = eqx.field(static=True)
    waviness: float = 0.0
    alignment: np.ndarray = eqx.field(default_factory=lambda: np.zeros(0))
    alignment_channels: tuple[int, ...] = eqx.field(static=True, default=())
    structure_sensitivity: np.ndarray = eqx.field(default_factory=lambda: np.zeros(0))
    structure_cov: np.ndarray = eqx.field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def chi2_dof(self) -> float:
        return self.chi2 / self.dof if self.dof > 0 else float("nan")

    @property
    def gcv(self) -> float:
        """The weight criterion's score (kept for the report; NaN for a given λ)."""
        return self.weight.score

    def profiles(self, s) -> tuple[np.ndarray, np.ndarray]:
        """Profiles and their posterior σ at ``s`` (m): two arrays (m) of shape
        ``(2 rails, 2 planes) + np.shape(s)``, i.e. ``(2, 2, len(s))`` for 1-D ``s`` and
        ``(2, 2)`` for a scalar; planes ``(vertical, horizontal)``.
        ``σ² = bᵀ Cov b + waviness²`` (``b`` the basis functions at ``s``).

        ``s`` must be finite (``ValueError`` otherwise) and a scalar or 1-D. Outside the fitted
        range ``[basis.start, basis.end]`` the end segments' cubics are continued (an
        extrapolation the data do not support)."""
        s = np.asarray(s, dtype=float)
        if s.ndim > 1:
            raise ValueError(f"s must be a scalar or a 1-D array (m), got shape {s.shape}")
        if not np.all(np.isfinite(s)):
            raise ValueError(f"s must be finite (m); it holds {s[~np.isfinite(s)][:3]}")
        shape = s.shape
        B = self.basis.matrix(np.atleast_1d(s))
        n = self.basis.n_coeffs
        val = np.einsum("sk,rpk->rps", B, self.coeffs)
        sig = np.zeros_like(val)
        for k in range(4):
            r, p = divmod(k, 2)
            C = self.cov[k * n:(k + 1) * n, k * n:(k + 1) * n]
            sig[r, p] = np.sqrt(np.maximum(np.einsum("sk,kl,sl->s", B, C, B), 0.0)
                                + self.waviness**2)
        return val.reshape((2, 2) + shape), sig.reshape((2, 2) + shape)

    def rails(self) -> tuple[SplineRail, SplineRail]:
        """The fitted profiles as :class:`~diffguide.rails.SplineRail` (rail 1, rail 2)."""
        c = self.coeffs
        return tuple(SplineRail(self.basis.start, self.basis.spacing, jnp.asarray(c[r, 0]),
                                jnp.asarray(c[r, 1])) for r in range(2))

    def to_dataframe(self, s=None):
        """The profiles as a ``pandas.DataFrame`` in user units, the columns of ``rails.csv``:
        ``rail, s_mm, vertical_um, vertical_sigma_um, horizontal_um, horizontal_sigma_um`` at
        ``s`` (m; a scalar or 1-D, finite; default every 2 mm over the fitted range): one row
        per rail and ``s`` (a scalar ``s`` gives two rows). Needs the ``[pandas]`` extra."""
        from .._core.frames import require_pandas

        pd = require_pandas()
        if s is None:
            s = np.arange(self.basis.start, self.basis.end + 1e-12, 2e-3)
        s = np.asarray(s, dtype=float)
        if s.ndim == 0:
            s = s[None]
        val, sig = self.profiles(s)
        parts = []
        for r in range(2):
            parts.append(pd.DataFrame({
                "rail": r + 1, "s_mm": s * 1e3,
                "vertical_um": val[r, 0] * 1e6, "vertical_sigma_um": sig[r, 0] * 1e6,
                "horizontal_um": val[r, 1] * 1e6, "horizontal_sigma_um": sig[r, 1] * 1e6,
            }))
        return pd.concat(parts, ignore_index=True)


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
    positions, pos_idx = np.unique(np.round(meas.position, 9), return_inverse=True)
    chan = meas.channel_index()
    return _Problem(
        family=family, positions=jnp.asarray(positions),
        pos_idx=jnp.asarray(pos_idx), pt_idx=jnp.asarray(meas.point),
        q_idx=jnp.asarray(meas.quantity), value=jnp.asarray(meas.value),
        sigma=jnp.asarray(meas.sigma), weight=jnp.ones(meas.n), z=jnp.asarray(meas.z),
        lead=jnp.asarray(lead_B), chan=jnp.asarray(chan),
        prior_sigma=jnp.asarray(family.prior_sigma()), x_ref=jnp.asarray(float(x_ref)),
        start=basis.start, spacing=basis.spacing, n_coeffs=basis.n_coeffs,
        n_chan=int(chan.max()) + 1, n_q=family.n_params,
    )


def _as_family(machine) -> MachineFamily:
    if isinstance(machine, MachineFamily):
        return machine
    return MachineFamily(machine, None, (), 0.0, 1.0, StructurePriors())


#: Half-step of :func:`_structure_sensitivity`'s secant, within these limits (prior σ).
SECANT_STEP_LIMITS = (0.05, 1.0)


def _structure_sensitivity(linearise, x_at, x, J, ic, iq, q_bounds, cov_q, Pc, Hc_inv):
    """``G = ∂ĉ/∂q`` at the solution ``x``, ``(len(ic), len(iq))``: how the rails and lead that
    minimise the objective move with each structural unknown, as a secant over ``±σ_q``.

    At each step ``q_v`` the rails are solved again on the model linearised there — one
    Gauss–Newton step from ``x_c``, ``ĉ(q_v) = x_c − H_v⁻¹(J_vᵀr_v + P_c x_c)``, the model being
    all but linear in the rails (``r_v = r(x_at(q_v)) + J_v·(x_c − x_at,c)``: ``x_at``, where
    the model was linearised, is ``x`` for Levenberg–Marquardt) — and ``G_i = (ĉ(q + h) −
    ĉ(q − h))/2h``. The half-step ``h`` is the unknown's posterior σ, ``√Cov q_ii``, within
    :data:`SECANT_STEP_LIMITS` and its bounds (one-sided at a bound). Where the model fails at a
    step the column is the Gauss–Newton ``−H_c⁻¹J_cᵀJ_q``, and a note is logged.
    """
    out = np.empty((len(ic), len(iq)))
    for i, k in enumerate(iq):
        h = float(np.clip(np.sqrt(max(cov_q[i, i], 0.0)), *SECANT_STEP_LIMITS))
        a, b = max(x_at[k] - h, q_bounds[i, 0]), min(x_at[k] + h, q_bounds[i, 1])
        c = []
        for v in (a, b) if b > a else ():
            xv = x_at.copy()
            xv[k] = v
            r_v, J_v, _, ok_v, _ = linearise(xv)
            if not (ok_v and np.all(np.isfinite(J_v)) and np.all(np.isfinite(r_v))):
                break
            Jv = J_v[:, ic]
            r_v = r_v + Jv @ (x[ic] - x_at[ic])
            c.append(-np.linalg.solve(_spd(Jv.T @ Jv + Pc), Jv.T @ r_v + Pc @ x[ic]))
        if len(c) == 2:
            out[:, i] = (c[1] - c[0]) / (b - a)
        else:
            _log.info("fit: %s: the structure's share of the rails' σ from the Gauss-Newton "
                      "term alone", "the model failed around the structure's estimate"
                      if b > a else "the unknown's bounds leave no room for a step")
            out[:, i] = -Hc_inv @ (J[:, ic].T @ J[:, k])
    return out


def fit_rails(
    machine,
    meas: Measurements,
    *,
    knot_spacing: float | None = None,
    lam: float | None = None,
    criterion: str = "ml",
    x_ref: float = 0.0,
    rtol: float = 1e-6,
    max_steps: int = 60,
    method: str = "lm",
    reject_outliers: bool = True,
    waviness: float = 0.0,
) -> RailFit:
    """Fit the rail straightness profiles (and the structure) to merged measurements.

    Arguments:
        machine: a :class:`~diffguide.machine.Machine` (structure fixed) or a
            :class:`~.structure.MachineFamily` (structure estimated), whose points are
            ``meas.point_names`` (same order); ``machine.with_rigid_table()`` gives the classical
            rigid-table inversion.
        meas: merged measurements (:func:`diffguide.measurements.read_measurements`).
        knot_spacing: requested knot spacing (m); default the carriage's loaded length
            (``n·p``, 48 mm for ``majda2012``): shorter wavelengths are averaged out by the
            carriage, so finer knots only add undetermined unknowns.
        lam: regularisation weight; default chosen by ``criterion`` (:mod:`.weight`).
        criterion: ``"ml"`` (marginal likelihood) or ``"gcv"``.
        x_ref: reference position of the model (m); the result does not depend on it.
        rtol: LM tolerance on the Gauss–Newton decrement, relative to the χ² per datum.
            max_steps: LM step limit per pass.
        method: ``"lm"`` (through the nonlinear model) or ``"linear"`` (linearised at straight
            rails and solved once: the classical linear inversion).
        reject_outliers: zero-weight merged values beyond :data:`OUTLIER_Z` and refit once.
        waviness: RMS (m) of the rails' short-wave content — wavelengths shorter than about
            two knot spacings, which the basis cannot represent and the carriages average out
            (at the default knots, the carriage's loaded length) — as the user knows it from
            the rails' grade. The data cannot estimate it (those wavelengths move no
            carriage); it is added in quadrature to every profile σ. Default 0: the bands then
            cover only what the knot grid resolves.

    Raises ``ValueError`` for inputs that cannot be fitted at all (mismatched points, fewer data
    than channels, a model that does not converge for straight rails); everything after that
    returns a :class:`RailFit` (see ``converged`` and ``message``).
    """
    if method not in ("lm", "linear"):
        raise ValueError(f"method must be 'lm' or 'linear', got {method!r}")
    if not (np.isfinite(waviness) and waviness >= 0.0):
        raise ValueError(f"waviness must be a finite RMS >= 0 m, got {waviness!r}")
    require_x64("fit_rails")
    family = _as_family(machine)
    base = family.base
    if tuple(base.point_names) != tuple(meas.point_names):
        raise ValueError(
            f"the machine's points {base.point_names} differ from the measurement points "
            f"{meas.point_names}; build the machine with points=... from the measurements"
        )
    if knot_spacing is None:
        knot_spacing = base.carriage.length
    lo, hi = visited_range(base, meas.position)
    basis = RailBasis.covering(lo, hi, knot_spacing)
    # the common slope of both rails in a plane is invisible: pitch and yaw are relative to
    # their reference position, and a straightness channel's slope is its alignment (fitted)
    fix_slope = (True, True)
    C, gauge = basis.gauge_functionals(fix_slope)
    Z = null_space_basis(C, basis.size)
    G2, G0 = basis.penalty_factor() @ Z, basis.amplitude_factor() @ Z
    Om_curv, Om_amp = G2.T @ G2, G0.T @ G0
    lead_B, lead_basis = _lead_basis(meas)
    align_S, align_chan = _alignment_columns(meas)
    n_lead = lead_B.shape[1]
    nuisance_B = np.hstack([lead_B, align_S])  # the ℓ columns: lead, then alignment slopes
    n_theta, n_q, n_l = Z.shape[1], family.n_params, nuisance_B.shape[1]
    n_x = n_theta + n_q + n_l
    prob = _problem(family, meas, basis, nuisance_B, x_ref)
    n_chan, chan = prob.n_chan, meas.channel_index()
    M = np.zeros((basis.size + n_q + n_l, n_x))  # v = M x
    M[:basis.size, :n_theta] = Z
    M[basis.size:, n_theta:] = np.eye(n_q + n_l)

    def linearise(x_):
        try:
            r_, Jv, pred_, ok_ = (np.asarray(a) for a in _linearise(jnp.asarray(M @ x_), prob))
        except _RUNTIME_ERRORS as exc:  # an equilibrium's check raised (EQX_ON_ERROR=raise):
            _log.info("fit: the model failed at a trial point (%s)", type(exc).__name__)
            nan = np.full(meas.n, np.nan)  # the trial point is rejected like a non-converged one
            return nan, np.full((meas.n, n_x), np.nan), nan, False, None
        return r_, Jv @ M, pred_, ok_, Jv[:, :basis.size]
    if meas.n - n_chan - n_l <= 0:
        raise ValueError(f"{meas.n} measurements in {n_chan} channels: nothing to fit")

    def penalty(c):
        P = np.zeros((n_x, n_x))
        P[:n_theta, :n_theta] = c.lam * (Om_curv + c.kappa * Om_amp)
        P[n_theta:n_theta + n_q, n_theta:n_theta + n_q] = np.eye(n_q)
        P[n_theta + n_q:, n_theta + n_q:] = LEAD_RIDGE**2 * np.eye(n_l)
        return P

    def choose(J, r, x, weights, criterion=criterion):
        """λ on the problem linearised at ``x`` (nuisance columns projected out)."""
        used = int(np.sum(weights > 0))
        # the data in the rail and lead unknowns at the structure in x:
        # r(x + δ) ≈ r − J_c x_c + J_c(x_c + δ_c)
        y = -(r - J[:, ic] @ x[ic])
        Jt, yp, rank_f = project_out(J[:, n_theta + n_q:], J[:, :n_theta], y)
        n_eff = used - n_chan - rank_f
        if lam is not None:
            return fixed_weight(lam, Jt, yp, Om_curv + Om_amp, n_eff)
        return choose_prior(Jt, yp, Om_curv, Om_amp, n_eff, criterion)

    x = np.zeros(n_x)
    _log.info("fit: %d merged values in %d channels, %d rail + %d structural + %d lead "
              "unknowns; compiling the linearisation", meas.n, n_chan, n_theta, n_q, n_l)
    r, J, pred, ok, Jc = linearise(x)
    if not ok or not np.all(np.isfinite(J)):
        raise ValueError("the machine equilibrium did not converge for straight rails at the "
                         "prior structure; check the machine configuration")
    weights = np.ones(meas.n)
    iq = np.arange(n_theta, n_theta + n_q)  # structure columns
    ic = np.setdiff1d(np.arange(n_x), iq)  # rails and lead: solved by LM at a given structure
    q_bounds = family.bounds() / family.prior_sigma()[:, None] if n_q else np.zeros((0, 2))
    cov_q = np.eye(n_q)
    q_info: dict = {}

    def structure_stage(x, r, J, weights):
        """The structure by marginal likelihood at the current rails (see the module
        docstring), the prior's weight and shape (λ, κ) held at their choice at ``x`` (a smooth
        objective in ``q``; λ is re-chosen afterwards and the stage repeated if it moved);
        returns ``x`` with ``q`` replaced, ``Cov q`` and a note."""
        used = int(np.sum(weights > 0))
        # data with no content (zero readings, constant channels) say nothing on the
        # structure: the prior, not the profiled score's round-off (:mod:`.marginal`)
        y0 = -(r - J[:, ic] @ x[ic])
        _, yp0, rank0 = project_out(J[:, n_theta + n_q:], J[:, :n_theta], y0)
        w0 = weights / np.asarray(meas.sigma)
        scale = (float(np.linalg.norm(w0 * np.asarray(meas.value))) + float(np.linalg.norm(r))
                 + float(np.linalg.norm(J[:, ic] @ x[ic])))
        if not carries_information(yp0, used - n_chan - rank0, scale):
            _log.info("fit: the data are zero to round-off (|y| = %.3g): the structure is the "
                      "prior's", float(np.linalg.norm(yp0)))
            out = x.copy()
            out[iq] = 0.0
            return out, np.eye(n_q), {
                "iterations": 0, "evaluations": 0, "at_bound": [False] * n_q,
                "message": ("the data carry no information on it (zero to round-off once the "
                            "channel zeros and the lead are removed): its value and σ are the "
                            "prior's")}
        c0 = choose(J, r, x, weights, "ml")
        Om_fixed = Om_curv + c0.kappa * Om_amp

        parts: dict = {}

        def parts_at(q):
            """The marginal likelihood's terms at structure ``q``, ``(Q, log det, N')``, or
            None where the model failed (one linearisation and one SVD per ``q``)."""
            key = np.asarray(q, float).tobytes()
            if key not in parts:
                xq = x.copy()
                xq[iq] = q
                r_q, J_q, _, ok_q, _ = linearise(xq)
                if not ok_q or not np.all(np.isfinite(J_q)):
                    parts[key] = None
                else:
                    y = -(r_q - J_q[:, ic] @ x[ic])  # data in the total rail and lead unknowns
                    Jt, yp, rank_f = project_out(J_q[:, n_theta + n_q:], J_q[:, :n_theta], y)
                    parts[key] = (*marginal_parts(Jt, yp, Om_fixed, c0.lam),
                                  used - n_chan - rank_f)
            return parts[key]

        def score(q, scale2=None):
            p = parts_at(q)
            if p is None:
                return np.inf
            return score_of_parts(*p, scale2) + float(q @ q)

        q, cov, note = maximise_marginal(score, x[iq], q_bounds)
        p = parts_at(q)
        s2 = p[0] / max(p[2], 1) if p is not None else 1.0  # ŝ², the profiled noise variance
        note["noise_scale"] = float(np.sqrt(s2))
        if s2 < 1.0 and not note["message"].startswith("the model failed"):
            # the data scatter less than their stated σ: the profiled score would take that
            # scatter, model error included, for the noise and narrow the structure's σ; like
            # the rails' σ, it is never narrowed below what the stated σ give (module docstring)
            cov, factors = laplace(lambda v: score(v, 1.0), q, cov, q_bounds)
            note["widened"] = [float(a) for a in factors]
            _log.info("fit: the data scatter %.2g of their stated sigma: the structure's "
                      "sigma is taken at the stated sigma", float(np.sqrt(s2)))
        out = x.copy()
        out[iq] = q
        return out, cov, note

    choice = choose(J, r, x, weights)
    P = penalty(choice)
    Pc = P[np.ix_(ic, ic)]
    recent: dict = {}  # the full linearisations of LM's latest trial points

    def linearise_c(xc):
        xf = x.copy()
        xf[ic] = xc
        out = linearise(xf)
        if len(recent) > 4:
            recent.clear()
        recent[xc.tobytes()] = out
        return out[0], (out[1][:, ic] if out[1] is not None else None), *out[2:]

    def gn_start(r, J):
        Jc_ = J[:, ic]
        return x[ic] + np.linalg.solve(_spd(Jc_.T @ Jc_ + Pc), -(Jc_.T @ r + Pc @ x[ic]))

    def structure(r, J):
        """The structure stage at ``x`` (``r``, ``J`` there); the linearisation at ``q̂``."""
        _log.info("fit: the structure by marginal likelihood")
        xn, cov, info = structure_stage(x, r, J, weights)
        return xn, cov, info, linearise(xn)

    x_lin = x.copy()
    x[ic] = gn_start(r, J)  # Gauss–Newton start at the prior structure
    steps, converged, message = 0, True, "converged"
    outliers = np.zeros(0, int)
    passes = 0
    if method == "linear" and n_q:  # the structure on the problem linearised at x = 0
        x[ic] = 0.0
        x, cov_q, q_info, (r, J, pred, ok, Jc) = structure(r, J)
        x[ic] = gn_start(r, J)
        x_lin = x.copy()
        x_lin[ic] = 0.0
    if method == "lm":
        r, J, pred, ok, Jc = linearise(x)
        if not (bool(ok) and np.all(np.isfinite(J))):  # GN start too far: start from zero
            x[ic] = 0.0
            r, J, pred, ok, Jc = linearise(x)
        if n_q:  # the structure at the Gauss–Newton rails
            x_stage = x.copy()
            x, cov_q, q_info, (r, J, pred, ok, Jc) = structure(r, J)
    while method == "lm":
        passes += 1
        xc, r, _, pred, Jc, converged, n, message = _levenberg_marquardt(
            x[ic], r, J[:, ic], pred, Jc, linearise_c, Pc, rtol, max_steps)
        x[ic] = xc
        steps += n
        full = recent.get(xc.tobytes())
        r, J, pred, ok, Jc = full if full is not None else linearise(x)
        _log.info("fit: pass %d, %d LM steps, chi2 %.4g, lambda %.3g (kappa %g): %s", passes, n,
                  float(r @ r), choice.lam, choice.kappa, message)
        if passes >= 4:
            break
        redo = False
        if reject_outliers and passes <= 2:
            scale = np.sqrt(max(_chi2_dof(J[:, ic], r, Pc, weights, n_chan), 1.0))
            bad = np.flatnonzero((weights > 0) & (np.abs(r) > OUTLIER_Z * scale))
            if bad.size and bad.size <= 0.05 * meas.n:
                weights[bad] = 0.0
                outliers = np.union1d(outliers, bad)
                prob = eqx.tree_at(lambda p: p.weight, prob, jnp.asarray(weights))
                r, J, pred, _, Jc = linearise(x)
                redo = True
        # the structure again when the data changed or the rails moved far from where it was
        # estimated (a nonlinear model: the linearisation there no longer holds)
        if n_q and (redo or np.linalg.norm(x[ic] - x_stage[ic])
                    > 0.2 * max(np.linalg.norm(x[ic]), 1e-12)):
            q_old, x_stage = x[iq].copy(), x.copy()
            x, cov_q, q_info, (r, J, pred, ok, Jc) = structure(r, J)
            if np.max(np.abs(x[iq] - q_old)) > 0.1:
                redo = True
        if lam is None:
            new = choose(J, r, x, weights)
            if abs(np.log(new.lam / choice.lam)) >= np.log(1.5):
                redo = True
            choice = new
            P = penalty(choice)
            Pc = P[np.ix_(ic, ic)]
        if not redo:
            break
    if method == "linear":  # residuals of the linear model at the solution
        r = r + J[:, ic] @ (x[ic] - x_lin[ic])
    # the rails and lead given the structure, then the structure's uncertainty carried in:
    # Cov c = s²H_c⁻¹ + G Cov q Gᵀ, G = ∂ĉ/∂q over ±σ_q (the delta method, a secant)
    Jcc = J[:, ic]
    Hc = _spd(Jcc.T @ Jcc + Pc)
    Hc_inv = np.linalg.inv(Hc)
    Hc_inv = 0.5 * (Hc_inv + Hc_inv.T)
    x_at = x_lin if method == "linear" else x  # where the model was linearised
    G = _structure_sensitivity(linearise, x_at, x, J, ic, iq, q_bounds, cov_q, Pc, Hc_inv)
    edf = float(np.trace(Hc_inv @ (Jcc.T @ Jcc))) + float(np.trace(np.eye(n_q) - cov_q))
    chi2 = float(r @ r)
    used = int(np.sum(weights > 0))
    dof = float(used - n_chan - edf)
    sigma_scale = float(np.sqrt(max(chi2 / dof, 1.0))) if dof > 0 else 1.0
    cov_x = np.zeros((n_x, n_x))
    cov_x[np.ix_(ic, ic)] = sigma_scale**2 * Hc_inv + G @ cov_q @ G.T
    cov_x[np.ix_(ic, iq)] = G @ cov_q
    cov_x[np.ix_(iq, ic)] = (G @ cov_q).T
    cov_x[np.ix_(iq, iq)] = cov_q
    sigma = np.asarray(meas.sigma)
    if method == "lm":
        # measured − fitted for every row (outliers included), with the channel zeros
        d = pred - np.asarray(meas.value)
        offsets = _channel_offsets(d, sigma, weights, chan, n_chan)
        residual = -(d - offsets[chan])
    else:  # the linear method has no outlier pass: every weight is 1
        residual = -r * sigma
        offsets = np.full(n_chan, np.nan)
    fitted = np.asarray(meas.value) - residual
    theta = x[:n_theta]
    c_um = Z @ theta
    cov = Z @ cov_x[:n_theta, :n_theta] @ Z.T * _UM**2
    structure = _structure_report(family, x[iq], cov_q, q_info.get("at_bound", [False] * n_q))
    if q_info and q_info["message"] != "converged":
        message += f"; structure: {q_info['message']}"
    for name, v in structure.items():
        if v["at_bound"]:
            message += (f"; the {name} estimate sits on the edge of its range "
                        f"({v['value']:.4g}): the data push it outside the prior range, so "
                        "treat it, and the rails' bands, with suspicion")
    if choice.at_bound:
        message += (f"; the {choice.criterion} weight search ended on its range's edge "
                    f"(lambda {choice.lam:.3g})")
    return RailFit(
        basis=basis, coeffs=(c_um * _UM).reshape(2, 2, basis.n_coeffs), cov=cov, Z=Z,
        gauge=tuple(gauge), fix_slope=fix_slope, lam=float(choice.lam), weight=choice,
        structure=structure, lead=x[n_theta + n_q:n_theta + n_q + n_lead] * _UM,
        lead_basis=lead_basis, alignment=x[n_theta + n_q + n_lead:] * _UM,
        alignment_channels=align_chan,
        fitted=fitted, residual=residual, offsets=offsets, outliers=outliers, chi2=chi2,
        dof=dof, edf=edf, sigma_scale=sigma_scale, converged=bool(converged), message=message,
        steps=steps, jacobian=J, jacobian_full=Jc, penalty=P, n_theta=n_theta,
        Omega=Om_curv + choice.kappa * Om_amp,
        rigid=bool(base.rigid), waviness=float(waviness),
        structure_sensitivity=(Z @ G[:n_theta] * _UM).reshape(2, 2, basis.n_coeffs, n_q),
        structure_cov=np.asarray(cov_q, float).reshape(n_q, n_q),
    )


def _channel_offsets(d, sigma, weights, chan, n_chan):
    w = weights / sigma**2
    num = np.bincount(chan, w * d, n_chan)
    den = np.bincount(chan, w, n_chan)
    return np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)


def _chi2_dof(J, r, P, weights, n_chan):
    H = _spd(J.T @ J + P)
    edf = float(np.trace(np.linalg.solve(H, J.T @ J)))
    dof = np.sum(weights > 0) - n_chan - edf
    return float(r @ r / dof) if dof > 0 else 1.0


def _structure_report(family: MachineFamily, q, cov_q, at_bound) -> dict:
    out = {}
    prior_sig = family.prior_sigma()
    values = family.values(q * prior_sig)
    for i, name in enumerate(family.names):
        pr = getattr(family.priors, name)
        sd_log = float(np.sqrt(max(cov_q[i, i], 0.0))) * prior_sig[i]
        lo, hi = family.bounds()[i]
        u = q[i] * prior_sig[i]
        out[name] = {
            "value": values[name],
            "sigma": values[name] * sd_log,
            "sigma_log": sd_log,
            "prior_value": pr.value,
            "prior_range": [pr.lo, pr.hi],
            "prior_sigma_log": float(prior_sig[i]),
            "at_bound": bool(at_bound[i] or u <= lo + 1e-6 or u >= hi - 1e-6),
        }
        # at the edge of the interpolation range the model is flat in the parameter: its σ
        # there says nothing, so the parameter is not determined
        out[name]["determined"] = bool(sd_log < DETERMINED_RATIO * prior_sig[i]
                                       and not out[name]["at_bound"])
    return out


def _spd(H):
    H = 0.5 * (H + H.T)
    return H
