r"""The fitted model solved once over the table positions: the errors with σ at any points of
the table top from it, without condensing the table again.

The joint errors at a point P are a linear map of the table's interface DOF ``u`` (the
carriages' and the nut's poses): ``E_P(x) = R_P (u(x) − u(x_ref))`` (``R_P`` the point's
recovery rows; the gravity sag ``r0`` cancels in the difference). So one equilibrium sweep per
structure value gives the errors at every point of the table:

- ``Δu(x) = u(x) − u(x_ref)`` at the fitted structure, with its Jacobian in the rail
  coefficients and the preload (one forward-mode pass through the implicit equilibria), and at
  ``t̂·e^{±hσ_t}`` for the thickness's secant (or an imported table's stiffness scale);
- ``R_P`` of each structure value's table: a measured point's rows from the table itself,
  another point's from its nodes by the shell's shape functions
  (:func:`~diffguide.fe.recovery.point_rows`; an imported table has no nodes: it predicts at
  its retained points only).

With ``J_P = [R_P Ju ; the lead row]`` and the secant column ``a_P = (R⁺_P Δu⁺ − R⁻_P Δu⁻)/(2h)``
the variance is ``diag(J_P Cov J_Pᵀ)``, computed as ``R̂_P S R̂_Pᵀ`` with ``S = Ĵu Cov Ĵuᵀ``
(one ``(m+1)²`` matrix per position, whatever the number of points) plus the secant terms:
memory and time grow linearly with the points (:meth:`PosteriorSweep.errors`).
"""

import dataclasses
import hashlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.aot import cached_program
from ..fe.recovery import point_rows
from ..guideway.rails import bspline_matrix
from ..machine.build import build_machine, table_from_spec, with_overrides
from ..machine.kinematics import ERROR_NAMES, joint_errors_traced
from .posterior import SECANT_STEP_LIMITS
from .structure import scaled_preload

#: Machines kept (each a condensation of the table; ~1 s for ``majda2012``).
MACHINE_CACHE_SIZE = 8
#: Sweeps kept (each: a fit over one set of positions).
SWEEP_CACHE_SIZE = 8
#: Points per block of the σ computation (bounds its memory: ~50 MB at 71 positions).
POINT_BLOCK = 512
#: A point this close (m) to a control point of the machine takes that point's rows.
_SAME_POINT = 1e-9
_EXX, _EYX = ERROR_NAMES.index("EXX"), ERROR_NAMES.index("EYX")
_EAX, _EBX = ERROR_NAMES.index("EAX"), ERROR_NAMES.index("EBX")

_MACHINES: dict = {}
_SWEEPS: dict = {}


def fitted_machine(spec, points: dict, nx, ny, structure: dict, log_shift: float = 0.0,
                   make_machine=None):
    """The machine of ``spec`` at the fitted structure (the thickness, or an imported table's
    stiffness scale, times ``e^shift``) with ``points`` (m) in its mesh, built by
    ``make_machine(points, **kw)`` (default :func:`~diffguide.machine.build.build_machine` of
    ``spec`` on the mesh ``nx``, ``ny``); the last :data:`MACHINE_CACHE_SIZE` are kept."""
    kw = {}
    if "thickness" in structure:
        kw["thickness"] = structure["thickness"]["value"] * float(np.exp(log_shift))
    if "stiffness" in structure:
        kw["stiffness_scale"] = structure["stiffness"]["value"] * float(np.exp(log_shift))
    if "preload" in structure:
        kw["preload_fraction"] = structure["preload"]["value"]
    key = (id(spec), id(make_machine), nx, ny, tuple((k, *v) for k, v in points.items()),
           tuple(sorted(kw.items())))
    if key not in _MACHINES:
        while len(_MACHINES) >= MACHINE_CACHE_SIZE:
            _MACHINES.pop(next(iter(_MACHINES)))
        if make_machine is None:
            m = build_machine(spec, nx=nx, ny=ny, points=points, **kw)
        else:
            m = make_machine(points, **kw)
        _MACHINES[key] = (spec, make_machine, m)  # the first two keep their ids alive
    return _MACHINES[key][-1]


