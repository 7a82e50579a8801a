r"""The machine: a condensed elastic table on four carriages, two rails, the feed screw, gravity.

Unknowns at each table position ``x``: the interface DOF ``u`` of the condensed table
(:class:`~diffguide.fe.condense.CondensedTable`): 6 per carriage patch (the carriage is a rigid
body bolted to its patch, so its pose *is* the patch's DOF) and 6 for the screw-nut patch. The
total potential is convex:

.. math::

    Π(u) = ½uᵀKu - fᵀu + \sum_{k}\sum_{j} φ\bigl(a_{kj}(u_k; x)\bigr) + ½ k_s(x)\,u_{nut,x}^2,

with ``a_kj`` the element approaches of carriage ``k`` over the rail at ``s = x + X_k + ξ_j``
(:meth:`~diffguide.guideway.Carriage.approaches`), ``k_s(x) = E A / (L₀ + x)`` the axial stiffness
of the screw between its fixed bearing and the nut. Its stationary point is found with Newton and
an Armijo line search (:mod:`diffguide._core.newton`), for all positions in one vmapped call. Π is
quadratic in each carriage's ``tx`` (no element load has an X component) and in the nut's six DOF:
those are condensed exactly (:class:`_Condensation`), and Newton runs on the carriages' other
``5k`` DOF. The solution is differentiated by the implicit function theorem on the full ``Π``
(its exact Hessian at the solution; :func:`~diffguide._core.newton.implicit_root`).

Rigid-table mode: the same machine with an infinitely stiff table, i.e. the interface DOF
restricted to the six rigid-body motions of the table, ``u = Φ q`` (``Φ`` maps the table's
translation and rotation at the origin to each patch): ``K → ΦᵀKΦ = 0``, ``f → Φᵀf`` (the weight
and its moment), control points move rigidly and gravity sag is gone.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.newton import implicit_root, solve_equilibrium
from .._core.precision import require_x64
from .._core.result import RESULTS
from .._core.rigid import rigid_transfer
from .._core.types import Array, Float, Int
from ..fe.condense import CondensedTable
from ..guideway.carriage import Carriage
from ..guideway.rails import AbstractRailProfile

#: Unknowns in µm and µrad.
DOF_SCALE = 1e-6


def rigid_body_map(ref_points: Float[Array, "p 3"]) -> Float[Array, "6p 6"]:
    """``Φ``: the motion ``(u, θ)`` of each reference point for a rigid motion ``(t, θ)`` of the
    table at the origin, ``u = t + θ × p`` (:func:`~diffguide._core.rigid.rigid_transfer`)."""
    return rigid_transfer(jnp.asarray(ref_points)).reshape(-1, 6)


class Machine(eqx.Module):
    """A table on four carriages: everything the equilibrium needs, SI units.

    Arguments:
        table: the condensed elastic table; interface order: the carriage patches, then the nut.
        carriage: the runner block (the same block at every carriage position).
        carriage_x: ``X_k``, each carriage's X offset from the table centre (m).
        carriage_rail: the rail (0 = rail 1, 1 = rail 2) of each carriage.
        point_names: control-point names, in the order of ``table.R``'s rows.
        points_xy: control points (x, y) on the table top, relative to its centre (m).
        screw_EA: axial rigidity of the screw core, ``E·π d²/4`` (N).
        screw_length_ref: free length of the screw from its fixed bearing to the nut at x = 0
            (m); the free length at position ``x`` is ``screw_length_ref + x``.
        rigid: infinitely stiff table (see the module docstring).
        stroke: the X stroke (m), symmetric about the reference position, when known (a machine
            built from a specification); measured positions beyond it are refused by the fit.
    """

    table: CondensedTable
    carriage: Carriage
    carriage_x: Float[Array, " k"]
    carriage_rail: tuple[int, ...] = eqx.field(static=True)
    point_names: tuple[str, ...] = eqx.field(static=True)
    points_xy: Float[Array, "p 2"]
    screw_EA: float | Float[Array, ""]
    screw_length_ref: float | Float[Array, ""]
    rigid: bool = eqx.field(static=True, default=False)
    stroke: float | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        k = len(self.carriage_rail)
        if np.shape(self.carriage_x) != (k,):
            raise ValueError(
                f"carriage_x must have one entry per carriage ({k}), got shape "
                f"{np.shape(self.carriage_x)}"
            )
        if any(r not in (0, 1) for r in self.carriage_rail):
            raise ValueError(f"carriage_rail entries must be 0 or 1, got {self.carriage_rail}")
        m = np.shape(self.table.K)[0]
        if m != 6 * (k + 1):
            raise ValueError(
                f"the table must have 6 interface DOF per carriage plus 6 for the nut "
                f"({6 * (k + 1)}), got {m}"
            )
        if len(self.point_names) != np.shape(self.points_xy)[0]:
            raise ValueError("point_names and points_xy must have the same length")

    @property
    def n_carriages(self) -> int:
        return len(self.carriage_rail)

    @property
    def nut_dof(self) -> int:
        """Index of the nut's ux in the interface DOF."""
        return 6 * self.n_carriages

    def with_rigid_table(self, rigid: bool = True) -> "Machine":
        """The same machine with an infinitely stiff table (or back to the elastic one)."""
        return dataclasses.replace(self, rigid=rigid)

    def basis(self) -> Float[Array, "m d"]:
        """``Φ``: interface DOF from the generalized DOF (identity, or the rigid-body map)."""
        if self.rigid:
            return rigid_body_map(self.table.ref_points)
        return jnp.eye(self.table.K.shape[0])

    def screw_stiffness(self, x: Float[Array, ""]) -> Float[Array, ""]:
        """Axial stiffness of the screw at table position ``x`` (m): ``EA / (L₀ + x)`` (N/m)."""
        return self.screw_EA / (self.screw_length_ref + x)

    def rail_under_carriages(
        self, x: Float[Array, ""], rails: tuple[AbstractRailProfile, AbstractRailProfile]
    ) -> Float[Array, "k n 2"]:
        """Rail deviation ``(e_y, e_z)`` (m) under every element of every carriage at ``x`` (m)."""
        xi = jnp.asarray(self.carriage.xi, dtype=float)
        parts, order = [], []
        for r in sorted(set(self.carriage_rail)):  # one evaluation per rail (a smaller program)
            ks = [k for k, rk in enumerate(self.carriage_rail) if rk == r]
            ey, ez = rails[r](x + self.carriage_x[np.asarray(ks)][:, None] + xi)
            parts.append(jnp.stack([ey, ez], axis=-1))
            order += ks
        out = jnp.concatenate(parts)
        return out if order == sorted(order) else out[np.argsort(order)]


