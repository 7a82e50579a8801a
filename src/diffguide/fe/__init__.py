"""Elastic table finite elements: MITC4 flat shells, Timoshenko rib beams, condensation.

Layers: :mod:`.materials` → :mod:`.mesh` (structured table + ribs) → :mod:`.shell`,
:mod:`.beam` (pure element functions) → :mod:`.assemble` (vmapped element matrices, scatter,
supports) → :mod:`.condense` (rigid patches, control points) → :mod:`.table` (table spec,
table on its patches).
SI units; node DOF ``(ux, uy, uz, rx, ry, rz)``; X along the rails, Y across, Z up.
"""

from .assemble import (
    DOF_NAMES as DOF_NAMES,
)
from .assemble import (
    ElementArrays as ElementArrays,
)
from .assemble import (
    PlateSection as PlateSection,
)
from .assemble import (
    assemble as assemble,
)
from .assemble import (
    element_arrays as element_arrays,
)
from .assemble import (
    point_load as point_load,
)
from .assemble import (
    solve_fixed as solve_fixed,
)
from .beam import (
    beam_load as beam_load,
)
from .beam import (
    beam_stiffness as beam_stiffness,
)
from .beam import (
    bonded_rib_torsion as bonded_rib_torsion,
)
from .beam import (
    rect_section as rect_section,
)
from .condense import (
    CondensedTable as CondensedTable,
)
from .condense import (
    RigidPatch as RigidPatch,
)
from .condense import (
    condense as condense,
)
from .condense import (
    patch_lines as patch_lines,
)
from .materials import (
    CAST_IRON as CAST_IRON,
)
from .materials import (
    STEEL as STEEL,
)
from .materials import (
    Material as Material,
)
from .materials import (
    material as material,
)
from .mesh import (
    Rib as Rib,
)
from .mesh import (
    TableMesh as TableMesh,
)
from .mesh import (
    grid_lines as grid_lines,
)
from .mesh import (
    table_mesh as table_mesh,
)
from .shell import shell_load as shell_load
from .shell import shell_stiffness as shell_stiffness
from .superelement import (
    ReducedMatrix as ReducedMatrix,
)
from .superelement import (
    RetainedPoint as RetainedPoint,
)
from .superelement import (
    check_rigid_modes as check_rigid_modes,
)
from .superelement import (
    scaled_table as scaled_table,
)
from .superelement import (
    table_from_reduced as table_from_reduced,
)
from .superelement import (
    weight_at_interfaces as weight_at_interfaces,
)
from .superelement import (
    with_rotation_nodes as with_rotation_nodes,
)
from .table import TableModel as TableModel
from .table import TableSpec as TableSpec
from .table import table_model as table_model

