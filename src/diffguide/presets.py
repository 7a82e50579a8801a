"""The built-in machines and parts, by name: what the CLI's ``--preset`` and users choose.

Each value is defined once, with the reason it was chosen, in the layer that uses it; this
module only names them (nothing in the library imports it):

- :func:`majda2012`: the vertical machining centre of Majda, Precision Engineering 36 (2012)
  369-378 (:func:`diffguide.machine.majda2012.majda2012_spec`);
- :func:`majda2012_cross`: the same machine as a whole cross table (table, saddle, both
  joints; :func:`diffguide.machine.paper_cross.majda2012_cross_spec`);
- :func:`ball_block_25`, :func:`roller_block_25`: its size-25 ball runner block and a
  catalogue-typical roller block (:mod:`diffguide.guideway.blocks`);
- :func:`cast_iron`, :func:`steel`: table materials (:mod:`diffguide.fe.materials`).

Each returns a fresh typed specification (:class:`~diffguide.machine.spec.MachineSpec`,
:class:`~diffguide.machine.cross_spec.CrossSpec`,
:class:`~diffguide.guideway.carriage.CarriageSpec`, :class:`~diffguide.fe.materials.Material`);
change a value with ``eqx.tree_at`` (array fields, which may then be traced) or
``dataclasses.replace``. SI units throughout.
"""

from .fe.materials import cast_iron as cast_iron
from .fe.materials import steel as steel
from .guideway.blocks import ball_block_25 as ball_block_25
from .guideway.blocks import roller_block_25 as roller_block_25
from .machine.majda2012 import majda2012_spec as majda2012
from .machine.paper_cross import majda2012_cross_spec as majda2012_cross

__all__ = ["majda2012", "majda2012_cross", "ball_block_25", "roller_block_25", "cast_iron", "steel"]