def _split(u, n_carriages):
    return u[: 6 * n_carriages].reshape(n_carriages, 6)


def _contacts(machine: Machine, u, rail):
    """Approaches (k, rows, n) of all carriages at interface DOF ``u`` (m, rad)."""
    poses = _split(u, machine.n_carriages)
    return jax.vmap(machine.carriage.approaches)(poses, rail)


# ---- elastic table: Newton on the carriages' 5k contact DOF, the others condensed exactly ----


def _dof_split(n_carriages: int) -> tuple[np.ndarray, np.ndarray]:
    """Static index sets ``(N, L)`` of the interface DOF: ``L``, those on which the potential is
    quadratic — each carriage's ``tx`` (the elements' load directions have no X component, so no
    approach depends on it) and the nut's six — and ``N``, the carriages' other five."""
    lin = [6 * c for c in range(n_carriages)] + list(range(6 * n_carriages, 6 * n_carriages + 6))
    nonlin = [6 * c + i for c in range(n_carriages) for i in range(1, 6)]
    return np.array(nonlin), np.array(lin)


class _Condensation(eqx.Module):
    r"""The position-independent part of the exact condensation of the quadratic DOF ``L``.

    With ``A(x) = K_LL + k_s(x) e eᵀ`` (``e``: the nut's ux in ``L``), minimising Π over
    ``u_L`` gives ``u_L = A⁻¹(f_L − K_LN u_N)`` and the reduced potential
    ``½u_NᵀS u_N − f_rᵀu_N + Σφ`` with ``S = K_NN − K_NL A⁻¹ K_LN``,
    ``f_r = f_N − K_NL A⁻¹ f_L``. ``A`` is SPD: the only rigid motion of the free table that
    vanishes on ``N`` is the X translation, which moves the nut. Its ``x`` dependence is the
    rank one ``k_s(x)``: with ``A_c = K_LL + c e eᵀ`` (``c = k_s(0)``) and
    ``β = (k_s − c)/(1 + (k_s − c) eᵀA_c⁻¹e)``, Sherman–Morrison gives
    ``A⁻¹ = A_c⁻¹ − β A_c⁻¹e eᵀA_c⁻¹``, ``S = S_c + β w wᵀ``, ``f_r = f_c + β h w`` with
    ``w = K_NL A_c⁻¹ e``, ``h = eᵀA_c⁻¹ f_L``.

    Newton's default start is one step from zero of the problem with linear springs at preload
    (stiffnesses ``k⁰``, forces ``F⁰`` at the approaches on straight rails, ``a⁰``), i.e. the
    solution of that linear problem: ``y₀ = −P g̃``, ``P`` (µm²/J) the inverse of the reduced
    Hessian at zero on straight rails with ``k_s(0)``, ``g̃ = −f_r − Σ_j (F⁰_j + k⁰_j Δa_j) G_j``
    with ``Δa`` the approaches' change by the rail deviation. It costs a matrix-vector product
    per position where the exact first Newton step costs a factorisation (and lands as close:
    one Newton step fewer).
    """

    A_inv: Float[Array, "l l"]
    K_LN: Float[Array, "l n"]
    f_L: Float[Array, " l"]
    S: Float[Array, "n n"]
    f_r: Float[Array, " n"]
    w: Float[Array, " n"]
    h: Float[Array, ""]
    c: Float[Array, ""]
    P: Float[Array, "n n"]
    a0: Float[Array, "rows m"]
    k0: Float[Array, " e"]
    w0: Float[Array, " 5"]
    nut: int = eqx.field(static=True)

    @classmethod
    def of(cls, machine: Machine, K, f) -> "_Condensation":
        N, L = _dof_split(machine.n_carriages)
        nut = machine.n_carriages  # the nut's ux in L
        c = jnp.asarray(machine.screw_stiffness(0.0), dtype=float)
        A = K[np.ix_(L, L)].at[nut, nut].add(c)
        A_inv = jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(A), jnp.eye(len(L)))
        K_LN = K[np.ix_(L, N)]
        A_inv_f = A_inv @ f[L]
        S = K[np.ix_(N, N)] - K_LN.T @ A_inv @ K_LN
        carriage = machine.carriage
        n = machine.n_carriages
        a0 = carriage.approaches(jnp.zeros(6), jnp.zeros((carriage.n_elements, 2)))
        k0 = carriage.element_stiffnesses(a0).reshape(-1)
        G = carriage.jacobian().reshape(-1, 6)[:, 1:]
        T = (k0 * G.T) @ G
        blocks = (T[None, :, None, :] * jnp.eye(n)[:, None, :, None]).reshape(5 * n, 5 * n)
        H0 = S + blocks
        P = jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(H0), jnp.eye(5 * n))
        return cls(
            A_inv=A_inv,
            K_LN=K_LN,
            f_L=f[L],
            S=S,
            f_r=f[N] - K_LN.T @ A_inv_f,
            w=K_LN.T @ A_inv[:, nut],
            h=A_inv_f[nut],
            c=c,
            P=P * (1.0 / DOF_SCALE**2),
            a0=a0,
            k0=k0,
            w0=carriage.element_forces(a0).reshape(-1) @ G,
            nut=nut,
        )

    def beta(self, ks):
        return (ks - self.c) / (1.0 + (ks - self.c) * self.A_inv[self.nut, self.nut])

    def start(self, machine: Machine, f_r, rail):
        """Newton's default start (µm, µrad), see the class docstring."""
        carriage = machine.carriage
        n = machine.n_carriages
        da = jax.vmap(carriage.approaches)(jnp.zeros((n, 6)), rail) - self.a0
        G = carriage.jacobian().reshape(-1, 6)[:, 1:]
        wrenches = self.w0 + (da.reshape(n, -1) * self.k0) @ G
        return self.P @ (f_r + wrenches.reshape(-1)) * DOF_SCALE

    def reduced(self, ks):
        """``(S, f_r)`` at screw stiffness ``ks`` (N/m)."""
        b = self.beta(ks)
        return self.S + b * self.w[:, None] * self.w, self.f_r + b * self.h * self.w

    def interface(self, u_N, ks):
        """All interface DOF (m, rad) from the contact DOF ``u_N`` (m, rad):
        ``u_L = A⁻¹(f_L − K_LN u_N)``."""
        rhs = self.f_L - self.K_LN @ u_N
        e_col = self.A_inv[:, self.nut]
        u_L = self.A_inv @ rhs - self.beta(ks) * e_col * (e_col @ rhs)
        N, L = _dof_split(self.nut)
        return jnp.concatenate([u_N, u_L])[np.argsort(np.concatenate([N, L]))]