def perturbed_joint_errors(c, dq_p, machine, positions, x_ref, basis, sigma_p):
    """:func:`~diffguide.machine.kinematics.joint_errors_traced` of ``machine`` for rail
    coefficients ``c`` (m, flat, on ``basis``) with the preload moved by ``dq_p`` prior σ
    (``sigma_p``) of its log: the fitted model as the prediction evaluates it."""
    m = scaled_preload(machine, sigma_p * dq_p)
    rails = basis.rails(c.reshape(2, 2, basis.per_profile))
    return joint_errors_traced(m, rails, positions, x_ref)


def _interface_traced(c, dq_p, machine, positions, x_ref, basis, sigma_p):
    """``u(x) − u(x_ref)`` ``(n_pos, m)`` (:func:`perturbed_joint_errors`) and whether every
    equilibrium converged."""
    je = perturbed_joint_errors(c, dq_p, machine, positions, x_ref, basis, sigma_p)
    return je.interface - je.interface_ref, jnp.all(je.converged)


#: ``Δu`` ``(n_pos, m)`` and convergence; with an export folder set (the command line sets
#: one, :mod:`diffguide._core.aot`) a later process reads the traced program back instead of
#: tracing it again. A prediction runs it once per process, so the stored program is
#: compiled at XLA's optimisation level 0: the compilation dominates a first
#: ``diffguide predict``, the sweep's run time stays in the milliseconds.
_interface_jit = cached_program(eqx.filter_jit(_interface_traced),
                                "inverse.posterior_sweep._interface",
                                compiler_options={"xla_backend_optimization_level": 0})


def with_jacobian(traced):
    """The compiled ``(value, its Jacobian in (c, dq_p) (..., 4n + 1), convergence)`` of
    ``traced(c, dq_p, machine, positions, x_ref, basis, sigma_p) -> (value, converged)``
    (forward mode: a few hundred columns at most)."""

    @eqx.filter_jit
    def value_and_jacobian(c, dq_p, machine, positions, x_ref, basis, sigma_p):
        def f(t):
            v, ok = traced(t[:-1], t[-1], machine, positions, x_ref, basis, sigma_p)
            return v, (v, ok)

        J, (v, ok) = jax.jacfwd(f, has_aux=True)(jnp.concatenate([c, jnp.zeros(1) + dq_p]))
        return v, J, ok

    return value_and_jacobian


#: ``Δu`` ``(n_pos, m)``, its Jacobian ``(n_pos, m, 4n + 1)`` and convergence (stored as
#: :data:`_interface_jit` is).
_interface_and_jacobian = cached_program(with_jacobian(_interface_traced),
                                         "inverse.posterior_sweep._interface_and_jacobian",
                                         compiler_options={"xla_backend_optimization_level": 0})


def abbe_matrix(z: float) -> np.ndarray:
    """``T`` ``(6, 6)``: the errors at the table top carried to the height ``z`` (m) above it
    on the rigid body over the top, ``EXX += z·EBX``, ``EYX −= z·EAX``."""
    T = np.eye(6)
    T[_EXX, _EBX] += z
    T[_EYX, _EAX] -= z
    return T


