r"""Volumetric errors of the cross table: the table relative to the bed at any ``(X, Y)``.

Homogeneous transformations (ISO 230-1's small-angle form). A small motion ``ε = (δ, θ)`` of a
frame (translation m, rotation rad) is

.. math::

    E(ε) = \begin{bmatrix} 1 & −θ_z & θ_y & δ_x\\ θ_z & 1 & −θ_x & δ_y\\
           −θ_y & θ_x & 1 & δ_z\\ 0&0&0&1 \end{bmatrix}
         = \begin{bmatrix} I + [θ]_× & δ\\ 0 & 1\end{bmatrix},

and the frame of control point P on the table top, in the bed frame, is the chain

.. math::

    T_P(X, Y) = \underbrace{\mathrm{Tr}(o_S(Y))\,E(ε_S)}_{T_Y(Y)}\;
                \underbrace{\mathrm{Tr}(r_T(X) + P)\,E(m_P)}_{T_X(X)},

``o_S = (0, Y, −dz)`` the saddle centre, ``ε_S`` its motion (:class:`CrossState.saddle`),
``r_T = (X, 0, dz)`` the table centre from the saddle centre, ``P = (x_P, y_P, t/2)`` the
point on the table top and ``m_P`` its motion relative to the saddle (the one-axis model's,
elastic deformation included: :func:`~diffguide.machine.equilibrium.point_motion`). The nominal
frame is the pure translation ``T₀_P = Tr(o_S + r_T + P)``. For a rigid table ``m_P`` is the
table's rigid motion carried to P, and ``T_P = T_Y(Y) · T_X(X) · Tr(P)`` with the table's pose
``T_X = Tr(r_T) E(ε_T)``: the chain of the two axes, ``T = T_Y · T_X`` (ISO 230-1 Annex;
Okafor & Ertekin 2000).

Outputs, both relative to the reference position ``(X_ref, Y_ref)`` (where an instrument is
zeroed), as the one-axis joint errors are:

- the six errors of the table at P relative to the bed: ``e_P = ε(T₀_P⁻¹ T_P)`` minus the same
  at the reference, with ``ε(D) = (D_{:3,3}, vee(½(D_{:3,:3} − D_{:3,:3}ᵀ)))`` (EX, EY, EZ in
  m; EA, EB, EC in rad, about +X, +Y, +Z);
- the volumetric error of the workpiece point at height ``z`` above P: ``v = T_P·p − T₀_P·p``
  with ``p = (0, 0, z, 1)`` in P's frame, minus the same at the reference.
"""

import operator

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.checks import length
from .._core.result import RESULTS
from .._core.rigid import skew, transfer
from .._core.types import Array, Float
from .cross import CrossMachine
from .cross_equilibrium import Rails, cross_equilibrium_traced
from .equilibrium import _error_if_failed, node_motion, point_motion
from .kinematics import POSITION_RANGE, _check_sweep_inputs

#: Names of the six errors of the table relative to the bed (machine axes X, Y, Z; rotations
#: A, B, C about them), the order of the last axis of :attr:`CrossErrors.errors`.
TABLE_ERROR_NAMES = ("EX", "EY", "EZ", "EA", "EB", "EC")


def small_motion_htm(motion: Float[Array, "... 6"]) -> Float[Array, "... 4 4"]:
    """``E(ε)``: the 4 × 4 homogeneous transformation of a small motion ``(δ, θ)`` (m, rad),
    ISO 230-1's small-angle form (module docstring)."""
    top = jnp.concatenate(
        [jnp.eye(3) + skew(motion[..., 3:]), motion[..., :3, None]], axis=-1
    )
    bottom = jnp.broadcast_to(jnp.array([0.0, 0.0, 0.0, 1.0]), top.shape[:-2] + (1, 4))
    return jnp.concatenate([top, bottom], axis=-2)


def translation_htm(t: Float[Array, "... 3"]) -> Float[Array, "... 4 4"]:
    """``Tr(t)``: the pure translation by ``t`` (m)."""
    return small_motion_htm(jnp.concatenate([t, jnp.zeros_like(t)], axis=-1))


def htm_errors(D: Float[Array, "... 4 4"]) -> Float[Array, "... 6"]:
    """``ε(D)``: translation and small rotation ``vee(½(A − Aᵀ))`` of a near-identity
    transformation ``D`` (m, rad)."""
    A = D[..., :3, :3]
    rot = 0.5 * jnp.stack(
        [A[..., 2, 1] - A[..., 1, 2], A[..., 0, 2] - A[..., 2, 0], A[..., 1, 0] - A[..., 0, 1]],
        axis=-1,
    )
    return jnp.concatenate([D[..., :3, 3], rot], axis=-1)