def _poses(machine: Machine, y):
    """Carriage poses (k, 6) (m, rad) from the scaled contact DOF (µm, µrad): ``tx = 0``."""
    u = (y * DOF_SCALE).reshape(machine.n_carriages, 5)
    return jnp.pad(u, ((0, 0), (1, 0)))


def _potential(y, args):
    """Reduced potential (J; a constant dropped) at the scaled contact DOF ``y``."""
    machine, S, f_r, rail = args
    u = y * DOF_SCALE
    a = jax.vmap(machine.carriage.approaches)(_poses(machine, y), rail)
    return 0.5 * u @ (S @ u) - f_r @ u + machine.carriage.energy(a)


def _grad_hess(y, args):
    """Gradient (J/µm) and Hessian (J/µm²) of :func:`_potential`.

    The carriages' tangents ``T_c = Σ_j k_cj G_j G_jᵀ`` (their 5×5 contact blocks) are one matrix
    product of the element stiffnesses with the elements' outer products ``G_j G_jᵀ``, placed on
    the block diagonal by a broadcast with the identity: the assembly is element-wise (no
    scatter), which XLA fuses.
    """
    machine, S, f_r, rail = args
    u = y * DOF_SCALE
    carriage = machine.carriage
    n = machine.n_carriages
    a = jax.vmap(carriage.approaches)(_poses(machine, y), rail)
    G = carriage.jacobian().reshape(-1, 6)[:, 1:]  # (elements, 5); the tx column is zero
    F = carriage.element_forces(a).reshape(n, -1)
    wrenches = (F @ G).reshape(-1)  # elements on the carriages = carriages on the table
    g = (S @ u - f_r - wrenches) * DOF_SCALE
    k = carriage.element_stiffnesses(a).reshape(n, -1)
    T = (k @ (G[:, :, None] * G[:, None, :]).reshape(-1, 25)).reshape(n, 5, 1, 5)
    H = S + (T * jnp.eye(n)[:, None, :, None]).reshape(5 * n, 5 * n)
    return g, H * DOF_SCALE**2


