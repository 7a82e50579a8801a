"""Structured mesh of a rectangular table: a tensor grid of 4-node shells, plus rib beams.

The grid is non-uniform: ``nx`` × ``ny`` uniform divisions united with any extra grid lines the
caller asks for (footprint edges of the carriages, control points, rib positions), so that rigid
patches contain whole element patches and points can sit on nodes. Near-coincident lines (closer
than ``tol``) are merged.

Frame: X along the rails (length), Y across (width), Z up; the plate mid-surface is at z = 0.
Nodes are numbered column by column: ``node = i * len(ys) + j`` for the grid line ``xs[i]``,
``ys[j]``; quads are counter-clockwise seen from +Z (normal +Z). Ribs are Timoshenko beams along
grid lines, hanging under the plate (their centroid at ``z = -t/2 - depth/2``, an offset from the
plate nodes handled by the beam element; their torsion constant is the one they add to the
plate, :func:`diffguide.fe.beam.bonded_rib_torsion`).

Topology (indices) is plain NumPy, fixed when the mesh is built; node coordinates are a NumPy
array here, and any array of the same shape (e.g. a traced one) may replace them in assembly.
"""

from collections.abc import Sequence

import equinox as eqx
import numpy as np

from .._core.types import ScalarLike
from .materials import Material


class Rib(eqx.Module):
    """A rectangular rib under the plate, running along a grid line.

    Args:
        axis: ``"x"`` (longitudinal rib, along the rails) or ``"y"`` (transverse rib).
        position: the rib's line: y of an ``"x"`` rib, x of a ``"y"`` rib, in m.
        width: rib width (horizontal, across the rib) in m, > 0.
        depth: rib depth below the plate underside in m, > 0.
        start, stop: extent of the rib along its axis in m (default: the whole table).
        material: the rib's material (default: the plate's).
    """

    axis: str = eqx.field(static=True)
    position: float = eqx.field(static=True)
    width: ScalarLike
    depth: ScalarLike
    start: float | None = eqx.field(static=True, default=None)
    stop: float | None = eqx.field(static=True, default=None)
    material: Material | None = None

    def __check_init__(self):
        if self.axis not in ("x", "y"):
            raise ValueError(f"Rib.axis must be 'x' or 'y', got {self.axis!r}")
        for name in ("width", "depth"):
            v = getattr(self, name)
            if isinstance(v, (int, float)) and not v > 0:
                raise ValueError(f"Rib.{name} must be > 0 m, got {v}")


class TableMesh(eqx.Module):
    """Tensor-grid shell mesh of a rectangular plate with optional rib beams.

    Attributes:
        xs, ys: grid lines (m), increasing.
        nodes: node coordinates, shape (n_nodes, 3), m (z = 0: mid-surface).
        quads: shell connectivity, shape (n_quads, 4), counter-clockwise.
        beams: rib beam connectivity, shape (n_beams, 2).
        beam_rib: index into ``ribs`` of each beam element, shape (n_beams,).
        ribs: the ribs.
    """

    xs: np.ndarray
    ys: np.ndarray
    nodes: np.ndarray
    quads: np.ndarray
    beams: np.ndarray
    beam_rib: np.ndarray
    ribs: tuple[Rib, ...] = ()

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.shape[0])

    @property
    def n_dof(self) -> int:
        """Number of DOF of the unconstrained mesh, 6 per node (ux, uy, uz, rx, ry, rz)."""
        return 6 * self.n_nodes

    def node_index(self, i: int, j: int) -> int:
        return int(i) * len(self.ys) + int(j)

    def node_at(self, x: float, y: float, tol: float = 1e-9) -> int:
        """Index of the node at (x, y) (m); ``ValueError`` if there is none within ``tol``."""
        d = np.hypot(self.nodes[:, 0] - x, self.nodes[:, 1] - y)
        k = int(np.argmin(d))
        if d[k] > tol:
            raise ValueError(
                f"no node at (x, y) = ({x}, {y}) m (nearest is {d[k]:.3g} m away); add grid "
                "lines there (lines_x / lines_y)"
            )
        return k

    def nodes_in_box(self, x0: float, x1: float, y0: float, y1: float, tol: float = 1e-9):
        """Indices of the nodes with x0 <= x <= x1 and y0 <= y <= y1 (m, inclusive ± tol)."""
        x, y = self.nodes[:, 0], self.nodes[:, 1]
        inside = (x >= x0 - tol) & (x <= x1 + tol) & (y >= y0 - tol) & (y <= y1 + tol)
        return np.flatnonzero(inside)

    def locate(self, x: float, y: float) -> int:
        """Index of the quad containing (x, y) (m) in the tensor grid; ``ValueError`` outside."""
        xs, ys = self.xs, self.ys
        tol = 1e-9
        if not (xs[0] - tol <= x <= xs[-1] + tol and ys[0] - tol <= y <= ys[-1] + tol):
            raise ValueError(
                f"point (x, y) = ({x}, {y}) m is outside the table "
                f"[{xs[0]}, {xs[-1]}] × [{ys[0]}, {ys[-1]}] m"
            )
        i = int(np.clip(np.searchsorted(xs, x, side="right") - 1, 0, len(xs) - 2))
        j = int(np.clip(np.searchsorted(ys, y, side="right") - 1, 0, len(ys) - 2))
        return i * (len(ys) - 1) + j


