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
an Armijo line search, differentiated implicitly by optimistix (:mod:`diffguide._core.newton`), for
all positions in one vmapped call.

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
import optimistix as optx

from .._core.newton import solve_equilibrium
from .._core.precision import require_x64
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


def _interface(y, Phi):
    """Interface DOF (m, rad) from the generalized unknowns (µm, µrad); ``Phi`` is ``None`` for
    the elastic table (the unknowns are the interface DOF themselves)."""
    return (y if Phi is None else Phi @ y) * DOF_SCALE


def _potential(y, args):
    machine, K, f, Phi, ks, rail = args
    u = _interface(y, Phi)
    a = _contacts(machine, u, rail)
    nut = u[machine.nut_dof]
    return 0.5 * u @ (K @ u) - f @ u + machine.carriage.energy(a) + 0.5 * ks * nut**2


def _grad_hess(y, args):
    """Gradient (J/µm) and Hessian (J/µm²) of the potential in the scaled unknowns.

    The carriages' tangents ``T_c = Σ_j k_cj G_j G_jᵀ`` are one matrix product of the element
    stiffnesses with the elements' outer products ``G_j G_jᵀ`` (elements, 36), placed on the
    block diagonal by a broadcast with the identity; the whole assembly is element-wise (no
    scatter), which XLA fuses.
    """
    machine, K, f, Phi, ks, rail = args
    u = _interface(y, Phi)
    a = _contacts(machine, u, rail)
    carriage = machine.carriage
    n = machine.n_carriages
    nc, m = 6 * n, K.shape[0]
    G = carriage.jacobian().reshape(-1, 6)  # (elements, 6)
    F = carriage.element_forces(a).reshape(n, -1)
    k = carriage.element_stiffnesses(a).reshape(n, -1)
    wrenches = (F @ G).reshape(-1)  # elements on the carriages = carriages on the table
    # the carriages' tangents −d(wrench)/d(pose), (k, 6, 6), as one block-diagonal (6k, 6k)
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
        result: optimistix result code per position.
        steps: Newton steps per position.
    """

    positions: Float[Array, " n_pos"]
    interface: Float[Array, "n_pos m"]
    forces: Float[Array, "n_pos k rows n"]
    result: optx.RESULTS
    steps: Int[Array, " n_pos"]

    @property
    def converged(self) -> jax.Array:
        return self.result == optx.RESULTS.successful


def _solve_one(machine: Machine, x, rails, Phi, K, f, y0, tol, max_steps):
    rail = machine.rail_under_carriages(x, rails)
    args = (machine, K, f, Phi, machine.screw_stiffness(x), rail)
    y, result, steps = solve_equilibrium(
        _potential, _grad_hess, y0, args, tol=tol, max_steps=max_steps
    )
    u = _interface(y, Phi)
    forces = machine.carriage.element_forces(_contacts(machine, u, rail))
    return u, forces, result, steps


@eqx.filter_jit
def equilibrium(
    machine: Machine,
    rails: tuple[AbstractRailProfile, AbstractRailProfile],
    positions: Float[Array, " n_pos"],
    *,
    initial: Float[Array, "n_pos d"] | None = None,
    tol: float = 1e-9,
    max_steps: int = 60,
    throw: bool = False,
) -> MachineState:
    """Equilibrium of the machine at every table position, in one compiled, vmapped call.

    Arguments:
        machine: the machine (elastic or rigid table).
        rails: the error profiles of rail 1 and rail 2.
        positions: table positions ``x`` (m).
        initial: Newton's starting point per position, in the generalized DOF (µm, µrad;
            ``(n_pos, 30)`` elastic, ``(n_pos, 6)`` rigid); default zero.
        tol: stop when the largest Newton step is below ``tol`` µm / µrad.
        max_steps: Newton step limit.
        throw: raise (``eqx.error_if``, also under ``jit``) when any position fails, instead
            of only flagging it in ``result``.

    Returns:
        :class:`MachineState`; positions that did not converge are flagged in ``result``
        (``optx.RESULTS.nonlinear_max_steps_reached``, or ``nonfinite`` for inf/NaN).
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

    if initial is None:
        initial = jnp.zeros((positions.shape[0], d))
    if initial.shape != (positions.shape[0], d):
        raise ValueError(f"initial must have shape (n_pos, {d}), got {initial.shape}")

    def one(x, y0):
        return _solve_one(machine, x, rails, Phi, K, f, y0, tol, max_steps)

    u, forces, result, steps = jax.vmap(one)(positions, initial)
    if throw:
        u = _error_if_failed(u, result, "equilibrium")
    return MachineState(positions, u, forces, result, steps)


def _error_if_failed(x, result, what: str):
    """``x``, raising (``eqx.error_if``) if any entry of the batched ``result`` failed."""
    failed = result != optx.RESULTS.successful
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
