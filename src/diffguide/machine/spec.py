"""Typed machine specification, SI units: everything :func:`~diffguide.machine.build.build_machine`
needs, as ``eqx.Module`` s.

A :class:`MachineSpec` is built from a preset (:func:`diffguide.presets.majda2012`) or from a
machine file (:func:`diffguide.io.config.spec_from_config`; the file is in user units, the spec in
SI). Fields that studies differentiate are ordinary pytree leaves and may hold traced arrays —
replace them with ``eqx.tree_at``::

    spec = eqx.tree_at(lambda s: s.table.thickness, presets.majda2012(), t)   # t may be traced
    machine = build_machine(spec)

Differentiable: ``table.thickness``, ``table.material.E``, ``carriage.preload_fraction``,
``carriage.capacity``, ``guideway.carriage_spacing``, ``guideway.rail_spacing``,
``screw.nut_x``, ``screw.nut_y``, the ribs' ``width`` and ``depth`` and the screw's stiffness
parameters.
Everything that fixes the mesh topology (sizes, positions, point names, mesh divisions) is static
(change it with ``dataclasses.replace``).
"""

from collections.abc import Mapping

import equinox as eqx

from .._core.checks import length, positive_int
from .._core.types import Array, Float
from ..fe.mesh import Rib
from ..fe.table import TableSpec
from ..guideway.carriage import CarriageSpec

Pair = tuple[float, float]
#: Plausible carriage footprints and nut flanges (m), each side: the machine file's 5 mm .. 1 m.
FOOTPRINT_RANGE = (5e-3, 1.0)
#: Plausible X strokes (m): the machine file's 1 mm .. 50 m.
STROKE_RANGE = (1e-3, 50.0)
#: Fewest rolling elements per row the model takes: the carriage's loaded length (``n·p``, the
#: default knot spacing of a fit) and its pitch stiffness need two.
MIN_ELEMENTS_PER_ROW = 2


def _pair(value) -> Pair:
    a, b = value
    return (float(a), float(b))


def _points(value) -> tuple[tuple[str, Pair], ...]:
    items = value.items() if isinstance(value, Mapping) else value
    return tuple((str(k), _pair(v)) for k, v in items)


class GuidewaySpec(eqx.Module):
    """Where the rails and carriages are (the ``[guideway]`` section of a machine file).

    Arguments:
        rail_y: Y of rail 1 and rail 2 (m), rail 1 first (the smaller Y).
        carriage_x: X of the two carriages on each rail, from the table centre (m).
        footprint: carriage footprint bolted to the table, (X, Y) (m; each within
            :data:`FOOTPRINT_RANGE`).
        carriage_spacing: ``None``, or the distance between the two carriages on each rail (m;
            may be traced): moves the carriages about the centre of ``carriage_x`` keeping the
            mesh topology (:func:`~diffguide.machine.build.build_machine`).
        rail_spacing: ``None``, or the distance between the two rails (m; may be traced): moves
            the rails (and their carriages) about the centre of ``rail_y`` keeping the mesh
            topology (:mod:`~diffguide.machine.morph`).
    """

    rail_y: Pair = eqx.field(static=True, converter=_pair)
    carriage_x: Pair = eqx.field(static=True, converter=_pair)
    footprint: Pair = eqx.field(static=True, converter=_pair)
    carriage_spacing: float | Float[Array, ""] | None = None
    rail_spacing: float | Float[Array, ""] | None = None

    def __check_init__(self):
        for k, side in enumerate(self.footprint):
            length(f"footprint[{k}]", side, *FOOTPRINT_RANGE)
        if not self.rail_y[0] < self.rail_y[1]:
            raise ValueError(f"rail_y: rail 1 must be at the smaller Y, got {self.rail_y}")
        if not self.carriage_x[1] - self.carriage_x[0] >= self.footprint[0]:
            raise ValueError(
                f"carriage_x: the carriages overlap ({self.carriage_x} m, footprint "
                f"{self.footprint[0]} m long)"
            )