def grid_lines(start: float, stop: float, n: int, extra: Sequence[float] = (), tol: float = 1e-9):
    """``n`` uniform divisions of [start, stop] united with the ``extra`` lines inside it (m).

    Lines closer than ``tol`` are merged (the uniform one is kept).
    """
    lines = list(np.linspace(start, stop, n + 1))
    for e in sorted(float(v) for v in extra):
        if e < start - tol or e > stop + tol:
            raise ValueError(f"grid line {e} m is outside [{start}, {stop}] m")
        if min(abs(e - v) for v in lines) > tol:
            lines.append(e)
    return np.array(sorted(lines))


def table_mesh(
    length: float,
    width: float,
    nx: int,
    ny: int,
    *,
    lines_x: Sequence[float] = (),
    lines_y: Sequence[float] = (),
    ribs: Sequence[Rib] = (),
    origin: tuple[float, float] | None = None,
) -> TableMesh:
    """Structured mesh of a ``length`` × ``width`` plate (m) with ``nx`` × ``ny`` divisions.

    Args:
        length, width: plate size along X and Y in m, > 0.
        nx, ny: uniform divisions along X and Y, >= 1.
        lines_x, lines_y: extra grid lines (x and y values, m), e.g. footprint edges.
        ribs: ribs; their lines and ends are added to the grid automatically.
        origin: (x, y) of the corner with the smallest coordinates; default centred on (0, 0).
    """
    if not length > 0:
        raise ValueError(f"length must be > 0 m, got {length}")
    if not width > 0:
        raise ValueError(f"width must be > 0 m, got {width}")
    for name, n in (("nx", nx), ("ny", ny)):
        if int(n) != n or n < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {n}")
    x0, y0 = (-length / 2, -width / 2) if origin is None else (float(origin[0]), float(origin[1]))
    x1, y1 = x0 + length, y0 + width
    lines_x, lines_y = list(lines_x), list(lines_y)
    for r in ribs:
        on, along = (lines_y, lines_x) if r.axis == "x" else (lines_x, lines_y)
        on.append(r.position)
        along.extend(v for v in (r.start, r.stop) if v is not None)
    xs = grid_lines(x0, x1, int(nx), lines_x)
    ys = grid_lines(y0, y1, int(ny), lines_y)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    nodes = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    mx, my = len(xs), len(ys)
    i, j = np.meshgrid(np.arange(mx - 1), np.arange(my - 1), indexing="ij")
    i, j = i.ravel(), j.ravel()
    quads = np.stack([i * my + j, (i + 1) * my + j, (i + 1) * my + j + 1, i * my + j + 1], axis=1)
    beams, beam_rib = [], []
    tol = 1e-9
    for k, r in enumerate(ribs):
        start = -np.inf if r.start is None else r.start
        stop = np.inf if r.stop is None else r.stop
        if r.axis == "x":
            jr = int(np.argmin(abs(ys - r.position)))
            for ii in range(mx - 1):
                if xs[ii] >= start - tol and xs[ii + 1] <= stop + tol:
                    beams.append((ii * my + jr, (ii + 1) * my + jr))
                    beam_rib.append(k)
        else:
            ir = int(np.argmin(abs(xs - r.position)))
            for jj in range(my - 1):
                if ys[jj] >= start - tol and ys[jj + 1] <= stop + tol:
                    beams.append((ir * my + jj, ir * my + jj + 1))
                    beam_rib.append(k)
    return TableMesh(
        xs=xs,
        ys=ys,
        nodes=nodes,
        quads=quads.astype(np.int64),
        beams=np.array(beams, dtype=np.int64).reshape(-1, 2),
        beam_rib=np.array(beam_rib, dtype=np.int64),
        ribs=tuple(ribs),
    )
