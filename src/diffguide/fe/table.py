"""The table of a preset machine: mesh + plate + carriage/nut patches + control points.

:func:`majda2012_table` builds the ``majda2012`` table from ``presets.MAJDA2012_TABLE``,
``MAJDA2012_LAYOUT`` and ``MAJDA2012_POINTS``: a 1000 × 500 × 50 mm cast-iron plate on four
carriages (rails at y = ∓170 mm, carriages at x = ∓160 mm, footprints 60 × 48 mm bolted to the
underside) and the screw nut under the centre. Grid lines are added at every footprint edge and
at the control points, so footprints hold whole elements and points sit on nodes.
"""

from collections.abc import Sequence

import equinox as eqx

from ..presets import MAJDA2012_LAYOUT, MAJDA2012_POINTS, MAJDA2012_TABLE
from .assemble import PlateSection
from .condense import CondensedTable, RigidPatch, condense, patch_lines
from .materials import Material
from .mesh import Rib, TableMesh, table_mesh

#: Half-size (m) of the nut patch: a 50 × 50 mm flange (nut housing of a 32 mm screw, bolted
#: under the table centre).
NUT_HALF = 0.025


class TableModel(eqx.Module):
    """A table ready to condense: mesh, plate, interfaces (carriages then nut), control points.

    ``patches`` order = order of the interface DOF ``u_b`` (6 each); ``points`` (x, y) in m.
    """

    mesh: TableMesh
    plate: PlateSection
    patches: tuple[RigidPatch, ...]
    points: tuple[tuple[float, float], ...] = eqx.field(static=True)
    point_names: tuple[str, ...] = eqx.field(static=True)
    gravity: float = eqx.field(static=True, default=9.81)

    def condense(self, **kwargs) -> CondensedTable:
        """:func:`diffguide.fe.condense` of this table (keyword arguments passed on)."""
        kwargs.setdefault("gravity", self.gravity)
        return condense(self.mesh, self.plate, self.patches, self.points, **kwargs)


def majda2012_table(
    nx: int | None = None,
    ny: int | None = None,
    *,
    nut: bool = True,
    ribs: Sequence[Rib] = (),
    thickness: float | None = None,
    material: Material | None = None,
    points: dict[str, tuple[float, float]] | None = None,
) -> TableModel:
    """The ``majda2012`` table (see module docstring).

    Args:
        nx, ny: uniform divisions along X and Y (default 20 × 10, 50 mm elements), >= 1.
        nut: add the screw-nut patch (last interface, 6 DOF) under the table centre.
        ribs: optional ribs under the plate.
        thickness: plate thickness in m (default 0.05, the preset's equivalent thickness).
        material: plate material (default: the preset's cast iron, E 110 GPa, ν 0.26).
        points: control points ``{name: (x, y)}`` on the top surface (m); default P1..P5.

    Returns:
        :class:`TableModel` with patches C11, C12 (rail 1, y < 0; x < 0 then x > 0), C21, C22
        (rail 2), then ``nut``; points P1..P5 on the top surface.
    """
    T, L = MAJDA2012_TABLE, MAJDA2012_LAYOUT
    nx = T["nx"] if nx is None else nx
    ny = T["ny"] if ny is None else ny
    hx, hy = 0.5 * L["carriage_footprint"][0], 0.5 * L["carriage_footprint"][1]
    patches = [
        RigidPatch(x=cx, y=ry, half_x=hx, half_y=hy, name=f"C{i + 1}{j + 1}")
        for i, ry in enumerate(L["rail_y"])
        for j, cx in enumerate(L["carriage_x"])
    ]
    if nut:
        nx0, ny0 = L["nut_xy"]
        patches.append(RigidPatch(x=nx0, y=ny0, half_x=NUT_HALF, half_y=NUT_HALF, name="nut"))
    chosen = MAJDA2012_POINTS if points is None else points
    names = tuple(chosen)
    points = tuple(tuple(map(float, chosen[k])) for k in names)
    lx, ly = patch_lines(patches)
    lx += [p[0] for p in points]
    ly += [p[1] for p in points]
    mesh = table_mesh(T["length"], T["width"], nx, ny, lines_x=lx, lines_y=ly, ribs=ribs)
    if material is None:
        material = Material(E=T["E"], nu=T["nu"], rho=T["rho"], name="cast iron")
    plate = PlateSection(thickness=T["thickness"] if thickness is None else thickness,
                         material=material)
    return TableModel(
        mesh=mesh,
        plate=plate,
        patches=tuple(patches),
        points=points,
        point_names=names,
        gravity=float(L["gravity"]),
    )