@dataclasses.dataclass(frozen=True)
class PosteriorSweep:
    """A fit's model solved over ``positions`` (SI): what the errors with σ at any points need
    (module docstring). Made by :func:`posterior_sweep`.

    Attributes:
        positions: ``(n_pos,)`` table positions (m). machines: the fitted machine, then the two
            machines (``−h``, ``+h``) of each secant unknown. mesh: their mesh's topology
            (``None`` for an imported table). du: ``(n_machines, n_pos, m)`` ``u(x) − u(x_ref)``.
        jac: ``(n_pos, m + 1, n_v)`` the Jacobian of ``Δu`` (rows ``:m``) and of the lead
            error in EXX (row ``m``) in the fit's unknowns ``v``. lead: ``(n_pos,)`` the lead
            error (m) added to EXX. secants: ``(index in v, h)`` per secant unknown. cov: the
            posterior covariance of ``v``.
    """

    positions: np.ndarray
    machines: tuple
    mesh: object
    du: np.ndarray
    jac: np.ndarray
    lead: np.ndarray
    secants: tuple
    cov: np.ndarray

    def rows(self, points_xy) -> np.ndarray:
        """``(n_machines, q, 6, m)`` recovery rows of the top-surface points ``(q, 2)`` (m):
        a control point's own rows where a point is one (within 1 nm), else interpolated."""
        pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        out = []
        for machine in self.machines:
            own = np.asarray(machine.points_xy, dtype=float).reshape(-1, 2)
            R = np.asarray(machine.table.R).reshape(len(own), 6, -1)
            d = np.abs(pts[:, None, :] - own[None, :, :]).max(axis=-1)  # (q, n_own)
            hit = d.min(axis=1) <= _SAME_POINT
            rows = np.empty((len(pts), 6, R.shape[-1]))
            rows[hit] = R[np.argmin(d[hit], axis=1)]
            if not hit.all():
                if self.mesh is None:
                    x, y = pts[~hit][0] * 1e3
                    raise ValueError(f"point ({x:g}, {y:g}) mm is not a retained point of the "
                                     "imported table: predict at its retained points")
                rows[~hit] = point_rows(machine.table, self.mesh, pts[~hit])[0]
            out.append(rows)
        return np.stack(out)

    def errors(self, points_xy, z: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """The errors and their σ ``(n_pos, q, 6)`` (m, rad) at the points ``(q, 2)`` (m), at
        the height ``z`` (m) above the top (:func:`abbe_matrix`); in blocks of
        :data:`POINT_BLOCK` points."""
        pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        es, ss = [], []
        for k in range(0, len(pts), POINT_BLOCK):
            e, s = self._errors(pts[k:k + POINT_BLOCK], abbe_matrix(float(z)))
            es.append(e)
            ss.append(s)
        return np.concatenate(es, axis=1), np.concatenate(ss, axis=1)

    def _errors(self, pts, T):
        R = np.einsum("kl,sqlm->sqkm", T, self.rows(pts))  # (n_machines, q, 6, m)
        n_pos, q, m = len(self.positions), len(pts), R.shape[-1]
        e = np.einsum("qkm,pm->pqk", R[0], self.du[0])
        e[:, :, _EXX] += self.lead[:, None]
        Rh = np.concatenate([R[0], np.zeros((q, 6, 1))], axis=-1)
        Rh[:, _EXX, m] = 1.0  # the lead row enters EXX (which no Abbe term feeds)
        Rh = Rh.reshape(q * 6, m + 1)
        S = np.einsum("pav,vw,pbw->pab", self.jac, self.cov, self.jac, optimize=True)
        a1 = m + 1  # one product (Q, a1) @ (a1, n_pos·a1): a single large BLAS call
        Y = (Rh @ S.transpose(1, 0, 2).reshape(a1, n_pos * a1)).reshape(q * 6, n_pos, a1)
        var = np.einsum("qpb,qb->pq", Y, Rh)
        if self.secants:
            idx = [i for i, _ in self.secants]
            a = np.stack([(self._motion(R, 2 * s + 2) - self._motion(R, 2 * s + 1)) / (2 * h)
                          for s, (_, h) in enumerate(self.secants)], axis=-1)  # (p, Q, n_sec)
            b = np.einsum("pav,vi->pai", self.jac, self.cov[:, idx])  # (p, m + 1, n_sec)
            var += 2 * np.einsum("pqi,qa,pai->pq", a, Rh, b, optimize=True)
            var += np.einsum("pqi,ij,pqj->pq", a, self.cov[np.ix_(idx, idx)], a)
        sig = np.sqrt(np.maximum(var, 0.0)).reshape(n_pos, q, 6)
        return e, sig

    def _motion(self, R, k):
        """``R_P Δu`` of machine ``k``, ``(n_pos, q·6)``."""
        return self.du[k] @ R[k].reshape(-1, R.shape[-1]).T


def _post_key(post) -> str:
    """A digest of a posterior's content (its arrays and settings)."""
    h = hashlib.sha1()
    for f in dataclasses.fields(post):
        v = getattr(post, f.name)
        h.update(f.name.encode())
        h.update(np.ascontiguousarray(v).tobytes() if isinstance(v, np.ndarray)
                 else repr(v).encode())
    return h.hexdigest()


def posterior_sweep(post, spec, positions, mesh_points: dict, nx=None, ny=None,
                    make_machine=None) -> PosteriorSweep:
    """The :class:`PosteriorSweep` of the posterior ``post``
    (:class:`~.predict.FitPosterior`) on the machine ``spec`` over ``positions`` (m, checked by
    the caller), its table meshed with grid lines through ``mesh_points`` ``{name: (x, y)}``
    (m; the fit's points: the fit's own mesh), on the mesh ``nx``, ``ny`` (default the
    spec's); ``make_machine`` as :func:`fitted_machine`'s. The last :data:`SWEEP_CACHE_SIZE`
    are kept: a prediction at other points of the same fit and positions reuses one.
    ``ValueError`` when an equilibrium does not converge."""
    x = np.asarray(positions, dtype=float)
    key = (_post_key(post), id(spec), id(make_machine), x.tobytes(), nx, ny,
           tuple((k, *map(float, v)) for k, v in mesh_points.items()))
    if key not in _SWEEPS:
        while len(_SWEEPS) >= SWEEP_CACHE_SIZE:
            _SWEEPS.pop(next(iter(_SWEEPS)))
        _SWEEPS[key] = (spec, make_machine, _solve(post, spec, x, mesh_points, nx, ny,
                                                   make_machine))
    return _SWEEPS[key][-1]


def _run(post, machine, x, with_jacobian: bool):
    names = list(post.structure)
    sigma_p = post.structure["preload"]["prior_sigma_log"] if "preload" in names else 0.0
    if post.rigid:
        machine = machine.with_rigid_table()
    args = (jnp.asarray(post.coeffs.reshape(-1)), 0.0, machine, jnp.asarray(x),
            jnp.asarray(float(post.x_ref)), post.basis, float(sigma_p))
    if with_jacobian:
        du, J, ok = _interface_and_jacobian(*args)
        return np.asarray(du), np.asarray(J), bool(ok)
    du, ok = _interface_jit(*args)
    return np.asarray(du), None, bool(ok)


def _solve(post, spec, x, mesh_points, nx, ny, make_machine) -> PosteriorSweep:
    names = list(post.structure)
    n_c, n_v = 4 * post.basis.per_profile, post.cov.shape[0]
    machine = fitted_machine(spec, mesh_points, nx, ny, post.structure, 0.0, make_machine)
    du, Jm, ok = _run(post, machine, x, True)
    if not ok:
        raise ValueError("the fitted model's equilibrium did not converge at some position; "
                         "no prediction")
    m = du.shape[1]
    jac = np.zeros((len(x), m + 1, n_v))
    jac[:, :m, :n_c] = Jm[..., :n_c]
    if "preload" in names:
        jac[:, :m, n_c + names.index("preload")] = Jm[..., n_c]
    lead = np.zeros(len(x))
    if len(post.lead):
        lo = n_c + len(names)
        ls, lh, ln = post.lead_basis
        B = bspline_matrix(x, ls, lh, ln) - bspline_matrix(np.array([post.x_ref]), ls, lh, ln)
        lead = B @ post.lead
        jac[:, m, lo:lo + ln] = B
    machines, dus, secants = [machine], [du], []
    for name in ("thickness", "stiffness"):
        if name in names and not post.rigid:
            i = names.index(name)
            s = post.structure[name]["prior_sigma_log"]
            h = float(np.clip(np.sqrt(max(post.cov[n_c + i, n_c + i], 0.0)),
                              *SECANT_STEP_LIMITS))
            for sign in (-1.0, 1.0):
                mm = fitted_machine(spec, mesh_points, nx, ny, post.structure, sign * h * s,
                                    make_machine)
                d, _, ok = _run(post, mm, x, False)
                if not ok:
                    raise ValueError(f"the fitted model's equilibrium did not converge at the "
                                     f"{name} ± its σ; no prediction")
                machines.append(mm)
                dus.append(d)
            secants.append((n_c + i, h))
    mesh = None
    if make_machine is None:
        mesh = table_from_spec(with_overrides(spec, nx=nx, ny=ny, points=mesh_points)).mesh
    return PosteriorSweep(positions=x, machines=tuple(machines), mesh=mesh, du=np.stack(dus),
                          jac=jac, lead=lead, secants=tuple(secants), cov=np.asarray(post.cov))
