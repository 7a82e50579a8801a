"""Elastic table finite elements: MITC4 flat shells, Timoshenko rib beams, condensation.

Layers: :mod:`.materials` → :mod:`.mesh` (structured table + ribs) → :mod:`.shell`,
:mod:`.beam` (pure element functions) → :mod:`.assemble` (vmapped element matrices, scatter,
supports) → :mod:`.condense` (rigid patches, control points) → :mod:`.table` (presets).
SI units; node DOF ``(ux, uy, uz, rx, ry, rz)``; X along the rails, Y across, Z up.
"""

from .assemble import (
    DOF_NAMES as DOF_NAMES,
    ElementArrays as ElementArrays,
    PlateSection as PlateSection,
    assemble as assemble,
    element_arrays as element_arrays,
    point_load as point_load,
    solve_fixed as solve_fixed,
)
from .beam import (
    beam_load as beam_load,
    beam_stiffness as beam_stiffness,
    rect_section as rect_section,
)
from .condense import (
    CondensedTable as CondensedTable,
    RigidPatch as RigidPatch,
    condense as condense,
    patch_lines as patch_lines,
)
from .materials import (
    CAST_IRON as CAST_IRON,
    STEEL as STEEL,
    Material as Material,
    material as material,
)
from .mesh import (
    Rib as Rib,
    TableMesh as TableMesh,
    grid_lines as grid_lines,
    table_mesh as table_mesh,
)
from .shell import shell_load as shell_load, shell_stiffness as shell_stiffness
from .table import (
    TableModel as TableModel,
    majda2012_table as majda2012_table,
    table_model as table_model,
)
