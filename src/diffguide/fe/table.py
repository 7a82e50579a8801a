"""The table of a machine: mesh + plate + carriage/nut patches + control points.

:class:`TableSpec` is the plate (size, thickness, material, mesh divisions, SI);
:func:`table_model` puts it on carriages at ``carriage_x × rail_y`` and a screw nut. Grid lines
are added at every footprint edge and at the control points, so footprints hold whole elements
and points sit on nodes. (The ``majda2012`` table:
:func:`diffguide.machine.majda2012.majda2012_table`.)
"""

from collections.abc import Sequence

import equinox as eqx

from .._core.checks import length as _length
from .._core.types import Array, Float
from .assemble import PlateSection
from .condense import CondensedTable, RigidPatch, condense, patch_lines
from .materials import Material
from .mesh import Rib, TableMesh, table_mesh

#: Plausible plate sizes (m), the machine file's ranges: length along X, width along Y and the
#: equivalent thickness (1 mm to 2 m).
LENGTH_RANGE = (0.05, 20.0)
WIDTH_RANGE = (0.05, 10.0)
THICKNESS_RANGE = (1e-3, 2.0)


class TableSpec(eqx.Module):
    """The table plate, SI units (the ``[table]`` section of a machine file).

    Arguments:
        length, width: plate size along X and Y (m; within :data:`LENGTH_RANGE`,
            :data:`WIDTH_RANGE`). thickness: equivalent plate thickness (m, within
            :data:`THICKNESS_RANGE`; may be traced: checked only when concrete).
        material: plate material (its ``E`` may be traced). nx, ny: uniform mesh divisions
            along X and Y (refined by footprint and point lines).
    """

    length: float = eqx.field(static=True)
    width: float = eqx.field(static=True)
    thickness: float | Float[Array, ""]
    material: Material
    nx: int = eqx.field(static=True)
    ny: int = eqx.field(static=True)

    def __check_init__(self):
        if not (self.length > 0 and self.width > 0):
            raise ValueError(f"length and width must be > 0 m, got {self.length}, {self.width}")
        _length("length", self.length, *LENGTH_RANGE)
        _length("width", self.width, *WIDTH_RANGE)
        _length("thickness", self.thickness, *THICKNESS_RANGE)
        for name in ("nx", "ny"):
            n = getattr(self, name)
            if isinstance(n, bool) or int(n) != n or n < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {n!r}")


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
    nut_xy: tuple[float, float] | None = None,
    nut_half: tuple[float, float] | None = None,
    ribs: Sequence[Rib] = (),
    gravity: float = 9.81,
) -> TableModel:
    """A rectangular table on carriages at ``carriage_x × rail_y`` (and a nut), SI units.

    Args:
        length, width: plate size (m). thickness: plate thickness (m, within
            :data:`THICKNESS_RANGE`; may be traced).
        material: plate material. nx, ny: uniform divisions (refined by footprint/point lines).
        rail_y: Y of each rail (m). carriage_x: X of the carriages on each rail (m).
        footprint: carriage footprint (X, Y) bolted to the underside (m).
        points: control points ``{name: (x, y)}`` on the top surface (m).
        nut_xy: the screw nut's position (m), or ``None`` for no nut patch.
        nut_half: half-sizes of the nut flange (m; needed with ``nut_xy``). ribs: ribs under
            the plate.
        gravity: (m/s²).

    Returns:
        :class:`TableModel` with patches ``C{rail}{carriage}`` (rail by rail, carriages in the
        order of ``carriage_x``), then ``nut``.
    """
    _length("thickness", thickness, *THICKNESS_RANGE)  # concrete values only
    hx, hy = 0.5 * footprint[0], 0.5 * footprint[1]
    patches = [
        RigidPatch(x=cx, y=ry, half_x=hx, half_y=hy, name=f"C{i + 1}{j + 1}")
        for i, ry in enumerate(rail_y)
        for j, cx in enumerate(carriage_x)
    ]
    if nut_xy is not None:
        if nut_half is None:
            raise ValueError("nut_half (half-sizes of the nut flange, m) is needed with nut_xy")
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
        mesh=mesh,
        plate=plate,
        patches=tuple(patches),
        points=xy,
        point_names=names,
        gravity=float(gravity),
    )
