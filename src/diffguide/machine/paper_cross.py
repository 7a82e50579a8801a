"""The source paper's machine as a whole cross table (preset ``majda2012-cross``), as data.

Majda, Precision Engineering 36 (2012) 369-378: a vertical machining centre, XYOZ (table X on a
saddle Y on the bed; the tool Z on a column, taken as rigid), strokes X/Y/Z 700/460/500 mm,
size-25 guideways. The paper models only the X joint and gives no saddle, Y guideway or stack
heights; every value below is chosen here, with its reason. The X joint is the ``majda2012``
table (:func:`~diffguide.machine.paper.majda2012_spec`) with size-25 *roller* blocks on both
joints (the cross-table issue's choice; the one-axis preset keeps the paper's ball blocks). The
Z stroke (500 mm) does not enter: the column is rigid. SI units (m, Pa, N).
"""

import dataclasses

from ..fe.materials import cast_iron
from ..fe.table import TableSpec
from ..guideway.blocks import roller_block_25
from .cross_spec import CrossSpec
from .paper import majda2012_spec
from .spec import GuidewaySpec, MachineSpec, ScrewSpec

#: Footprint of a size-25 roller block bolted to its body (m, along, across the rail): the
#: ~100 mm steel body of :func:`~diffguide.guideway.blocks.roller_block_25` (88 mm loaded zone),
#: 48 mm wide as the ball block.
ROLLER_FOOTPRINT = (0.100, 0.048)


def majda2012_cross_spec() -> CrossSpec:
    """The ``majda2012-cross`` machine as a specification (SI), every value with its reason
    (module docstring and the comments). A fresh object on every call."""
    x = majda2012_spec()
    x = dataclasses.replace(
        x,
        carriage=roller_block_25(),
        guideway=dataclasses.replace(x.guideway, footprint=ROLLER_FOOTPRINT),
    )
    saddle = MachineSpec(
        # The saddle in the Y axis frame (x' = Y, y' = -X): 560 mm along Y, 1120 mm along X.
        table=TableSpec(
            # Along Y: the Y carriages 400 mm apart plus their 100 mm bodies, 30 mm margin each
            # side; it carries the X rails (340 mm apart) with room to spare.
            length=0.56,
            # Along X: the X rails must be supported over the X stroke: the table's carriages
            # span 320 mm + a 100 mm body, moved +-350 mm: 1120 mm.
            width=1.12,
            # Equivalent solid-plate thickness 80 mm: 360 kg of cast iron, the mass range of a
            # ribbed saddle under a 180 kg table of this class (about twice the table). Only
            # the mass matters while the saddle is rigid.
            thickness=0.08,
            material=cast_iron(),
            # A coarse mesh: the rigid saddle uses only the plate's load and its interfaces.
            nx=4,
            ny=8,
        ),
        guideway=GuidewaySpec(
            # Y rails 600 mm apart (in X): a saddle's base is wider than the table's rails
            # (340 mm) to carry the overhanging table; 260 mm inside each saddle edge.
            rail_y=(-0.300, 0.300),
            # Y carriages 400 mm apart along each Y rail, symmetric about the saddle centre.
            carriage_x=(-0.200, 0.200),
            footprint=ROLLER_FOOTPRINT,
        ),
        carriage=roller_block_25(),
        screw=ScrewSpec(
            # A 32 mm core as the X screw (the same drive size).
            core_diameter=0.032,
            E=210e9,
            # Nut under the saddle centre; the fixed bearing 350 mm behind it at Y = 0, so the
            # free length is 0.35 m + Y (0.12 ... 0.58 m over the 460 mm stroke).
            free_length_at_ref=0.35,
            nut_xy=(0.0, 0.0),
            nut_footprint=(0.05, 0.05),
        ),
        # A point on the saddle's top at its centre (the saddle's own motion is reported there).
        points={"S0": (0.0, 0.0)},
        ribs=(),
        gravity=x.gravity,
        # The paper's Y stroke, symmetric about the reference position.
        stroke=0.46,
    )
    # Saddle top to table underside: a size-25 rail and block assembly, 36 mm (the block's
    # height over its rail, as in roller_block_25's row positions).
    return CrossSpec(x=x, y=saddle, x_guideway_height=0.036)