class CrossErrors(eqx.Module):
    """The table relative to the bed at its control points over a grid of ``(X, Y)``.

    Attributes:
        X, Y: table and saddle positions (m). X_ref, Y_ref: the reference position (m).
        point_names: the table's control points. points: their positions on the table top in
            the table frame, ``(p, 3)`` (m).
        poses: ``T_P(X, Y)``, ``(n_x, n_y, p, 4, 4)`` (module docstring; m).
        nominal: ``T₀_P(X, Y)``, the same shape. poses_ref, nominal_ref: the same at the
            reference, ``(p, 4, 4)``.
        errors: six errors of the table relative to the bed at each point, relative to the
            reference, ``(n_x, n_y, p, 6)``, :data:`TABLE_ERROR_NAMES` (m, rad).
        result: result code per ``(X, Y)`` (a failed reference is reported everywhere).
        table_interface: the table's interface DOF relative to the saddle at each ``X``
            (m, rad). saddle: the saddle's motion at each ``(X, Y)`` (machine frame; m, rad).
        table_interface_ref, saddle_ref: the same at the reference.
    """

    X: Float[Array, " n_x"]
    Y: Float[Array, " n_y"]
    X_ref: Float[Array, ""]
    Y_ref: Float[Array, ""]
    point_names: tuple[str, ...] = eqx.field(static=True)
    points: Float[Array, "p 3"]
    poses: Float[Array, "n_x n_y p 4 4"]
    nominal: Float[Array, "n_x n_y p 4 4"]
    poses_ref: Float[Array, "p 4 4"]
    nominal_ref: Float[Array, "p 4 4"]
    errors: Float[Array, "n_x n_y p 6"]
    result: RESULTS
    table_interface: Float[Array, "n_x m"]
    table_interface_ref: Float[Array, " m"]
    saddle: Float[Array, "n_x n_y 6"]
    saddle_ref: Float[Array, " 6"]

    @property
    def converged(self) -> jax.Array:
        return self.result == RESULTS.successful

    def volumetric(self, z: float | Float[Array, ""] = 0.0) -> Float[Array, "n_x n_y p 3"]:
        """Position error of the workpiece point at height ``z`` (m) above each control point,
        relative to the reference: ``(T_P − T₀_P)·p`` minus the same at the reference (m)."""
        p = jnp.stack([0.0, 0.0, jnp.asarray(z, dtype=float), 1.0])
        v = (self.poses - self.nominal) @ p
        return (v - (self.poses_ref - self.nominal_ref) @ p)[..., :3]


def _frames(cross: CrossMachine, m, saddle, X, Y, points):
    """``(T_P, T₀_P, T₀_P⁻¹ T_P)``, ``(n_x, n_y, p, 4, 4)`` each, for the points' motions
    relative to the saddle ``m`` ``(n_x, p, 6)``, the saddle's ``(n_x, n_y, 6)`` and the points
    ``(p, 3)`` (table frame)."""
    zeros_x, zeros_y = jnp.zeros_like(X), jnp.zeros_like(Y)
    o_s = jnp.stack([zeros_y, Y, zeros_y - cross.dz], axis=-1)  # (n_y, 3)
    r_t = jnp.stack([X, zeros_x, zeros_x + cross.dz], axis=-1)  # (n_x, 3)
    T_y = translation_htm(o_s)[None] @ small_motion_htm(saddle)  # (n_x, n_y, 4, 4)
    T_x = translation_htm(r_t[:, None] + points) @ small_motion_htm(m)  # (n_x, p, 4, 4)
    poses = T_y[:, :, None] @ T_x[:, None]
    n = o_s[None, :, None] + r_t[:, None, None] + points
    return poses, translation_htm(n), translation_htm(-n) @ poses


