r"""Joint kinematic errors of the X axis at points on the table (ISO 230-1).

At a control point P the six errors at table position ``x`` are the motion of the material point
P at ``x`` minus its motion at the reference position ``x_ref`` (ISO 230-1):

.. math::  [E_{XX}, E_{YX}, E_{ZX}, E_{AX}, E_{BX}, E_{CX}](x) = m_P(x) - m_P(x_{ref}),

``m_P = (u_x, u_y, u_z, θ_x, θ_y, θ_z)`` of the top-surface point (translation including the
rotation × offset from the plate mid-surface). EXX positioning, EYX horizontal and EZX vertical
straightness (m inside, µm at the edges); EAX roll, EBX pitch, ECX yaw (rad inside, µrad = µm/m
at the edges), each positive along/about +X, +Y, +Z (right-handed).
"""

import operator

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.checks import concrete, length
from .._core.result import RESULTS
from .._core.rigid import transfer
from .._core.types import Array, Float
from ..guideway.rails import AbstractRailProfile
from .equilibrium import Machine, _error_if_failed, equilibrium_traced, point_motion
from .errors import ERROR_MEANINGS as ERROR_MEANINGS  # names, meanings, units: one table
from .errors import ERROR_NAMES as ERROR_NAMES
from .errors import error_columns, to_user

#: Plausible table positions and reference positions (m): half the longest stroke a machine
#: file allows (50 m), either side of x = 0. Concrete positions outside are refused (with a hint
#: when they look like mm); the machine's own stroke is the caller's to respect.
POSITION_RANGE = (-25.0, 25.0)


class JointErrors(eqx.Module):
    """Joint kinematic errors at the control points over a sweep of table positions.

    Attributes:
        positions: table positions ``x`` (m). x_ref: reference position (m).
        point_names: control-point names. points_xy: their (x, y) on the table (m).
        errors: ``(n_pos, n_points, 6)``: EXX, EYX, EZX (m), EAX, EBX, ECX (rad).
        result: result code (:class:`~diffguide._core.result.RESULTS`) per position (the
            reference position's failure is reported at every position).
        interface: the table's interface DOF at each position (m, rad).
        interface_ref: the same at the reference position.
    """

    positions: Float[Array, " n_pos"]
    x_ref: Float[Array, ""]
    point_names: tuple[str, ...] = eqx.field(static=True)
    points_xy: Float[Array, "p 2"]
    errors: Float[Array, "n_pos p 6"]
    result: RESULTS
    interface: Float[Array, "n_pos m"]
    interface_ref: Float[Array, " m"]

    @property
    def converged(self) -> jax.Array:
        return self.result == RESULTS.successful

    def user_units(self) -> np.ndarray:
        """``errors`` in µm and µrad, as a NumPy array ``(n_pos, n_points, 6)``
        (:func:`diffguide.machine.errors.to_user`)."""
        return to_user(self.errors)

    def to_dataframe(self):
        """A ``pandas.DataFrame`` in user units, one row per position and point, as
        ``diffguide simulate`` writes: ``position_mm, point, x_mm, y_mm, EXX_um, EYX_um, EZX_um,
        EAX_urad, EBX_urad, ECX_urad, converged`` (needs the ``[pandas]`` extra)."""
        from .._core.frames import require_pandas

        pd = require_pandas()
        errs = self.user_units()
        n_pos, n_pt = errs.shape[:2]
        xy = np.asarray(self.points_xy) * 1e3
        data = {
            "position_mm": np.repeat(np.asarray(self.positions) * 1e3, n_pt),
            "point": np.tile(np.asarray(self.point_names, dtype=object), n_pos),
            "x_mm": np.tile(xy[:, 0], n_pos),
            "y_mm": np.tile(xy[:, 1], n_pos),
        }
        for k, column in enumerate(error_columns()):
            data[column] = errs[:, :, k].reshape(-1)
        data["converged"] = np.repeat(np.broadcast_to(np.asarray(self.converged), (n_pos,)), n_pt)
        return pd.DataFrame(data)

    def error(self, name: str, point: str) -> jax.Array:
        """One error curve (SI) by ISO name (``"EBX"``) and point name (``"P1"``)."""
        if name not in ERROR_NAMES:
            raise ValueError(f"error name must be one of {ERROR_NAMES}, got {name!r}")
        if point not in self.point_names:
            raise ValueError(f"point must be one of {self.point_names}, got {point!r}")
        return self.errors[:, self.point_names.index(point), ERROR_NAMES.index(name)]


def _check_sweep_inputs(rails, positions, x_ref) -> None:
    """Refuse a single rail and positions / ``x_ref`` of the wrong rank with a clear message.

    Only types and shapes are looked at (static under ``jit``/``vmap``/``grad``): the checks run
    once, when the function is traced, and cost nothing in the compiled program."""
    if isinstance(rails, AbstractRailProfile):
        raise TypeError(
            "rails must be a pair (rail 1, rail 2) of rail profiles, got a single "
            f"{type(rails).__name__}; e.g. (rail, diffguide.StraightRail())"
        )
    try:
        n_rails = len(rails)
    except TypeError:
        raise TypeError(
            f"rails must be a pair (rail 1, rail 2) of rail profiles, got {type(rails).__name__}"
        ) from None
    if n_rails != 2:
        raise ValueError(f"rails must be a pair (rail 1, rail 2), got {n_rails} profiles")
    for k, rail in enumerate(rails):
        if not callable(rail):
            raise TypeError(
                f"rails[{k}] must be a rail profile (callable s -> (e_y, e_z), e.g. "
                f"diffguide.StraightRail()), got {type(rail).__name__}"
            )
    if np.ndim(positions) > 1:
        raise ValueError(
            "positions must be a scalar or a 1-D array of table positions (m), "
            f"got shape {np.shape(positions)}"
        )
    if np.ndim(x_ref) != 0:
        raise ValueError(f"x_ref must be a scalar (m), got shape {np.shape(x_ref)}")


