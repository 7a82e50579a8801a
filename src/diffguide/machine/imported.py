"""A machine whose table comes from the user's FE code: a reduced (superelement) matrix
(:mod:`diffguide.fe.superelement`) put under the carriages, nut and control points of a
:class:`~diffguide.machine.spec.MachineSpec`.

The retained nodes are named by the machine's own names: the carriages ``C{rail}{carriage}``
(``C11``, ``C12``, … rail by rail, carriages in the order of ``guideway.carriage_x``, as the
plate model names its patches) and ``nut``; the control points by their names in
``spec.points``. Each node's (x, y) must be where the specification puts that carriage / point
(within ``tol``): the same frame (origin at the table centre, X the travel, Z up).
"""

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np

from ..fe.condense import CondensedTable
from ..fe.superelement import ReducedMatrix, RetainedPoint, scaled_table, table_from_reduced
from .build import build_machine, machine_from_table, with_overrides
from .equilibrium import Machine
from .spec import MachineSpec


@dataclasses.dataclass(frozen=True)
class ImportedTable:
    """An imported table's data, SI: the reduced matrix (rotation nodes merged), the node
    coordinates, the interface nodes ``{name: node}``, the points ``{name: (RetainedPoint,
    rigid_to name or None)}``, the weight ``(mass, cog)`` when given and the file's format
    (read by :func:`diffguide.io.superelement_file.load_imported_table`)."""

    matrix: ReducedMatrix
    coords: dict
    interfaces: dict
    points: dict
    weight: tuple | None = None
    format: str = ""


def interface_names(spec: MachineSpec) -> tuple[str, ...]:
    """The interface names of ``spec`` in the order of the table's DOF: carriages, then nut."""
    g = spec.guideway
    return tuple(f"C{i + 1}{j + 1}" for i in range(len(g.rail_y))
                 for j in range(len(g.carriage_x))) + ("nut",)


def _expected_xy(spec: MachineSpec) -> dict[str, tuple[float, float]]:
    g = spec.guideway
    out = {f"C{i + 1}{j + 1}": (cx, ry) for i, ry in enumerate(g.rail_y)
           for j, cx in enumerate(g.carriage_x)}
    out["nut"] = tuple(spec.screw.nut_xy)
    return out


def imported_table(
    spec: MachineSpec,
    rm: ReducedMatrix,
    coords: Mapping[int, Sequence[float]],
    interfaces: Mapping[str, int],
    points: Mapping[str, RetainedPoint | int],
    *,
    weight: tuple[float, Sequence[float]] | None = None,
    tol: float = 1e-3,
    check: bool = True,
) -> CondensedTable:
    """The :class:`~diffguide.fe.condense.CondensedTable` of an imported reduced matrix for the
    machine ``spec`` (module docstring).

    Args:
        spec: the machine (carriage, nut and point positions; SI).
        rm: the reduced matrix, SI, rotation nodes merged
            (:func:`~diffguide.fe.superelement.with_rotation_nodes`).
        coords: ``{node: (x, y, z)}`` (m).
        interfaces: ``{"C11": node, …, "nut": node}``: each interface's reference node (six DOF
            retained).
        points: ``{name: RetainedPoint or node}`` for every control point of ``spec`` (a bare
            node: its DOF 4-6 must be retained).
        weight: ``(mass kg, (x, y, z) m)`` when ``rm`` has no self-weight loads (g from
            ``spec.gravity``).
        tol: largest distance in the XY plane between a node and its carriage / point (m).
        check: the rigid-body check of the matrix.

    Raises:
        KeyError: an interface or a control point of ``spec`` without a node (named).
        ValueError: a node away from its carriage / point, or a matrix that is not a free table.
    """
    names = interface_names(spec)
    where = _expected_xy(spec)
    nodes = []
    for name in names:
        if name not in interfaces:
            raise KeyError(f"{rm.source}: interface {name!r} has no retained node (give "
                           f"interfaces[{name!r}]; expected {', '.join(names)})")
        nodes.append(int(interfaces[name]))
        _near(rm, coords, nodes[-1], where[name], f"interface {name!r}", tol)
    extra = sorted(set(interfaces) - set(names))
    if extra:
        raise KeyError(f"{rm.source}: unknown interfaces {extra}; this machine has {names}")
    pts = []
    for name, xy in spec.points:
        if name not in points:
            raise KeyError(f"{rm.source}: control point {name!r} is not a retained node (give "
                           f"points[{name!r}]; a control point must be retained in the reduction)")
        p = points[name]
        p = p if isinstance(p, RetainedPoint) else RetainedPoint(name=name, node=int(p))
        _near(rm, coords, p.node, xy, f"control point {name!r}", tol)
        pts.append(p)
    w = None if weight is None else (weight[0], weight[1], spec.gravity)
    return table_from_reduced(rm, coords, nodes, pts, weight=w, check=check)


