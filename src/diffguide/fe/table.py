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


def table_model(
    *,
    length: float,
    width: float,
    thickness,
    material: Material,
    nx: int,
    ny: int,
    rail_y: Sequence[float],
    carriage_x: Sequence[float],
    footprint: tuple[float, float],
    points: dict[str, tuple[float, float]],
    nut_xy: tuple[float, float] | None = (0.0, 0.0),
    nut_half: tuple[float, float] = (NUT_HALF, NUT_HALF),
    ribs: Sequence[Rib] = (),
    gravity: float = 9.81,
) -> TableModel:
    """A rectangular table on carriages at ``carriage_x × rail_y`` (and a nut), SI units.

    Args:
        length, width: plate size (m). thickness: plate thickness (m; may be traced).
        material: plate material. nx, ny: uniform divisions (refined by footprint/point lines).
        rail_y: Y of each rail (m). carriage_x: X of the carriages on each rail (m).
        footprint: carriage footprint (X, Y) bolted to the underside (m).
        points: control points ``{name: (x, y)}`` on the top surface (m).
        nut_xy: the screw nut's position (m), or ``None`` for no nut patch.
        nut_half: half-sizes of the nut flange (m). ribs: ribs under the plate.
        gravity: (m/s²).

    Returns:
        :class:`TableModel` with patches ``C{rail}{carriage}`` (rail by rail, carriages in the
        order of ``carriage_x``), then ``nut``.
    """
    hx, hy = 0.5 * footprint[0], 0.5 * footprint[1]
    patches = [
        RigidPatch(x=cx, y=ry, half_x=hx, half_y=hy, name=f"C{i + 1}{j + 1}")
        for i, ry in enumerate(rail_y)
        for j, cx in enumerate(carriage_x)
    ]
    if nut_xy is not None:
        patches.append(
            RigidPatch(x=nut_xy[0], y=nut_xy[1], half_x=nut_half[0], half_y=nut_half[1], name="nut")
        )
    names = tuple(points)
    xy = tuple(tuple(map(float, points[k])) for k in names)
    lx, ly = patch_lines(patches)
    lx += [p[0] for p in xy]
    ly += [p[1] for p in xy]
    mesh = table_mesh(length, width, nx, ny, lines_x=lx, lines_y=ly, ribs=ribs)
    plate = PlateSection(thickness=thickness, material=material)
    return TableModel(
        mesh=mesh, plate=plate, patches=tuple(patches), points=xy, point_names=names,
        gravity=float(gravity),
    )


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
    """The ``majda2012`` table (see module docstring; :func:`table_model` with the preset).

    Args:
        nx, ny: uniform divisions along X and Y (default 20 × 10, 50 mm elements), >= 1.
        nut: add the screw-nut patch (last interface, 6 DOF) under the table centre.
        ribs: optional ribs under the plate.
        thickness: plate thickness in m (default 0.05, the preset's equivalent thickness).
        material: plate material (default: the preset's cast iron, E 110 GPa, ν 0.26).
        points: control points ``{name: (x, y)}`` on the top surface (m); default P1..P5.
    """
    T, L = MAJDA2012_TABLE, MAJDA2012_LAYOUT
    if material is None:
        material = Material(E=T["E"], nu=T["nu"], rho=T["rho"], name="cast iron")
    return table_model(
        length=T["length"],
        width=T["width"],
        thickness=T["thickness"] if thickness is None else thickness,
        material=material,
        nx=T["nx"] if nx is None else nx,
        ny=T["ny"] if ny is None else ny,
        rail_y=L["rail_y"],
        carriage_x=L["carriage_x"],
        footprint=L["carriage_footprint"],
        points=MAJDA2012_POINTS if points is None else points,
        nut_xy=L["nut_xy"] if nut else None,
        ribs=ribs,
        gravity=L["gravity"],
    )
