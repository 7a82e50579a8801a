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
rails and lead minimise the objective above by Levenberg–Marquardt
(:class:`.lm.LevenbergMarquardt`: one compiled linearisation — residual and ``jacfwd``
Jacobian through the implicit equilibria — per step, the damped normal equations solved in NumPy), started from the Gauss–Newton step. λ
is chosen on the problem linearised at the current estimate (:mod:`.weight`: marginal likelihood
by default, GCV on request, or given), with the lead unknowns projected out, then re-chosen at
the solution and the fit repeated once if it moved by more than a factor 1.5.

**Outliers.** Gross outliers among the readings are set aside when merging
(:mod:`diffguide.measurements`); a merged value whose standardised residual still exceeds
:data:`.solve.OUTLIER_Z` after the fit is given zero weight and the fit repeated once (reported).

**Uncertainty.** The rails and lead given the structure: the Gauss–Newton posterior
``s²H_c⁻¹``, ``H_c = J_cᵀJ_c + P_c``, ``P_c = diag(λΩ, ε²I)``; the structure's own posterior
``Cov q`` (the Laplace approximation of the marginal likelihood, :mod:`.marginal`) carried into
them by the delta method,

.. math::  \mathrm{Cov}\,c = s²H_c⁻¹ + G\,\mathrm{Cov}\,q\,Gᵀ,\qquad
           G = ∂ĉ/∂q,

so the rails' bands include the structure's uncertainty and widen where the structure is not
determined. ``G`` is a secant over ``±σ_q`` along each unknown: the rails solved again on the
model linearised at ``q ± σ_q`` (:func:`.posterior.structure_sensitivity`, two linearisations per
unknown). The Gauss–Newton tangent ``−H_c⁻¹J_cᵀJ_q`` it replaces leaves out that the structure
scales how strongly the rails show in the data (a stiffer table shows a rail difference less):
on the battery's straightness case its thickness column was a third of what refitting moves
the rails. ``s² = max(1, χ²/dof)``: when the model does not explain the data to their stated σ,
the bands widen accordingly (never narrow). ``χ²/dof = ‖r‖² / (N − n_channels − edf)``,
``edf = tr(H_c⁻¹J_cᵀJ_c) + tr(I − Cov q)``.

**Knots.** By default the knots are the carriage's loaded length apart: shorter content is
averaged out by the carriage. A cubic B-spline follows content near two knot spacings poorly,
though; at µm-sized rails that error hides in the noise, at large rails (rows unloading, a
battery case at 15 µm RMS) it left ``χ²/dof`` at 5 and bands that missed the truth. Where
``χ²/dof`` stays above :data:`REFINE_CHI2` the fit is repeated on knots half as far apart while
that helps (:func:`refine_knots`); the message says so.

**Always an answer.** The fit returns its best estimate whatever happens after the first
linearisation: ``converged`` is False with the reason in ``message`` when LM stops on its step
limit or an equilibrium fails.

