r"""The stacked cross table: the table's joint (X) on a saddle, the saddle's joint (Y) on the bed.

Built from a :class:`~diffguide.machine.cross_spec.CrossSpec`: two one-axis machines
(:class:`~diffguide.machine.equilibrium.Machine`), each built as the one-axis model builds it
(:func:`~diffguide.machine.build.build_machine`):

- ``x_axis``: the table (elastic, or rigid with ``with_rigid_table``) on its four X carriages,
  the X rails, the X screw. Its rails are the saddle's: its interface DOF are the table's motion
  *relative to the saddle*.
- ``y_axis``: the saddle on its four Y carriages, the Y rails, the Y screw, in the Y axis frame
  (:data:`~diffguide.machine.cross_spec.Y_AXIS_FRAME`). **The saddle is rigid** in this version
  (``y_axis.rigid``): its six DOF are its motion relative to the bed, at its centre.

Rigid saddle, what it implies (stated, not hidden): the X rails keep their own straightness in
the saddle frame and move rigidly with the saddle; they do not yet follow the saddle's elastic
deformation under the carriage forces. The elastic saddle (the saddle condensed along the X
rails, the X rails' shape in space following it, both joints then coupled) is the next step.
Gravity acts along −Z of the bed; in the frame of the tilted saddle (tilts ~10 µrad) its
direction changes by that angle, a relative change of ~1e-5 of the weight, neglected (the
potential of gravity is linear in the small motions, as in the one-axis model).
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._core.types import Array, Float
from .build import build_machine
from .cross_spec import Y_AXIS_FRAME, CrossSpec
from .equilibrium import Machine, rigid_body_map


class CrossMachine(eqx.Module):
    """A cross table ready for :func:`~diffguide.machine.cross_equilibrium.cross_equilibrium`.

    Arguments:
        x_axis: the table on its X rails (the rails fixed on the saddle), machine frame.
        y_axis: the saddle on its Y rails, Y axis frame, rigid (``y_axis.rigid`` is required).
        dz: height of the table's mid-surface above the saddle's (m):
            ``t_table/2 + x_guideway_height + t_saddle/2``.
        table_top: the table's top surface above its mid-surface, ``t_table/2`` (m): where
            the control points are.
        x_stroke, y_stroke: the strokes (m), symmetric about the reference positions.
    """

    x_axis: Machine
    y_axis: Machine
    dz: float | Float[Array, ""]
    table_top: float | Float[Array, ""]
    x_stroke: float | None = eqx.field(static=True, default=None)
    y_stroke: float | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if not self.y_axis.rigid:
            raise ValueError(
                "y_axis: the saddle must be rigid in this version (y_axis.with_rigid_table()); "
                "the elastic saddle is not implemented"
            )

    def with_rigid_table(self, rigid: bool = True) -> "CrossMachine":
        """The same cross table with an infinitely stiff table (or back to the elastic one)."""
        return eqx.tree_at(lambda c: c.x_axis, self, self.x_axis.with_rigid_table(rigid))

    def table_wrench(self) -> Float[Array, " 6"]:
        """The loads on the table (its weight) as one wrench at the table centre, machine frame
        (N, N·m): ``Φᵀ f`` (:func:`~diffguide.machine.equilibrium.rigid_body_map`), exact for
        the condensed loads (condensation keeps the work of a rigid motion)."""
        t = self.x_axis.table
        return rigid_body_map(t.ref_points).T @ t.f

    def table_load_on_saddle(self, X: Float[Array, ""]) -> Float[Array, " 6"]:
        r"""The table's loads carried by the saddle at table position ``X`` (m), as a wrench at
        the saddle centre in the Y axis frame (N, N·m).

        The table's equilibrium passes its whole load through the X carriages and the X screw
        (both act between table and saddle) to the saddle: force ``F`` and moment
        ``M + r × F`` with ``(F, M)`` the :meth:`table_wrench` and ``r = (X, 0, dz)`` the table
        centre from the saddle centre; then turned into the Y axis frame (``Rᵀ``,
        :data:`~diffguide.machine.cross_spec.Y_AXIS_FRAME`).
        """
        w = self.table_wrench()
        r = jnp.stack([jnp.asarray(X, dtype=float), jnp.zeros(()), jnp.asarray(self.dz) + 0.0])
        force, moment = w[:3], w[3:] + jnp.cross(r, w[:3])
        R = jnp.asarray(Y_AXIS_FRAME)
        return jnp.concatenate([R.T @ force, R.T @ moment])


def build_cross(spec: CrossSpec, *, rigid_table: bool = False) -> CrossMachine:
    """Build the cross table of ``spec``: both joints as the one-axis model builds them
    (:func:`~diffguide.machine.build.build_machine`), the saddle rigid (module docstring).

    Arguments:
        spec: a :class:`~diffguide.machine.cross_spec.CrossSpec` (e.g.
            :func:`~diffguide.machine.paper_cross.majda2012_cross_spec`).
        rigid_table: the table infinitely stiff too (the rigid limit).
    """
    if not isinstance(spec, CrossSpec):
        raise TypeError(f"build_cross: spec must be a CrossSpec, got {type(spec).__name__}")
    x_axis = build_machine(spec.x).with_rigid_table(rigid_table)
    y_axis = build_machine(spec.y).with_rigid_table()
    dz = spec.x.table.thickness / 2 + spec.x_guideway_height + spec.y.table.thickness / 2
    return CrossMachine(
        x_axis=x_axis,
        y_axis=y_axis,
        dz=jnp.asarray(dz, dtype=float),  # arrays: another height is the same program
        table_top=jnp.asarray(spec.x.table.thickness / 2, dtype=float),
        x_stroke=float(spec.x.stroke),
        y_stroke=float(spec.y.stroke),
    )


def to_machine_frame(motion: Float[Array, "... 6"]) -> Float[Array, "... 6"]:
    """A small motion ``(u, θ)`` from the Y axis frame to the machine frame (``R u, R θ``)."""
    R = np.asarray(Y_AXIS_FRAME)
    return jnp.concatenate([motion[..., :3] @ R.T, motion[..., 3:] @ R.T], axis=-1)