class ScrewSpec(eqx.Module):
    """The feed screw and its nut (the ``[screw]`` section of a machine file).

    Arguments:
        core_diameter: screw core diameter (m). E: its Young's modulus (Pa).
        free_length_at_ref: fixed bearing to nut at x = 0 (m); the free length is this + x.
        nut_xy: the nut's position under the table (m). nut_footprint: its flange, (X, Y) (m).
        nut_x, nut_y: ``None``, or the nut's X or Y (m; may be traced) in place of ``nut_xy``'s,
            keeping the mesh topology (:mod:`~diffguide.machine.morph`).
    """

    core_diameter: float | Float[Array, ""]
    E: float | Float[Array, ""]
    free_length_at_ref: float | Float[Array, ""]
    nut_xy: Pair = eqx.field(static=True, converter=_pair)
    nut_footprint: Pair = eqx.field(static=True, converter=_pair)
    nut_x: float | Float[Array, ""] | None = None
    nut_y: float | Float[Array, ""] | None = None


class MachineSpec(eqx.Module):
    """A whole machine: table, guideway layout, runner block, screw, control points, ribs.

    Arguments:
        table: the plate (:class:`~diffguide.fe.table.TableSpec`).
        guideway: rails and carriage positions. carriage: the runner block (the same at every
            position, :class:`~diffguide.guideway.carriage.CarriageSpec`). screw: screw and nut.
        points: control points on the table top, ``{name: (x, y)}`` (m; stored as a tuple of
            pairs, in order).
        ribs: ribs under the plate (:class:`~diffguide.fe.mesh.Rib`, SI).
        gravity: g (m/s²), along −Z. stroke: X stroke, symmetric about x = 0 (m, within
            :data:`STROKE_RANGE`).

    The carriage needs ``elements_per_row >= 2`` (:data:`MIN_ELEMENTS_PER_ROW`); the table's
    sizes are checked by :class:`~diffguide.fe.table.TableSpec`, the footprints, stroke and
    points here, each refusal naming the field and its range in m.
    """

    table: TableSpec
    guideway: GuidewaySpec
    carriage: CarriageSpec
    screw: ScrewSpec
    points: tuple[tuple[str, Pair], ...] = eqx.field(static=True, converter=_points)
    ribs: tuple[Rib, ...] = eqx.field(default=(), converter=tuple)
    gravity: float = eqx.field(static=True, default=9.81)
    stroke: float = eqx.field(static=True, default=0.7)

    def __check_init__(self):
        if not self.points:
            raise ValueError("points: at least one control point is needed")
        length("stroke", self.stroke, *STROKE_RANGE)
        positive_int("carriage.elements_per_row", self.carriage.elements_per_row,
                     MIN_ELEMENTS_PER_ROW)
        names = [n for n, _ in self.points]
        if len(set(names)) != len(names):
            raise ValueError(f"points: names must be unique, got {names}")
        half_l, half_w = self.table.length / 2, self.table.width / 2
        fx, fy = self.guideway.footprint
        for y in self.guideway.rail_y:
            if abs(y) + fy / 2 > half_w + 1e-12:
                raise ValueError(f"guideway.rail_y: {y} m puts a carriage footprint off the table")
        for x in self.guideway.carriage_x:
            if abs(x) + fx / 2 > half_l + 1e-12:
                raise ValueError(
                    f"guideway.carriage_x: {x} m puts a carriage footprint off the table"
                )
        for name, (x, y) in self.points:
            if abs(x) > half_l + 1e-12 or abs(y) > half_w + 1e-12:
                raise ValueError(f"points: {name} at ({x}, {y}) m is off the table")

    @property
    def point_dict(self) -> dict[str, Pair]:
        """The control points as ``{name: (x, y)}`` (m)."""
        return dict(self.points)
