r"""Equilibrium of the cross table at every machine position ``(X, Y)`` of a grid, one program.

Unknowns: the table's interface DOF ``u`` relative to the saddle (30 elastic, 6 rigid; the
one-axis model's, :mod:`~diffguide.machine.equilibrium`) and the rigid saddle's motion ``q``
relative to the bed (6, at its centre, Y axis frame). Total potential, with ``Π_X`` the
one-axis potential of the table on the saddle's X rails (strain energy, its weight, the X
contacts, the X screw: all act between table and saddle) and ``Π_Y`` that of the saddle on the
Y rails (Y contacts, Y screw, the saddle's weight):

.. math::

    Π(u, q; X, Y) = Π_X(u; X) + Π_Y(q; Y) − w(X)ᵀ q,

``w(X)`` the table's weight carried to the saddle centre
(:meth:`~diffguide.machine.cross.CrossMachine.table_load_on_saddle`): the table's weight does
work on the saddle's motion too, because the table rides on it (its potential ``−fᵀ(u +
Φ_{T←S} q)`` with the table's absolute motion = relative + the saddle's, carried to the table).

With a rigid saddle the Hessian is block-diagonal (``w`` is constant in ``u`` and ``q``): the
table's equilibrium does not depend on ``Y`` and is solved once per ``X``
(:func:`~diffguide.machine.equilibrium.equilibrium_traced`), the saddle's once per ``(X, Y)``
(Newton with line search, 6 DOF, :func:`~diffguide._core.newton.solve_equilibrium`), all in one
compiled, vmapped call. Both are differentiated implicitly. With an elastic saddle (next step)
the X rails' shape follows ``q``'s deformation part and the two blocks couple.
"""

import equinox as eqx
import jax
import jax.numpy as jnp

from .._core.newton import solve_equilibrium
from .._core.precision import require_x64
from .._core.result import RESULTS
from .._core.types import Array, Float, Int
from ..guideway.rails import AbstractRailProfile
from .cross import CrossMachine, to_machine_frame
from .equilibrium import (
    DOF_SCALE,
    MachineState,
    _contacts,
    _full_grad_hess,
    _full_potential,
    equilibrium_traced,
)

Rails = tuple[AbstractRailProfile, AbstractRailProfile]


class CrossState(eqx.Module):
    """Equilibrium of the cross table over a grid of positions.

    Attributes:
        X: table positions (m), ``(n_x,)``. Y: saddle positions (m), ``(n_y,)``.
        table: the table's equilibrium relative to the saddle at each ``X``
            (:class:`~diffguide.machine.equilibrium.MachineState`; the same at every ``Y``).
        saddle: the saddle's motion at its centre relative to the bed, machine frame,
            ``(n_x, n_y, 6)`` (m, rad).
        saddle_forces: the Y carriages' element forces, ``(n_x, n_y, k, rows, n)`` (N).
        result: result code per ``(X, Y)``: the table's failure at ``X``, else the saddle's.
        steps: the saddle's Newton steps per ``(X, Y)``.
    """

    X: Float[Array, " n_x"]
    Y: Float[Array, " n_y"]
    table: MachineState
    saddle: Float[Array, "n_x n_y 6"]
    saddle_forces: Float[Array, "n_x n_y k rows n"]
    result: RESULTS
    steps: Int[Array, "n_x n_y"]

    @property
    def converged(self) -> jax.Array:
        return self.result == RESULTS.successful


def _saddle_potential(y, args):
    """``Π_Y(q) − wᵀq`` (J) at the scaled saddle DOF ``y`` (µm, µrad)."""
    full, w = args
    return _full_potential(y, full) - w @ y * DOF_SCALE


def _saddle_grad_hess(y, args):
    """Gradient (J/µm) and Hessian (J/µm²) of :func:`_saddle_potential`."""
    full, w = args
    g, H = _full_grad_hess(y, full)
    return g - w * DOF_SCALE, H


def _saddle_one(y_axis, Phi, rails_y, Y, w, tol, max_steps):
    """The saddle at position ``Y`` (m) under the table's load ``w`` (Y axis frame, N, N·m):
    its motion (m, rad; Y axis frame), element forces, result, steps."""
    rail = y_axis.rail_under_carriages(Y, rails_y)
    full = (y_axis, y_axis.table.K, y_axis.table.f, Phi, y_axis.screw_stiffness(Y), rail)
    y, result, steps = solve_equilibrium(
        _saddle_potential, _saddle_grad_hess, jnp.zeros(6), (full, w), tol=tol,
        max_steps=max_steps,
    )
    q = y * DOF_SCALE
    forces = y_axis.carriage.element_forces(_contacts(y_axis, Phi @ q, rail))
    return q, forces, result, steps


def cross_equilibrium_traced(
    cross: CrossMachine,
    rails_x: Rails,
    rails_y: Rails,
    X: Float[Array, " n_x"],
    Y: Float[Array, " n_y"],
    *,
    tol: float = 1e-9,
    max_steps: int = 60,
) -> CrossState:
    """Equilibrium of the cross table at every ``(X, Y)`` of the grid ``X × Y``.

    Arguments:
        cross: the cross table (:func:`~diffguide.machine.cross.build_cross`).
        rails_x: error profiles of X rails 1 and 2 (in the saddle's frame: their straightness
            on the saddle; rail coordinate ``s`` along +X).
        rails_y: error profiles of Y rails 1 and 2 (on the bed; ``s`` along +Y; rail 1 at the
            larger machine X, the Y axis frame's ``y' = −X``).
        X, Y: table and saddle positions (m), 1-D.
        tol, max_steps: Newton's tolerance (µm, µrad) and step limit, both solves.

    Returns:
        :class:`CrossState`; failed positions are flagged in ``result``.
    """
    require_x64("cross_equilibrium")
    X = jnp.atleast_1d(jnp.asarray(X, dtype=float))
    Y = jnp.atleast_1d(jnp.asarray(Y, dtype=float))
    if X.ndim != 1 or Y.ndim != 1:
        raise ValueError(f"X and Y must be 1-D (m), got shapes {X.shape}, {Y.shape}")
    for name, rails in (("rails_x", rails_x), ("rails_y", rails_y)):
        if len(rails) != 2:
            raise ValueError(f"{name} must be a pair (rail 1, rail 2), got {len(rails)}")
    table = equilibrium_traced(cross.x_axis, rails_x, X, tol=tol, max_steps=max_steps)
    y_axis = cross.y_axis
    y_axis = eqx.tree_at(lambda m: m.carriage, y_axis, y_axis.carriage.resolved())
    Phi = y_axis.basis()
    w = jax.vmap(cross.table_load_on_saddle)(X)  # (n_x, 6)

    def at(w_x, y):
        return _saddle_one(y_axis, Phi, rails_y, y, w_x, tol, max_steps)

    q, forces, s_result, steps = jax.vmap(jax.vmap(at, (None, 0)), (0, None))(w, Y)
    t_ok = (table.result == RESULTS.successful)[:, None]
    result = jax.tree_util.tree_map(
        lambda s, t: jnp.where(t_ok, s, jnp.broadcast_to(t[:, None], s.shape)),
        s_result, table.result,
    )
    return CrossState(X, Y, table, to_machine_frame(q), forces, result, steps)


#: :func:`cross_equilibrium_traced`, compiled (the function to call).
cross_equilibrium = eqx.filter_jit(cross_equilibrium_traced)