The pieces: :mod:`.problem` (the fit as data, model, prior and gauge), :mod:`.model` (the
residual through the machine), :mod:`.solve` and :mod:`.lm` (the passes), :mod:`.structure_stage`
(the structure by marginal likelihood), :mod:`.posterior` (the covariance); this module composes
them and reports the result as a :class:`RailFit`.
"""

import logging

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._core.checks import instance, mm_hint, positive_int
from .._core.precision import require_x64
from ..guideway.rails import JOINT_WIDTH
from .basis import PLANES, PROFILES, RailBasis
from .data import Measurements
from .posterior import SECANT_STEP_LIMITS as SECANT_STEP_LIMITS
from .posterior import Posterior, posterior
from .problem import LEAD_KNOT_SPACING as LEAD_KNOT_SPACING
from .problem import LEAD_RIDGE as LEAD_RIDGE
from .problem import FitProblem, build_problem
from .problem import visited_range as visited_range
from .solve import OUTLIER_Z as OUTLIER_Z
from .solve import FitState, solve_linear, solve_lm, start
from .structure_stage import structure_report
from .weight import WeightChoice

_UM = 1e-6
_log = logging.getLogger("diffguide")


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
            posterior_cov: the full posterior covariance of ``v = (c, q, ℓ)`` — every rail
            coefficient (m), the structural unknowns (prior σ), the lead and alignment
            nuisances (m) — cross terms included (:mod:`.predict`). position_range: the
            measured table positions' ``(min, max)`` (m).
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
    posterior_cov: np.ndarray = eqx.field(default_factory=lambda: np.zeros((0, 0)))
    position_range: tuple = eqx.field(static=True, default=())

    @property
    def chi2_dof(self) -> float:
        return self.chi2 / self.dof if self.dof > 0 else float("nan")

    @property
    def gcv(self) -> float:
        """The weight criterion's score (kept for the report; NaN for a given λ)."""
        return self.weight.score

    def profiles(self, s, *, extrapolate: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Profiles and their posterior σ at ``s`` (m): two arrays (m) of shape
        ``(2 rails, 2 planes) + np.shape(s)``, i.e. ``(2, 2, len(s))`` for 1-D ``s`` and
        ``(2, 2)`` for a scalar; planes ``(vertical, horizontal)``.
        ``σ² = bᵀ Cov b + waviness²`` (``b`` the basis functions at ``s``).

        ``s`` must be finite (``ValueError`` otherwise) and a scalar or 1-D, and within the fitted
        range ``[basis.start, basis.end]`` (m; ``ValueError`` naming the range otherwise). With
        ``extrapolate=True`` the end segments' cubics are continued outside it (an
        extrapolation the data do not support)."""
        s = np.asarray(s, dtype=float)
        if s.ndim > 1:
            raise ValueError(f"s must be a scalar or a 1-D array (m), got shape {s.shape}")
        if not np.all(np.isfinite(s)):
            raise ValueError(f"s must be finite (m); it holds {s[~np.isfinite(s)][:3]}")
        if not extrapolate:
            _check_in_range(s, self.basis.start, self.basis.end)
        shape = s.shape
        B = self.basis.matrix(np.atleast_1d(s))
        n = self.basis.per_profile
        val = np.einsum("sk,rpk->rps", B, self.coeffs)
        sig = np.zeros_like(val)
        for k in range(4):
            r, p = divmod(k, 2)
            C = self.cov[k * n:(k + 1) * n, k * n:(k + 1) * n]
            sig[r, p] = np.sqrt(np.maximum(np.einsum("sk,kl,sl->s", B, C, B), 0.0)
                                + self.waviness**2)
        return val.reshape((2, 2) + shape), sig.reshape((2, 2) + shape)

    def joint_steps(self) -> list[dict]:
        """The fitted step at each rail joint, per profile: ``{s, rail, plane, value, sigma}``
        (m), σ from the posterior (empty without joints)."""
        n, per = self.basis.n_coeffs, self.basis.per_profile
        out = []
        for j, s in enumerate(self.basis.joints):
            for k, (r, plane) in enumerate(PROFILES):
                i = k * per + n + j
                out.append({"s": float(s), "rail": r + 1, "plane": plane,
                            "value": float(self.coeffs[r, PLANES.index(plane), n + j]),
                            "sigma": float(np.sqrt(max(self.cov[i, i], 0.0)))})
        return out

    def predict(self, spec, points, positions, **kw):
        """The six joint errors, with σ from the full posterior, at ``points`` ``{name: (x,
        y)}`` (m) over table ``positions`` (m) of the machine ``spec`` (a
        :class:`~diffguide.machine.spec.MachineSpec`, the one fitted): EXX includes the fitted
        lead error; positions outside the measured range are refused unless
        ``extrapolate=True``. Keywords and returns: :func:`.predict.predict`."""
        from .predict import predict

        return predict(self, spec, points, positions, **kw)

    def rails(self) -> tuple:
        """The fitted profiles (rail 1, rail 2): :class:`~diffguide.guideway.SplineRail`, or
        :class:`~diffguide.guideway.SteppedRail` where the fit has rail joints."""
        return self.basis.rails(jnp.asarray(self.coeffs))

    def to_dataframe(self, s=None, *, extrapolate: bool = False):
        """The profiles as a ``pandas.DataFrame`` in user units, the columns of ``rails.csv``:
        ``rail, s_mm, vertical_um, vertical_sigma_um, horizontal_um, horizontal_sigma_um`` at
        ``s`` (m; a scalar or 1-D, finite; default every 2 mm over the fitted range): one row
        per rail and ``s`` (a scalar ``s`` gives two rows); ``extrapolate`` as in
        :meth:`profiles`. Needs the ``[pandas]`` extra."""
        from .._core.frames import require_pandas

        pd = require_pandas()
        if s is None:
            s = np.arange(self.basis.start, self.basis.end + 1e-12, 2e-3)
        s = np.asarray(s, dtype=float)
        if s.ndim == 0:
            s = s[None]
        val, sig = self.profiles(s, extrapolate=True) if extrapolate else self.profiles(s)
        parts = []
        for r in range(2):
            parts.append(pd.DataFrame({
                "rail": r + 1, "s_mm": s * 1e3,
                "vertical_um": val[r, 0] * 1e6, "vertical_sigma_um": sig[r, 0] * 1e6,
                "horizontal_um": val[r, 1] * 1e6, "horizontal_sigma_um": sig[r, 1] * 1e6,
            }))
        return pd.concat(parts, ignore_index=True)


#: ``s`` within this distance (m) of the fitted range counts as inside it (round-off of a grid).
_S_TOL = 1e-9


def _check_in_range(s: np.ndarray, lo: float, hi: float) -> None:
    """Refuse ``s`` (m) outside ``[lo, hi]`` with the range in m and mm, and the mm hint."""
    out = s[(s < lo - _S_TOL) | (s > hi + _S_TOL)]
    if out.size:
        v = float(out.flat[0])
        raise ValueError(
            f"s must lie within the fitted range [{lo:g}, {hi:g}] m ({lo * 1e3:g} .. "
            f"{hi * 1e3:g} mm), got {v:g} m{mm_hint(v, lo, hi)} (extrapolate=True continues "
            "the end segments, which the data do not support)"
        )


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
    joints=(),
    joint_width: float = JOINT_WIDTH,
) -> RailFit:
    """Fit the rail straightness profiles (and the structure) to merged measurements.

    Arguments:
        machine: a :class:`~diffguide.machine.Machine` (structure fixed) or a
            :class:`~.structure.MachineFamily` (structure estimated), whose points are
            ``meas.point_names`` (same order); ``machine.with_rigid_table()`` gives the classical
            rigid-table inversion.
        meas: merged measurements (:func:`diffguide.read_measurements`; a path is refused
            with a ``TypeError``).
        knot_spacing: requested knot spacing (m), within :data:`.problem.KNOT_SPACING_RANGE`
            (a value outside is refused, with a hint when it looks like mm); default the
            carriage's loaded length (``n·p``, 48 mm for ``majda2012``): shorter wavelengths
            are averaged out by the carriage, so finer knots only add undetermined unknowns;
            halved while ``χ²/dof`` stays above 2 and halving helps (:func:`refine_knots`).
        lam: regularisation weight; default chosen by ``criterion`` (:mod:`.weight`).
        criterion: ``"ml"`` (marginal likelihood) or ``"gcv"``.
        x_ref: reference position of the model (m), within
            :data:`~diffguide.machine.kinematics.POSITION_RANGE`; the result does not depend
            on it.
        rtol: LM tolerance on the Gauss–Newton decrement, relative to the χ² per datum.
            max_steps: LM step limit per pass, an integer >= 0 (0: the start only, reported
            as not converged).
        method: ``"lm"`` (through the nonlinear model) or ``"linear"`` (linearised at straight
            rails and solved once: the classical linear inversion).
        reject_outliers: zero-weight merged values beyond :data:`OUTLIER_Z` and refit once.
        waviness: RMS (m) of the rails' short-wave content — wavelengths shorter than about
            two knot spacings, which the basis cannot represent and the carriages average out
            (at the default knots, the carriage's loaded length) — as the user knows it from
            the rails' grade. The data cannot estimate it (those wavelengths move no
            carriage); it is added in quadrature to every profile σ. Default 0: the bands then
            cover only what the knot grid resolves.
        joints: rail joint positions ``s`` (m, increasing) on the profiles' axis (as
            :meth:`profiles`' ``s``, ``rails.csv``'s ``s_mm``): each profile (both rails,
            both planes) gains a step there, smoothed over ``joint_width`` (m), whose height the
            data decide (:mod:`.basis`). A step the knot grid cannot hold would ring over
            several knot spacings and bias the predictions around it. A joint outside the
            rail length the elements visit is refused (``ValueError``).

    Raises ``ValueError`` for inputs that cannot be fitted at all (arguments out of range,
    mismatched points, fewer data than channels, a model that does not converge for straight
    rails; ``TypeError`` for measurements that are not :class:`.data.Measurements`) before any
    work; everything after that
    returns a :class:`RailFit` (see ``converged`` and ``message``).
    """
    if method not in ("lm", "linear"):
        raise ValueError(f"method must be 'lm' or 'linear', got {method!r}")
    if not (np.isfinite(waviness) and waviness >= 0.0):
        raise ValueError(f"waviness must be a finite RMS >= 0 m, got {waviness!r}")
    instance("meas", meas, Measurements,
             "pass diffguide.read_measurements(path) (or Measurements.from_arrays(...))")
    max_steps = positive_int("max_steps", max_steps, 0)  # 0: the start only (as the CLI)
    if not (np.isfinite(rtol) and rtol > 0):
        raise ValueError(f"rtol must be a finite tolerance > 0, got {rtol!r}")
    if lam is not None and not (np.isfinite(lam) and lam > 0):
        raise ValueError(f"lam must be a finite weight > 0 (or None: chosen), got {lam!r}")
    require_x64("fit_rails")

    def fit_on(spacing, note=""):
        problem = build_problem(machine, meas, knot_spacing=spacing, lam=lam,
                                criterion=criterion, x_ref=x_ref, joints=tuple(joints),
                                joint_width=joint_width)
        st = start(problem)
        if method == "linear":
            solve_linear(st)
        else:
            solve_lm(st, rtol, max_steps, reject_outliers)
        return report_fit(st, posterior(st, method), method, waviness, note)

    fit = fit_on(knot_spacing)
    if knot_spacing is not None or method != "lm":
        return fit
    return refine_knots(fit, fit_on)


#: χ²/dof above which a fit on the default knots is tried again on knots half as far apart.
REFINE_CHI2 = 2.0
#: The finer knots are kept when their χ²/dof is at most this fraction of the coarser's.
REFINE_GAIN = 0.67
#: The finest knots tried automatically, as a fraction of the default spacing.
REFINE_FLOOR = 0.25


def refine_knots(fit: RailFit, fit_on) -> RailFit:
    """The default knots (the carriage's loaded length) cannot follow rail content near two
    knot spacings: a cubic B-spline represents a sine of wavelength ``2h`` poorly. At
    µm-sized rails that error hides in the noise; at large rails it leaves ``χ²/dof`` far
    above 1 and bands that do not cover the truth. While ``χ²/dof`` exceeds
    :data:`REFINE_CHI2`, fit again on knots half as far apart (``fit_on(spacing, note)``),
    down to :data:`REFINE_FLOOR` of the default, keeping the finer fit when its ``χ²/dof``
    falls to :data:`REFINE_GAIN` of the coarser's or below; the message says so."""
    h0, history = float(fit.basis.spacing), ""
    while fit.chi2_dof > REFINE_CHI2 and fit.basis.spacing / 2 >= REFINE_FLOOR * h0 * (1 - 1e-9):
        h = float(fit.basis.spacing) / 2
        note = history + (f"; χ²/dof {fit.chi2_dof:.3g} on {fit.basis.spacing * 1e3:.3g} mm "
                          f"knots: refitted on {h * 1e3:.3g} mm knots")
        finer = fit_on(h, note)
        if not finer.chi2_dof <= REFINE_GAIN * fit.chi2_dof:
            break
        _log.info("fit:%s (χ²/dof %.3g)", note, finer.chi2_dof)
        fit, history = finer, note
    return fit


def report_fit(st: FitState, post: Posterior, method: str, waviness: float,
               note: str = "") -> RailFit:
    """The :class:`RailFit` of the solved state ``st`` with its posterior ``post`` (SI, the
    profiles' coefficients in m; ``waviness`` in m RMS; ``note`` appended to the message)."""
    p: FitProblem = st.problem
    n_theta, n_q, iq = p.n_theta, p.n_q, p.iq
    x, (_, J, pred, _, Jc) = st.x, st.lin
    residual, offsets = _residuals(p, post.r, pred, method)
    c_um = p.Z @ x[:n_theta]
    cov = p.Z @ post.cov_x[:n_theta, :n_theta] @ p.Z.T * _UM**2
    structure = structure_report(p.family, x[iq], st.cov_q,
                                 st.q_info.get("at_bound", [False] * n_q))
    n_c, lead_end = p.basis.per_profile, n_theta + n_q + p.n_lead
    return RailFit(
        basis=p.basis, coeffs=(c_um * _UM).reshape(2, 2, n_c), cov=cov, Z=p.Z,
        gauge=p.gauge, fix_slope=p.fix_slope, lam=float(st.choice.lam), weight=st.choice,
        structure=structure, lead=x[n_theta + n_q:lead_end] * _UM,
        lead_basis=p.lead_basis, alignment=x[lead_end:] * _UM,
        alignment_channels=p.alignment_channels,
        fitted=np.asarray(p.meas.value) - residual, residual=residual, offsets=offsets,
        outliers=st.outliers, chi2=post.chi2, dof=post.dof, edf=post.edf,
        sigma_scale=post.sigma_scale, converged=bool(st.converged),
        message=_message(st, structure) + post.notes() + note,
        steps=st.steps, jacobian=J, jacobian_full=Jc,
        penalty=st.P, n_theta=n_theta, Omega=p.Om_curv + st.choice.kappa * p.Om_amp,
        rigid=bool(p.family.base.rigid), waviness=float(waviness),
        structure_sensitivity=(p.Z @ post.G[:n_theta] * _UM).reshape(2, 2, n_c, n_q),
        structure_cov=np.asarray(st.cov_q, float).reshape(n_q, n_q),
        posterior_cov=_v_covariance(p, post.cov_x),
        position_range=(float(np.min(p.meas.position)), float(np.max(p.meas.position))),
    )


def _v_covariance(p: FitProblem, cov_x) -> np.ndarray:
    """``Cov v`` of ``v = Mx = (c, q, ℓ)``: c and ℓ in m, q in prior σ."""
    u = np.concatenate([np.full(p.basis.size, _UM), np.ones(p.n_q), np.full(p.n_l, _UM)])
    return u[:, None] * (p.M @ cov_x @ p.M.T) * u[None, :]


def _residuals(p: FitProblem, r, pred, method: str):
    """Measured − fitted for every merged row (outliers included; m or rad) and each
    channel's zero (model − measured; NaN for the linear method, whose residual is the
    whitened ``r`` scaled back)."""
    sigma = np.asarray(p.meas.sigma)
    if method == "lm":
        d = pred - np.asarray(p.meas.value)
        offsets = _channel_offsets(d, sigma, p.weights, p.chan, p.n_chan)
        return -(d - offsets[p.chan]), offsets
    # the linear method has no outlier pass: every weight is 1
    return -r * sigma, np.full(p.n_chan, np.nan)


def _message(st: FitState, structure: dict) -> str:
    """LM's message with the structure stage's and the weight search's warnings appended."""
    message, q_info, choice = st.message, st.q_info, st.choice
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
    return message


def _channel_offsets(d, sigma, weights, chan, n_chan):
    """Each channel's weighted mean of ``d`` (weights ``w/σ²``), 0 for a channel with none."""
    w = weights / sigma**2
    num = np.bincount(chan, w * d, n_chan)
    den = np.bincount(chan, w, n_chan)
    return np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