# ---- all interface DOF (or the rigid table's six): the rigid table's Newton, and the elastic
# table's implicit derivative ----


def _interface(y, Phi):
    """Interface DOF (m, rad) from the generalized unknowns (µm, µrad); ``Phi`` is ``None`` for
    the elastic table (the unknowns are the interface DOF themselves)."""
    return (y if Phi is None else Phi @ y) * DOF_SCALE


def _full_potential(y, args):
    machine, K, f, Phi, ks, rail = args
    u = _interface(y, Phi)
    a = _contacts(machine, u, rail)
    nut = u[machine.nut_dof]
    return 0.5 * u @ (K @ u) - f @ u + machine.carriage.energy(a) + 0.5 * ks * nut**2


def _full_grad_hess(y, args):
    """Gradient (J/µm) and Hessian (J/µm²) of :func:`_full_potential` in the scaled unknowns."""
    machine, K, f, Phi, ks, rail = args
    u = _interface(y, Phi)
    a = _contacts(machine, u, rail)
    carriage = machine.carriage
    n = machine.n_carriages
    nc, m = 6 * n, K.shape[0]
    G = carriage.jacobian().reshape(-1, 6)  # (elements, 6)
    F = carriage.element_forces(a).reshape(n, -1)
    k = carriage.element_stiffnesses(a).reshape(n, -1)
    wrenches = (F @ G).reshape(-1)
    T = (k @ (G[:, :, None] * G[:, None, :]).reshape(-1, 36)).reshape(n, 6, 1, 6)
    tangents = (T * jnp.eye(n)[:, None, :, None]).reshape(nc, nc)
    e = jnp.zeros(m).at[machine.nut_dof].set(1.0)  # the screw acts on the nut's ux
    g = K @ u - f - jnp.pad(wrenches, (0, m - nc)) + ks * u[machine.nut_dof] * e
    H = K + jnp.pad(tangents, (0, m - nc)) + ks * e[:, None] * e
    if Phi is not None:
        g, H = Phi.T @ g, Phi.T @ H @ Phi
    return g * DOF_SCALE, H * DOF_SCALE**2