def _near(rm, coords, node, xy, what, tol):
    if node not in coords:
        raise KeyError(f"{rm.source}: {what}: no coordinates for node {node}")
    d = float(np.hypot(coords[node][0] - xy[0], coords[node][1] - xy[1]))
    if d > tol:
        raise ValueError(
            f"{rm.source}: {what}: node {node} is at ({coords[node][0]:.4g}, "
            f"{coords[node][1]:.4g}) m, {d * 1e3:.3g} mm from ({xy[0]:.4g}, {xy[1]:.4g}) m where "
            f"the machine puts it (tolerance {tol * 1e3:.3g} mm)")


def build_imported_machine(spec: MachineSpec, rm: ReducedMatrix, coords, interfaces, points,
                           **kwargs) -> Machine:
    """:func:`imported_table` put into the machine: ``machine_from_table(spec, table)``."""
    return machine_from_table(spec, imported_table(spec, rm, coords, interfaces, points,
                                                   **kwargs))


def resolve_points(data: ImportedTable, order, source: str = "") -> dict[str, RetainedPoint]:
    """``{name: RetainedPoint}`` of ``data`` with each ``rigid_to`` name turned into its index in
    the interface ``order`` (carriages, then nut); ``source`` names the description in errors."""
    order = list(order)
    points = {}
    for name, (pt, rigid_to) in data.points.items():
        if rigid_to is not None:
            if rigid_to not in order:
                raise ValueError(f"{source}: key 'points.{name}.rigid_to': {rigid_to!r} is not "
                                 f"one of {order}")
            pt = dataclasses.replace(pt, rigid_to=order.index(rigid_to))
        points[name] = pt
    return points


def machine_from_imported(spec: MachineSpec, data: ImportedTable, *, source: str = "",
                          stiffness_scale=None, **kwargs) -> Machine:
    """The machine ``spec`` on the imported table ``data`` (:func:`build_imported_machine`;
    ``kwargs``: ``tol``, ``check``), its stiffness times ``stiffness_scale`` when given (may be
    traced; :func:`~diffguide.fe.superelement.scaled_table`). ``source`` names the description
    in errors."""
    import equinox as eqx

    pts = resolve_points(data, interface_names(spec), source)
    try:
        machine = build_imported_machine(spec, data.matrix, data.coords, data.interfaces, pts,
                                         weight=data.weight, **kwargs)
    except KeyError as exc:  # a point or interface without its node: bad input, named
        raise ValueError(f"{exc.args[0]} (the table of {source}: measure or predict at "
                         f"its retained points, {', '.join(data.points)})") from None
    if stiffness_scale is not None:
        machine = eqx.tree_at(lambda m: m.table, machine,
                              scaled_table(machine.table, stiffness_scale))
    return machine


def machine_of_source(spec: MachineSpec, imported: ImportedTable | None = None, *,
                      source: str = "", nx: int | None = None, ny: int | None = None,
                      points: dict | None = None, stiffness_scale=None, **overrides) -> Machine:
    """The machine of ``spec`` on diffguide's plate (``imported`` ``None``) or on an imported
    table, with the same arguments for both.

    Arguments:
        spec: the machine. imported: the imported table, or ``None``. source: its description
            file as the user wrote it (for messages).
        nx, ny: the plate's mesh (``None``: the spec's); refused for an imported table.
        points: control points ``{name: (x, y)}`` (m) in place of the spec's; for an imported
            table each must be a retained node of the description.
        stiffness_scale: a factor on an imported table's stiffness (may be traced); refused
            for the plate.
        overrides: :func:`~diffguide.machine.build.build_machine`'s (``thickness``,
            ``preload_fraction``, …; SI); an imported table takes ``preload_fraction`` only.
    """
    if imported is None:
        if stiffness_scale is not None:
            raise ValueError("a stiffness scale applies to an imported table only (source = "
                             '"superelement"); the plate has a thickness')
        return build_machine(spec, nx=nx, ny=ny, points=points, **overrides)
    if nx is not None or ny is not None:
        raise ValueError(f"--mesh: the table is imported from {source} (source = "
                         '"superelement"): it has no mesh to set')
    plate = sorted(k for k, v in overrides.items() if v is not None and k != "preload_fraction")
    if plate:
        raise ValueError(f"{', '.join(plate)}: not a parameter of the imported table "
                         f"{source} (only preload_fraction and stiffness_scale are)")
    spec = with_overrides(spec, points=points, preload_fraction=overrides.get("preload_fraction"))
    return machine_from_imported(spec, imported, source=source, stiffness_scale=stiffness_scale)