def joint_errors_traced(
    machine: Machine,
    rails: tuple[AbstractRailProfile, AbstractRailProfile],
    positions: Float[Array, " n_pos"],
    x_ref: float | Float[Array, ""] = 0.0,
    *,
    throw: bool = False,
    condensed: bool = True,
) -> JointErrors:
    """Equilibrium at every position and at ``x_ref`` (one vmapped solve), then the errors.

    Arguments:
        machine: the machine (``machine.with_rigid_table()`` for the rigid-table comparison).
        rails: error profiles of rail 1 and rail 2, a pair (a single profile is refused:
            ``TypeError``).
        positions: table positions (m), a scalar or 1-D (2-D is refused: ``ValueError``);
            :func:`joint_errors` refuses concrete ones outside :data:`POSITION_RANGE`.
        x_ref: reference position (m), a scalar (the same range).
        throw: raise (``eqx.error_if``) when any position (or the reference) fails, instead of
            only reporting it in ``result``.
        condensed: the equilibrium's Newton solve on the contact DOF (``True``: the faster
            run) or on all 30 interface DOF (``False``: the smaller program, for a traced
            function compiled to run a few times); the same result (:func:`equilibrium`).
    """
    _check_sweep_inputs(rails, positions, x_ref)
    positions = jnp.atleast_1d(jnp.asarray(positions, dtype=float))
    x_ref = jnp.asarray(x_ref, dtype=float)
    state = equilibrium_traced(
        machine, rails, jnp.concatenate([positions, x_ref[None]]), condensed=condensed
    )
    motion = point_motion(machine, state.interface)
    errors = motion[:-1] - motion[-1]
    # a failed reference position invalidates every error: report its code everywhere
    ref_ok = (state.result == RESULTS.successful)[-1]
    result = jax.tree_util.tree_map(lambda v: jnp.where(ref_ok, v[:-1], v[-1]), state.result)
    if throw:
        errors = _error_if_failed(errors, result, "joint_errors")
    return JointErrors(
        positions=positions,
        x_ref=x_ref,
        point_names=machine.point_names,
        points_xy=machine.points_xy,
        errors=errors,
        result=result,
        interface=state.interface[:-1],
        interface_ref=state.interface[-1],
    )


_joint_errors_jit = eqx.filter_jit(joint_errors_traced)


def joint_errors(
    machine: Machine,
    rails: tuple[AbstractRailProfile, AbstractRailProfile],
    positions: Float[Array, " n_pos"],
    x_ref: float | Float[Array, ""] = 0.0,
    *,
    throw: bool = False,
    condensed: bool = True,
) -> JointErrors:
    """The joint errors at the machine's points over ``positions``: :func:`joint_errors_traced`
    compiled (the function to call), after refusing concrete ``positions`` and ``x_ref``
    outside :data:`POSITION_RANGE` (m).

    Arguments and returns: as :func:`joint_errors_traced`. Inside another traced function call
    ``joint_errors_traced`` itself: a nested ``jit`` is traced again by every transformation
    around it (``jvp``, ``vmap``), which makes a linearisation slower to trace.
    """
    length("positions", positions, *POSITION_RANGE)  # traced values pass unchecked
    length("x_ref", x_ref, *POSITION_RANGE)
    return _joint_errors_jit(machine, rails, positions, x_ref, throw=throw, condensed=condensed)


def error_field(machine: Machine, errors: JointErrors, index: int):
    """The joint errors over the whole table top at sweep position ``errors.positions[index]``.

    The motion of every mesh node's top-surface point (translation including ``θ × (t/2)e_z``
    from the mid-surface; rotation of the surface) at that position, minus the same at the
    reference position — the error field a plot of the table shows.

    Arguments:
        machine: the machine ``errors`` was computed with.
        errors: a sweep (:func:`joint_errors`).
        index: which position of the sweep, an integer in ``-n_pos .. n_pos − 1`` (negative
            counts from the end, as in Python); anything else raises ``IndexError`` (a float:
            ``TypeError``). A traced index is not checked (JAX would clamp it).

    Returns:
        ``(xy, field)``: node positions on the table (m), ``(n_nodes, 2)``, and their errors
        ``(n_nodes, 6)`` (m, rad), ordered as :data:`ERROR_NAMES`.
    """
    from .equilibrium import node_motion

    if concrete(index):
        n_pos = int(np.shape(errors.interface)[0])
        try:
            k = operator.index(index)
        except TypeError:
            raise TypeError(
                f"index must be an integer (a position of the sweep), got {index!r}"
            ) from None
        if not -n_pos <= k < n_pos:
            raise IndexError(
                f"index must be in -{n_pos} .. {n_pos - 1} (the sweep has {n_pos} positions), "
                f"got {k}"
            )
        index = k
    if np.shape(machine.table.nodes)[0] == 0:
        raise ValueError(
            "error_field: this table has no mesh nodes (a table imported as a reduced matrix "
            "knows only its retained nodes); use the control points (joint_errors), or retain "
            "more nodes as control points")
    half_t = -machine.table.ref_points[0, 2]  # the carriage patches sit on the underside
    offset = jnp.array([0.0, 0.0, 1.0]) * half_t

    def top(u):
        return transfer(node_motion(machine, u), offset)

    field = top(errors.interface[index]) - top(errors.interface_ref)
    return machine.table.nodes[:, :2], field