class MachineState(eqx.Module):
    """Equilibrium of the machine at a batch of table positions.

    Attributes:
        positions: table positions ``x`` (m).
        interface: interface DOF ``u`` of the table at each position, ``(n_pos, m)`` (m, rad).
        forces: element forces, ``(n_pos, k, rows, n)`` (N).
        result: result code (:class:`~diffguide._core.result.RESULTS`) per position.
        steps: Newton steps per position.
    """

    positions: Float[Array, " n_pos"]
    interface: Float[Array, "n_pos m"]
    forces: Float[Array, "n_pos k rows n"]
    result: RESULTS
    steps: Int[Array, " n_pos"]

    @property
    def converged(self) -> jax.Array:
        return self.result == RESULTS.successful


def _no_grad(tree):
    """``tree`` with ``stop_gradient`` on its arrays (other leaves as they are)."""
    return jax.tree_util.tree_map(
        lambda v: jax.lax.stop_gradient(v) if eqx.is_array(v) else v, tree
    )


def _solve_one(machine: Machine, x, rails, Phi, K, f, cond, y0, tol, max_steps):
    rail = machine.rail_under_carriages(x, rails)
    ks = machine.screw_stiffness(x)
    full = (machine, K, f, Phi, ks, rail)
    if cond is not None:
        # Newton on the contact DOF, not differentiated; the derivatives of all 30 DOF are the
        # implicit function theorem's on the full potential (its exact Hessian at the solution)
        sg = _no_grad
        S, f_r = cond.reduced(sg(ks))
        N, _ = _dof_split(machine.n_carriages)
        args = (sg(machine), S, f_r, sg(rail))
        if y0 is None:  # the solution with linear springs at preload (_Condensation)
            y0 = cond.start(args[0], f_r, args[3])
            y0 = jnp.where(jnp.all(jnp.isfinite(y0)), y0, 0.0)  # (a singular tangent)
        else:
            y0 = y0[N]
        y, result, steps = solve_equilibrium(
            _potential, _grad_hess, sg(y0), args, tol=tol, max_steps=max_steps
        )
        y = cond.interface(y * DOF_SCALE, sg(ks)) / DOF_SCALE
        y = implicit_root(_full_grad_hess, y, full)
    else:
        y, result, steps = solve_equilibrium(
            _full_potential, _full_grad_hess, y0, full, tol=tol, max_steps=max_steps
        )
    u = _interface(y, Phi)
    forces = machine.carriage.element_forces(_contacts(machine, u, rail))
    return u, forces, result, steps


