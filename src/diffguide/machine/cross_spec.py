r"""Typed specification of a cross table (XYOZ machine), SI units: the table on its X rails,
the X rails on a saddle, the saddle on its Y rails on the bed.

Each joint is a one-axis machine (:class:`~diffguide.machine.spec.MachineSpec`) in its own frame:

- ``x``: the table on the X guideway, in the machine frame (X along the X rails, Y across,
  Z up; origin at the table centre on its mid-surface, at the reference position). Its "bed" is
  the saddle's top: the X rails are bolted to the saddle and move with it.
- ``y``: the saddle on the Y guideway, in the Y axis's own frame ``(x', y', z')`` with ``x'``
  along the Y rails: ``x' = Y``, ``y' = −X``, ``z' = Z`` (a right-handed turn of +90° about Z,
  :data:`Y_AXIS_FRAME`); origin at the saddle centre on its mid-surface at the reference
  position. Its ``table`` is the saddle plate (only its size, thickness and density matter while
  the saddle is rigid, :mod:`~diffguide.machine.cross`), its ``guideway`` the Y rails and
  carriages under the saddle, its ``screw`` the Y screw, its ``points`` points on the saddle.
- ``x_guideway_height``: the X guideway's assembly height (the saddle's top face to the
  underside of the table: rail base to carriage face, m). The table's mid-surface is
  ``dz = t_table/2 + x_guideway_height + t_saddle/2`` above the saddle's.

The X rails lie on the saddle at the X axis's ``guideway.rail_y``; the nominal table centre is
above the saddle centre at X = 0 (both centres at the same Y).
"""

import equinox as eqx
import numpy as np

from .._core.checks import length
from .spec import MachineSpec

#: Columns: the Y axis frame's unit vectors ``x'``, ``y'``, ``z'`` in machine coordinates
#: (``v_machine = Y_AXIS_FRAME @ v_local``, for translations and small rotations alike).
Y_AXIS_FRAME = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
#: Plausible guideway assembly heights (m): 5 mm .. 0.5 m.
GUIDEWAY_HEIGHT_RANGE = (5e-3, 0.5)


class CrossSpec(eqx.Module):
    """A cross table: the X joint (table on the saddle) over the Y joint (saddle on the bed).

    Arguments:
        x: the table on its X rails (machine frame; module docstring).
        y: the saddle on its Y rails, in the Y axis frame ``x' = Y, y' = −X`` (module
            docstring); its ``stroke`` is the Y stroke.
        x_guideway_height: the X guideway's assembly height, saddle top to table underside (m,
            within :data:`GUIDEWAY_HEIGHT_RANGE`).

    The X rails (at machine Y = ``x.guideway.rail_y``) must lie on the saddle, and the saddle
    must carry them over the X stroke: ``|rail_y| <= saddle length / 2`` (the saddle's length
    is along Y).
    """

    x: MachineSpec
    y: MachineSpec
    x_guideway_height: float = eqx.field(static=True, default=0.036)

    def __check_init__(self):
        length("x_guideway_height", self.x_guideway_height, *GUIDEWAY_HEIGHT_RANGE)
        half = self.y.table.length / 2
        for ry in self.x.guideway.rail_y:
            if abs(ry) > half + 1e-12:
                raise ValueError(
                    f"x.guideway.rail_y: an X rail at Y = {ry} m is off the saddle (its length "
                    f"along Y is {self.y.table.length} m)"
                )

    @property
    def strokes(self) -> tuple[float, float]:
        """The X and Y strokes (m)."""
        return (self.x.stroke, self.y.stroke)
