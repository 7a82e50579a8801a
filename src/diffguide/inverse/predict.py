r"""Prediction from a fit: the six joint errors at any points of the table over any positions,
with σ from the fit's full posterior.

The fitted model's unknowns ``v = (c, q, ℓ)`` — every rail coefficient ``c`` (m), the structural
unknowns ``q`` (table thickness and preload, in prior σ of their log) and the nuisances ``ℓ``
(the feed screw's lead error, m, and each straightness channel's alignment slope) — have the
posterior mean ``v̂`` and covariance ``Cov v`` (:attr:`.fit.RailFit.posterior_cov`, cross terms
included). At table position ``x`` and point ``P``

.. math::  e(x) = E_P(x; c, q) + [\mathrm{EXX}]\bigl(ℓ(x) − ℓ(x_{ref})\bigr),\qquad
           σ_e(x) = \sqrt{\mathrm{diag}\bigl(J\,\mathrm{Cov}\,v\,Jᵀ\bigr)},\quad J = ∂e/∂v,

``E`` the machine's joint errors relative to the reference position ``x_ref``
(:func:`~diffguide.machine.kinematics.joint_errors`, ISO 230-1 signs), ``ℓ`` the fitted lead
spline: EXX *includes* the lead error the positioning data showed (a compensation table's EXX
must), extrapolated as a constant-free cubic outside the EXX data's range. The alignment slopes
belong to the instruments, not to the machine: they enter ``σ`` only through their correlation
with the rest (``J`` is zero in them). Straightness (EYX, EZX) is in the fit's gauge: the common
slope of both rails in each plane, which no reading determines, fixed as in the fit
(:mod:`.basis`); the linear part of a straightness curve is a matter of its reference line.

``J`` in ``c`` and in the preload: one forward-mode pass through the implicit equilibria (the
preload scales ``Carriage.preload_force``, :func:`.structure.scaled_preload`, as in
:class:`.structure.MachineFamily`). ``J`` in
the thickness (or an imported table's stiffness scale): a secant over ``±h`` (``h`` its
posterior σ within :data:`~.posterior.SECANT_STEP_LIMITS`, as the fit's own structure
sensitivity), the table condensed at ``t̂·e^{±hσ_t}`` (scaled by ``ŝ·e^{±hσ_s}``).

**The machine, solved once.** The errors at a point are a linear map of the table's
interface DOF (:mod:`.posterior_sweep`): :func:`predict` solves the fitted machine (the fit's
own mesh, with the measured points' grid lines) once over the positions, with the Jacobian, and
at the secant's two structure values, and keeps that (:data:`~.posterior_sweep.SWEEP_CACHE_SIZE`
most recent); any point of the table top then takes its rows from the condensed table — a
measured point its own, another one interpolated from the mesh nodes with the shell's shape
functions (:func:`~diffguide.fe.recovery.point_rows`), the table's own FE solution there. The
table is not condensed again for new points. (An imported table knows only its retained nodes:
there the requested points are added to the machine's points, as before.)
:func:`_predict_recondensed` is the former route, kept as a reference: the table condensed
again with grid lines through the requested points; on the same mesh the two agree to
round-off.

**Where the tool is.** With a height ``z`` above the table top (the tool point, a workpiece
feature) the body above the top turns rigidly with it: ``EXX(z) = EXX + z·EBX``,
``EYX(z) = EYX − z·EAX`` (Abbe), applied to ``e`` and to ``J`` before the σ, so the σ holds the
correlations (:func:`abbe`).

**Extrapolation.** Positions outside the measured range are refused (``ValueError`` naming the
range) unless ``extrapolate=True``; then the rails' and lead's end cubics are continued and the
σ is what that continuation's covariance gives (large, and growing with the distance), each such
position flagged.
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._core.checks import mm_hint
from .._core.limits import MAX_PREDICTION_BYTES, gigabytes
from ..guideway.rails import bspline_matrix
from ..machine.errors import to_user
from ..machine.kinematics import ERROR_NAMES, POSITION_RANGE
from .basis import RailBasis
from .posterior import SECANT_STEP_LIMITS
from .posterior_sweep import (
    fitted_machine,
    perturbed_joint_errors,
    posterior_sweep,
    with_jacobian,
)

#: A position this far (m) outside the measured range still counts as inside (round-off).
_X_TOL = 1e-9
_EXX, _EYX = ERROR_NAMES.index("EXX"), ERROR_NAMES.index("EYX")
_EAX, _EBX = ERROR_NAMES.index("EAX"), ERROR_NAMES.index("EBX")


@dataclasses.dataclass(frozen=True)
class FitPosterior:
    """What a prediction needs from a fit (SI): built from a :class:`~.fit.RailFit`
    (:meth:`from_fit`) or read back from a fit's output folder
    (:mod:`diffguide.io.fit_posterior`).

    Attributes:
        basis: the rails' unknowns (:class:`~.basis.RailBasis`: the knot grid, the rail joints
            and their steps' rise, m). coeffs: ``(2 rails, 2 planes, n)``
            spline coefficients (m), then the rail joints' step heights (m), planes (vertical,
            horizontal). cov: ``Cov v`` of
            ``v = (c, q, ℓ)`` (c, ℓ in m; q in prior σ). structure: per structural unknown,
            in the fit's order, ``{value, prior_value, prior_sigma_log}`` (thickness in m,
            preload a fraction of C). lead: the lead-error coefficients (m), on lead_basis
            ``(start, spacing, n)`` (m) or ``()``. position_range: the measured positions'
            ``(min, max)`` (m). rigid: fitted with the rigid-table model. x_ref: the reference
            position (m).
    """

    basis: RailBasis
    coeffs: np.ndarray
    cov: np.ndarray
    structure: dict
    lead: np.ndarray
    lead_basis: tuple
    position_range: tuple
    rigid: bool = False
    x_ref: float = 0.0

    def __post_init__(self):
        if not isinstance(self.basis, RailBasis):
            raise ValueError(f"basis must be a RailBasis, got {type(self.basis).__name__}")
        n = self.basis.per_profile
        n_v = 4 * n + len(self.structure) + len(self.lead)
        if np.shape(self.coeffs) != (2, 2, n):
            raise ValueError(f"coeffs must have shape (2, 2, {n}), got "
                             f"{np.shape(self.coeffs)}")
        if np.ndim(self.cov) != 2 or np.shape(self.cov)[0] != np.shape(self.cov)[1] \
                or np.shape(self.cov)[0] < n_v:
            raise ValueError(f"cov must be square and cover the {n_v} rail, structure and "
                             f"lead unknowns, got shape {np.shape(self.cov)}")
        if len(self.position_range) != 2:
            raise ValueError("position_range must be (min, max) of the measured positions (m)")
        if not isinstance(self.rigid, (bool, np.bool_)):
            raise ValueError(f"rigid must be a bool, got {type(self.rigid).__name__} "
                             f"{self.rigid!r}")
        d = np.diag(np.asarray(self.cov, float))
        if not (np.all(np.isfinite(self.cov)) and np.all(d >= 0)):
            raise ValueError("cov must be finite with variances (its diagonal) >= 0")

    @classmethod
    def from_fit(cls, fit) -> "FitPosterior":
        """The posterior of a :class:`~.fit.RailFit` (one made before ``posterior_cov``
        existed is refused: fit again)."""
        if isinstance(fit, cls):
            return fit
        if np.size(fit.posterior_cov) == 0 or len(fit.position_range) != 2:
            raise ValueError("the fit has no full posterior (posterior_cov): fit again with "
                             "this version of diffguide")
        keys = ("value", "prior_value", "prior_sigma_log")
        b = fit.basis
        return cls(
            basis=RailBasis(float(b.start), float(b.spacing), int(b.n_coeffs),
                            tuple(map(float, b.joints)), float(b.joint_width)),
            coeffs=np.asarray(fit.coeffs, float),
            cov=np.asarray(fit.posterior_cov, float),
            structure={n: {k: float(v[k]) for k in keys} for n, v in fit.structure.items()},
            lead=np.asarray(fit.lead, float), lead_basis=tuple(fit.lead_basis),
            position_range=tuple(map(float, fit.position_range)), rigid=bool(fit.rigid))


@dataclasses.dataclass(frozen=True)
class Prediction:
    """What :func:`predict` returns (SI).

    Attributes:
        positions: ``(n_pos,)`` table positions (m). point_names, points_xy: the points
            ``(n_pt, 2)`` (m). errors, sigma: ``(n_pos, n_pt, 6)``, EXX EYX EZX (m), EAX EBX
            ECX (rad), ISO 230-1 signs, relative to ``x_ref``; EXX includes the fitted lead
            error where ``lead`` is True. extrapolated: ``(n_pos,)`` outside the measured
            range. position_range: that range (m). lead: whether a lead error was fitted (EXX
            data) and is included. x_ref: the reference position (m). z: the points' height
            above the table top (m). grid_shape: ``(nx, ny)`` when the points are a grid over
            the table top, x-major (:func:`~.error_map.error_map`), else ``None``.
    """

    positions: np.ndarray
    point_names: tuple
    points_xy: np.ndarray
    errors: np.ndarray
    sigma: np.ndarray
    extrapolated: np.ndarray
    position_range: tuple
    lead: bool
    x_ref: float
    z: float = 0.0
    grid_shape: tuple | None = None

    def user_units(self) -> tuple[np.ndarray, np.ndarray]:
        """``(errors, sigma)`` in µm and µrad (:func:`diffguide.machine.errors.to_user`)."""
        return to_user(self.errors), to_user(self.sigma)


def check_size(n_positions: int, n_points: int, n_unknowns: int, what: str = "") -> None:
    """Refuse (``ValueError``, after ``what``: the option or file that asked) a prediction whose
    Jacobians (``n_positions × n_points × 6 × n_unknowns``, three copies) would exceed
    :data:`~diffguide._core.limits.MAX_PREDICTION_BYTES`, before anything is allocated."""
    per_row = 3 * 8 * 6 * max(int(n_unknowns), 1)
    need = int(n_positions) * int(n_points) * per_row
    if need > MAX_PREDICTION_BYTES:
        rows = MAX_PREDICTION_BYTES // per_row
        raise ValueError(
            f"{what + ': ' if what else ''}{n_positions} positions x {n_points} points "
            f"(the fit's measured points included) need about {gigabytes(need)} for the σ (the "
            f"Jacobian in the fit's {n_unknowns} unknowns); allowed: positions x points up to "
            f"{rows} ({gigabytes(MAX_PREDICTION_BYTES)}): give fewer positions or points")


def check_positions(positions, position_range, extrapolate: bool) -> np.ndarray:
    """``positions`` (m) as a 1-D array; refused (``ValueError``) when not finite, outside
    :data:`~diffguide.machine.kinematics.POSITION_RANGE`, or — unless ``extrapolate`` —
    outside the measured ``position_range`` (m). Returns the extrapolated flags."""
    x = np.atleast_1d(np.asarray(positions, float))
    if x.ndim != 1 or x.size == 0:
        raise ValueError(f"positions must be a non-empty 1-D array (m), got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"positions must be finite (m); they hold {x[~np.isfinite(x)][:3]}")
    lo, hi = POSITION_RANGE
    if np.any((x < lo) | (x > hi)):
        v = float(x[(x < lo) | (x > hi)][0])
        raise ValueError(f"positions must lie within [{lo:g}, {hi:g}] m, got {v:g} m"
                         f"{mm_hint(v, lo, hi)}")
    a, b = position_range
    out = (x < a - _X_TOL) | (x > b + _X_TOL)
    if out.any() and not extrapolate:
        v = float(x[out][0])
        raise ValueError(
            f"position {v * 1e3:g} mm is outside the measured range [{a * 1e3:g}, "
            f"{b * 1e3:g}] mm: the data say nothing there (extrapolate=True / --extrapolate "
            "continues the fitted curves, flagged, with their large σ)")
    return out


def _check_points(points, spec) -> dict:
    """``points`` ``{name: (x, y)}`` (m) checked: finite, on the table top."""
    if not isinstance(points, dict) or not points:
        raise ValueError("points must be a non-empty dict {name: (x, y)} (m)")
    half_l, half_w = spec.table.length / 2, spec.table.width / 2
    out = {}
    for name, xy in points.items():
        x, y = (float(v) for v in xy)
        if not (np.isfinite(x) and np.isfinite(y)) or abs(x) > half_l + 1e-12 \
                or abs(y) > half_w + 1e-12:
            raise ValueError(
                f"point {name!r} at ({x * 1e3:g}, {y * 1e3:g}) mm is off the table (|x| <= "
                f"{half_l * 1e3:g}, |y| <= {half_w * 1e3:g} mm)")
        out[str(name)] = (x, y)
    return out


def _errors_traced(c, dq_p, machine, positions, x_ref, basis, sigma_p):
    """Joint errors (m, rad) at every point for rail coefficients ``c`` (m, flat, on
    ``basis``) and the preload moved by ``dq_p`` prior σ of its log; and whether every
    equilibrium converged."""
    je = perturbed_joint_errors(c, dq_p, machine, positions, x_ref, basis, sigma_p)
    return je.errors, jnp.all(je.converged)


_errors_jit = eqx.filter_jit(_errors_traced)


#: Errors ``(n_pos, n_pt, 6)``, their Jacobian ``(..., 4n + 1)`` and convergence.
_errors_and_jacobian = with_jacobian(_errors_traced)


def _sweep(post: FitPosterior, machine, x, with_jacobian: bool):
    """Errors (and the Jacobian in ``(c, preload)``) of ``machine`` over ``x`` (m)."""
    names = list(post.structure)
    sigma_p = post.structure["preload"]["prior_sigma_log"] if "preload" in names else 0.0
    if post.rigid:
        machine = machine.with_rigid_table()
    args = (jnp.asarray(post.coeffs.reshape(-1)), 0.0, machine, jnp.asarray(x),
            jnp.asarray(float(post.x_ref)), post.basis, float(sigma_p))
    if with_jacobian:
        e, J, ok = _errors_and_jacobian(*args)
        return np.array(e), np.asarray(J), bool(ok)
    e, ok = _errors_jit(*args)
    return np.array(e), None, bool(ok)


def predict(fit, spec, points, positions, *, measured_points: dict | None = None,
            nx: int | None = None, ny: int | None = None,
            extrapolate: bool = False, z: float = 0.0, make_machine=None,
            mesh_points: dict | None = None) -> Prediction:
    """The six joint errors and their σ at ``points`` over ``positions`` (module docstring).

    Arguments:
        fit: a :class:`~.fit.RailFit` or a :class:`FitPosterior`.
        spec: the fitted machine's :class:`~diffguide.machine.spec.MachineSpec` (SI), at its
            configured structure (the fitted thickness and preload replace it).
        points: ``{name: (x, y)}`` (m) on the table top.
        positions: table positions (m), 1-D; outside the measured range only with
            ``extrapolate`` (then flagged).
        measured_points: the fit's points ``{name: (x, y)}`` (m), kept in the mesh (the fit's
            mesh lines); default none. nx, ny: the fit's mesh (default the spec's).
        z: the height (m) of the predicted points above the table top — the tool point or a
            workpiece feature — within :data:`Z_RANGE`: the table is rigid above its top, so
            EXX gains ``z·EBX`` and EYX ``−z·EAX`` (Abbe), in the errors and their σ.
        make_machine: ``make_machine(points, **kw)`` → the fitted machine with ``points``
            ``{name: (x, y)}`` (m) and the structure ``kw`` (``thickness``, ``preload_fraction``,
            ``stiffness_scale``); needed for a table imported from an FE model
            (:func:`diffguide.jobs.machine.config_machine`), whose points must be retained
            nodes. Default: :func:`~diffguide.machine.build.build_machine` of ``spec``.
        mesh_points: the points ``{name: (x, y)}`` (m) whose grid lines the table's mesh holds;
            default ``measured_points`` (the fit's mesh; the requested points are interpolated
            in its elements), or without them the specification's own points.
            ``{**measured_points, **points}`` gives the mesh of :func:`_predict_recondensed`
            (a grid line through every point).

    The table is condensed once per structure value and fitted model, not per point set
    (module docstring). Returns a :class:`Prediction`. ``ValueError`` for points off the
    table, positions as above or beyond the stroke, a name given twice with two locations, or
    an equilibrium that fails at some position.
    """
    post = FitPosterior.from_fit(fit)
    pts, x, flags, allp = _inputs(post, spec, points, positions, measured_points, extrapolate)
    z = _check_z(z)
    if make_machine is not None:  # an imported table: its retained points only
        mesh = allp
    else:
        given = measured_points if mesh_points is None else mesh_points
        mesh = _check_points(given or spec.point_dict, spec)
    sweep = posterior_sweep(post, spec, x, mesh, nx, ny, make_machine)
    e, sig = sweep.errors(np.array(list(pts.values())).reshape(-1, 2), z)
    return Prediction(positions=x, point_names=tuple(pts), points_xy=np.array(list(pts.values())),
                      errors=e, sigma=sig, extrapolated=flags,
                      position_range=tuple(post.position_range), lead=bool(len(post.lead)),
                      x_ref=float(post.x_ref), z=z)


def _inputs(post, spec, points, positions, measured_points, extrapolate):
    """The checked points, positions (m), extrapolation flags, and the measured points with
    the requested ones."""
    pts = _check_points(points, spec)
    x = np.atleast_1d(np.asarray(positions, float))
    flags = check_positions(x, post.position_range, extrapolate)
    half = float(spec.stroke) / 2
    if np.any(np.abs(x) > half + _X_TOL):
        v = float(x[np.abs(x) > half + _X_TOL][0])
        raise ValueError(f"position {v * 1e3:g} mm is beyond the machine's stroke "
                         f"(±{half * 1e3:g} mm)")
    allp = dict(_check_points(measured_points, spec)) if measured_points else {}
    for k, v in pts.items():
        if k in allp and not np.allclose(allp[k], v, atol=1e-9):
            raise ValueError(f"point {k!r} is a measured point at ({allp[k][0] * 1e3:g}, "
                             f"{allp[k][1] * 1e3:g}) mm: give the new point another name")
        allp[k] = v
    return pts, x, flags, allp


def _predict_recondensed(fit, spec, points, positions, *, measured_points=None, nx=None,
                         ny=None, extrapolate=False, z=0.0, make_machine=None) -> Prediction:
    """:func:`predict` the former way (a reference): the table condensed again with grid lines
    through the measured and the requested points, the errors and their Jacobian swept at
    those points, the thickness's secant column from two more such machines."""
    post = FitPosterior.from_fit(fit)
    pts, x, flags, allp = _inputs(post, spec, points, positions, measured_points, extrapolate)
    check_size(len(x), len(allp), post.cov.shape[0])
    machine = fitted_machine(spec, allp, nx, ny, post.structure, 0.0, make_machine)
    sel = [list(allp).index(k) for k in pts]
    z = _check_z(z)
    e, Jm, ok = _sweep(post, machine, x, True)
    if not ok:
        raise ValueError("the fitted model's equilibrium did not converge at some position; "
                         "no prediction")
    n_c, names = 4 * post.basis.per_profile, list(post.structure)
    n_v = post.cov.shape[0]
    J = np.zeros(e.shape + (n_v,))
    J[..., :n_c] = Jm[..., :n_c]
    if "preload" in names:
        J[..., n_c + names.index("preload")] = Jm[..., n_c]
    for name in ("thickness", "stiffness"):
        if name in names and not post.rigid:
            i = names.index(name)
            J[..., n_c + i] = _secant_column(post, spec, allp, nx, ny, x, i, name,
                                             make_machine)
    if len(post.lead):
        lo = n_c + len(names)
        ls, lh, ln = post.lead_basis
        B = bspline_matrix(x, ls, lh, ln) - bspline_matrix(np.array([post.x_ref]), ls, lh, ln)
        e[:, :, _EXX] += (B @ post.lead)[:, None]
        J[:, :, _EXX, lo:lo + ln] = B[:, None, :]
    e, J = abbe(e, z), abbe(J, z)
    sig = np.sqrt(np.maximum(np.einsum("pekv,vw,pekw->pek", J, post.cov, J), 0.0))
    return Prediction(positions=x, point_names=tuple(pts), points_xy=np.array(list(pts.values())),
                      errors=e[:, sel], sigma=sig[:, sel], extrapolated=flags,
                      position_range=tuple(post.position_range), lead=bool(len(post.lead)),
                      x_ref=float(post.x_ref), z=z)