def equilibrium_traced(
    machine: Machine,
    rails: tuple[AbstractRailProfile, AbstractRailProfile],
    positions: Float[Array, " n_pos"],
    *,
    initial: Float[Array, "n_pos d"] | None = None,
    tol: float = 1e-9,
    max_steps: int = 60,
    throw: bool = False,
    condensed: bool = True,
) -> MachineState:
    """Equilibrium of the machine at every table position, in one compiled, vmapped call.

    Arguments:
        machine: the machine (elastic or rigid table).
        rails: the error profiles of rail 1 and rail 2.
        positions: table positions ``x`` (m).
        initial: Newton's starting point per position, in the generalized DOF (µm, µrad;
            ``(n_pos, 30)`` elastic, ``(n_pos, 6)`` rigid); default zero (rigid) or, elastic,
            the solution with linear springs at preload (one Newton step fewer).
        tol: stop when the largest Newton step is below ``tol`` µm / µrad.
        max_steps: Newton step limit.
        throw: raise (``eqx.error_if``, also under ``jit``) when any position fails, instead
            of only flagging it in ``result``.
        condensed: elastic table: Newton on the carriages' contact DOF with the others
            condensed (see the module docstring): about half the run time of a sweep, but a
            larger program, which takes longer to compile; ``False``: Newton on all 30 interface DOF
            from zero. The same solution and derivatives either way.

    Returns:
        :class:`MachineState`; positions that did not converge are flagged in ``result``
        (``RESULTS.nonlinear_max_steps_reached``, or ``nonfinite`` for inf/NaN).
    """
    require_x64("equilibrium")
    if len(rails) != 2:
        raise ValueError(f"rails must be a pair (rail 1, rail 2), got {len(rails)} profiles")
    positions = jnp.atleast_1d(jnp.asarray(positions, dtype=float))
    machine = eqx.tree_at(lambda m: m.carriage, machine, machine.carriage.resolved())
    Phi = machine.basis() if machine.rigid else None
    d = machine.table.K.shape[0] if Phi is None else Phi.shape[1]
    K = machine.table.K
    f = machine.table.f

    # (not differentiated: see _solve_one)
    if machine.rigid or not condensed:
        cond = None
    else:
        cond = _Condensation.of(_no_grad(machine), _no_grad(K), _no_grad(f))
    predict = initial is None and cond is not None
    if initial is None:
        initial = jnp.zeros((positions.shape[0], d))
    if initial.shape != (positions.shape[0], d):
        raise ValueError(f"initial must have shape (n_pos, {d}), got {initial.shape}")

    def one(x, y0):
        return _solve_one(
            machine, x, rails, Phi, K, f, cond, None if predict else y0, tol, max_steps
        )

    u, forces, result, steps = jax.vmap(one)(positions, initial)
    if throw:
        u = _error_if_failed(u, result, "equilibrium")
    return MachineState(positions, u, forces, result, steps)


#: :func:`equilibrium_traced`, compiled (the function to call). Inside another traced function
#: call ``equilibrium_traced`` itself: a nested ``jit`` is traced again by every transformation
#: around it (``jvp``, ``vmap``).
equilibrium = eqx.filter_jit(equilibrium_traced)


def _error_if_failed(x, result, what: str):
    """``x``, raising (``eqx.error_if``) if any entry of the batched ``result`` failed."""
    failed = result != RESULTS.successful
    return eqx.error_if(
        x, failed, f"{what}: the solve did not converge at some positions (see `result`)"
    )


def point_motion(machine: Machine, interface: Float[Array, "... m"]) -> Float[Array, "... p 6"]:
    """Motion of the control points ``(ux, uy, uz, rx, ry, rz)`` (m, rad) for interface DOF.

    Elastic: ``R u + r0`` (``r0``: the gravity sag with the carriages held). Rigid: ``R u`` with
    ``u`` a rigid motion (the rigid table has no sag).
    """
    R = machine.table.R
    motion = jnp.einsum("im,...m->...i", R, interface)
    if not machine.rigid:
        motion = motion + machine.table.r0
    return motion.reshape(*motion.shape[:-1], -1, 6)


def node_motion(machine: Machine, interface: Float[Array, " m"]) -> Float[Array, "n 6"]:
    """Motion of every mesh node (mid-surface; m, rad) for interface DOF (the error field)."""
    field = machine.table.node_modes @ interface
    return field if machine.rigid else field + machine.table.node_u0