def cross_errors_traced(
    cross: CrossMachine,
    rails_x: Rails,
    rails_y: Rails,
    X: Float[Array, " n_x"],
    Y: Float[Array, " n_y"],
    X_ref: float | Float[Array, ""] = 0.0,
    Y_ref: float | Float[Array, ""] = 0.0,
    *,
    throw: bool = False,
) -> CrossErrors:
    """The table's errors relative to the bed at its control points over the grid ``X × Y``
    (m), relative to ``(X_ref, Y_ref)`` (m): one equilibrium over the grid and the reference
    (:func:`~diffguide.machine.cross_equilibrium.cross_equilibrium_traced`), then the chain of
    the module docstring. Rails as there (each a pair of profiles); ``throw``: raise
    (``eqx.error_if``) when any position fails, instead of only reporting it in ``result``."""
    _check_sweep_inputs(rails_x, X, X_ref)
    _check_sweep_inputs(rails_y, Y, Y_ref)
    X = jnp.atleast_1d(jnp.asarray(X, dtype=float))
    Y = jnp.atleast_1d(jnp.asarray(Y, dtype=float))
    X_ref = jnp.asarray(X_ref, dtype=float)
    Y_ref = jnp.asarray(Y_ref, dtype=float)
    Xa, Ya = jnp.concatenate([X, X_ref[None]]), jnp.concatenate([Y, Y_ref[None]])
    state = cross_equilibrium_traced(cross, rails_x, rails_y, Xa, Ya)
    xy = jnp.asarray(cross.x_axis.points_xy)
    points = jnp.concatenate([xy, jnp.full((xy.shape[0], 1), 1.0) * cross.table_top], axis=1)
    m = point_motion(cross.x_axis, state.table.interface)  # (n_x, p, 6), relative to the saddle
    poses, nominal, local = _frames(cross, m, state.saddle, Xa, Ya, points)
    six = htm_errors(local)
    ok_ref = (state.result == RESULTS.successful)[-1, -1]
    result = jax.tree_util.tree_map(
        lambda v: jnp.where(ok_ref, v[:-1, :-1], v[-1, -1]), state.result
    )
    errors = six[:-1, :-1] - six[-1, -1]
    if throw:
        errors = _error_if_failed(errors, result, "cross_errors")
    return CrossErrors(
        X=X, Y=Y, X_ref=X_ref, Y_ref=Y_ref,
        point_names=cross.x_axis.point_names,
        points=points,
        poses=poses[:-1, :-1], nominal=nominal[:-1, :-1],
        poses_ref=poses[-1, -1], nominal_ref=nominal[-1, -1],
        errors=errors,
        result=result,
        table_interface=state.table.interface[:-1],
        table_interface_ref=state.table.interface[-1],
        saddle=state.saddle[:-1, :-1],
        saddle_ref=state.saddle[-1, -1],
    )


_cross_errors_jit = eqx.filter_jit(cross_errors_traced)


def cross_errors(
    cross: CrossMachine,
    rails_x: Rails,
    rails_y: Rails,
    X: Float[Array, " n_x"],
    Y: Float[Array, " n_y"],
    X_ref: float | Float[Array, ""] = 0.0,
    Y_ref: float | Float[Array, ""] = 0.0,
    *,
    throw: bool = False,
) -> CrossErrors:
    """:func:`cross_errors_traced`, compiled (the function to call), after refusing concrete
    positions outside :data:`~diffguide.machine.kinematics.POSITION_RANGE` (m). Inside another
    traced function call ``cross_errors_traced`` itself."""
    for name, value in (("X", X), ("Y", Y), ("X_ref", X_ref), ("Y_ref", Y_ref)):
        length(name, value, *POSITION_RANGE)  # traced values pass unchecked
    return _cross_errors_jit(cross, rails_x, rails_y, X, Y, X_ref, Y_ref, throw=throw)


def _index(name: str, k, n: int) -> int:
    """``k`` as an index into ``n`` positions (negative from the end), else ``IndexError``."""
    try:
        k = operator.index(k)
    except TypeError:
        raise TypeError(f"{name} must be an integer, got {k!r}") from None
    if not -n <= k < n:
        raise IndexError(f"{name} must be in -{n} .. {n - 1}, got {k}")
    return k


def cross_error_field(cross: CrossMachine, errors: CrossErrors, i: int, j: int):
    """The table's six errors relative to the bed over the whole table top at grid position
    ``(errors.X[i], errors.Y[j])``: the frame chain of the module docstring at every mesh
    node's top-surface point, minus the same at the reference.

    Arguments:
        cross: the cross table ``errors`` was computed with.
        errors: a grid (:func:`cross_errors`).
        i, j: the X and Y indices (integers; negative count from the end).

    Returns:
        ``(xy, field)``: node positions on the table (m), ``(n_nodes, 2)``, and their errors
        ``(n_nodes, 6)`` (m, rad), ordered as :data:`TABLE_ERROR_NAMES`.
    """
    i = _index("i", i, int(np.shape(errors.X)[0]))
    j = _index("j", j, int(np.shape(errors.Y)[0]))
    nodes = jnp.asarray(cross.x_axis.table.nodes)
    if nodes.shape[0] == 0:
        raise ValueError("cross_error_field: this table has no mesh nodes (an imported table "
                         "knows only its retained nodes); use the control points")
    top = jnp.stack([jnp.zeros(()), jnp.zeros(()), jnp.asarray(cross.table_top) + 0.0])
    points = jnp.concatenate([nodes[:, :2], jnp.zeros_like(nodes[:, :1]) + top[2]], axis=1)

    def six(u, q, x, y):
        m = transfer(node_motion(cross.x_axis, u), top)[None]  # the top surface, (1, n, 6)
        return htm_errors(_frames(cross, m, q[None, None], x[None], y[None], points)[2])[0, 0]

    field = six(errors.table_interface[i], errors.saddle[i, j], errors.X[i], errors.Y[j]) - six(
        errors.table_interface_ref, errors.saddle_ref, errors.X_ref, errors.Y_ref)
    return nodes[:, :2], field
