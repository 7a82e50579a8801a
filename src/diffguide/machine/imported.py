"""A machine whose table comes from the user's FE code: a reduced (superelement) matrix
(:mod:`diffguide.fe.superelement`) put under the carriages, nut and control points of a
:class:`~diffguide.machine.spec.MachineSpec`.

The retained nodes are named by the machine's own names: the carriages ``C{rail}{carriage}``
(``C11``, ``C12``, … rail by rail, carriages in the order of ``guideway.carriage_x``, as the
plate model names its patches) and ``nut``; the control points by their names in
``spec.points``. Each node's (x, y) must be where the specification puts that carriage / point
(within ``tol``): the same frame (origin at the table centre, X the travel, Z up).
"""

from collections.abc import Mapping, Sequence

import numpy as np

from ..fe.condense import CondensedTable
from ..fe.superelement import ReducedMatrix, RetainedPoint, table_from_reduced
from .build import machine_from_table
from .equilibrium import Machine
from .spec import MachineSpec


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