#: Heights above the table top (m) a prediction accepts.
Z_RANGE = (-0.5, 2.0)


def _check_z(z) -> float:
    z = float(z)
    if not (np.isfinite(z) and Z_RANGE[0] <= z <= Z_RANGE[1]):
        raise ValueError(f"z (height above the table top) must lie within [{Z_RANGE[0]:g}, "
                         f"{Z_RANGE[1]:g}] m, got {z:g} m{mm_hint(z, *Z_RANGE)}")
    return z


def abbe(a: np.ndarray, z: float) -> np.ndarray:
    """Errors (or their derivatives) ``(..., 6, ...)`` at the table top carried to the height
    ``z`` (m) above it on the rigid body over the top: a point at ``(0, 0, z)`` turned by the
    small angles ``(EAX, EBX, ECX)`` moves by ``θ × (0, 0, z) = (z·EBX, −z·EAX, 0)``. The error
    axis is the one after the point axis (``e[:, :, k]``, ``J[:, :, k, :]``)."""
    if z == 0.0:
        return a
    out = np.array(a, float, copy=True)
    out[:, :, _EXX] += z * out[:, :, _EBX]
    out[:, :, _EYX] -= z * out[:, :, _EAX]
    return out


def _secant_column(post: FitPosterior, spec, allp, nx, ny, x, i, name,
                   make_machine=None) -> np.ndarray:
    """``∂e/∂q`` of the thickness or the stiffness scale (per prior σ of its log): a secant
    over ``±h`` prior σ (module docstring)."""
    s = post.structure[name]["prior_sigma_log"]
    nq = len(post.structure)
    n_c = 4 * post.basis.per_profile
    cov_q = post.cov[n_c:n_c + nq, n_c + i]
    h = float(np.clip(np.sqrt(max(cov_q[i], 0.0)), *SECANT_STEP_LIMITS))
    out = []
    for sign in (-1.0, 1.0):
        m = fitted_machine(spec, allp, nx, ny, post.structure, sign * h * s, make_machine)
        e, _, ok = _sweep(post, m, x, False)
        if not ok:
            raise ValueError(f"the fitted model's equilibrium did not converge at the {name} "
                             "± its σ; no prediction")
        out.append(e)
    return (out[1] - out[0]) / (2 * h)
