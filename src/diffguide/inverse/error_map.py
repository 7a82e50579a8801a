"""The error map: the six joint errors with σ on a grid over the whole table top, at every
table position, from a fit (:func:`error_map`; ``diffguide predict --grid NXxNY``).

The grid's ``NX × NY`` points are equally spaced over the table top, edges included, named
``G{i}_{j}`` (``i`` along X from 1 at ``x = −length/2``, ``j`` along Y from 1 at
``y = −width/2``), x-major. It is a :func:`~.predict.predict` at those points: the fitted
model is solved once over the positions and every grid point's errors follow from the
condensed table (:mod:`.posterior_sweep`), so time and memory grow linearly with the points.
The grid is bounded (:data:`GRID_SIDE`, :data:`MAX_GRID_VALUES`): the result holds twelve
float64 numbers (six errors, six σ) per point and position, and its CSV one line each.
"""

import dataclasses

import numpy as np

from .predict import Prediction, predict

#: Points along each side of the grid (NX along X, NY along Y).
GRID_SIDE = (2, 201)
#: Grid points times positions at most: 201 × 201 points at 71 positions, whose errors and σ
#: take 0.27 GB in memory and about 0.5 GB as a CSV.
MAX_GRID_VALUES = 201 * 201 * 71


def check_grid(shape, n_positions: int) -> tuple[int, int]:
    """``(NX, NY)``: integers within :data:`GRID_SIDE` whose product times ``n_positions``
    is at most :data:`MAX_GRID_VALUES`; ``ValueError`` naming the value and the bound."""
    try:
        nx, ny = shape
    except (TypeError, ValueError):
        raise ValueError(f"grid must be (NX, NY), got {shape!r}") from None
    lo, hi = GRID_SIDE
    for name, n in (("NX", nx), ("NY", ny)):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not lo <= n <= hi:
            raise ValueError(f"grid {name} must be an integer in {lo} .. {hi} (points along "
                             f"{'X' if name == 'NX' else 'Y'}, edges included), got {n!r}")
    if nx * ny * n_positions > MAX_GRID_VALUES:
        raise ValueError(
            f"grid {nx} x {ny} at {n_positions} positions is {nx * ny * n_positions} point "
            f"positions; at most {MAX_GRID_VALUES} (201 x 201 at 71 positions: the errors and "
            "σ take 0.27 GB, the CSV about 0.5 GB): use a coarser grid or fewer positions")
    return int(nx), int(ny)


def grid_points(spec, shape) -> dict:
    """``{G{i}_{j}: (x, y)}`` (m): the ``NX × NY`` grid over the table top of ``spec``,
    x-major (module docstring)."""
    nx, ny = shape
    half_l, half_w = spec.table.length / 2, spec.table.width / 2
    xs, ys = np.linspace(-half_l, half_l, nx), np.linspace(-half_w, half_w, ny)
    return {f"G{i + 1}_{j + 1}": (float(x), float(y))
            for i, x in enumerate(xs) for j, y in enumerate(ys)}


def error_map(fit, spec, shape, positions, *, measured_points: dict | None = None,
              nx: int | None = None, ny: int | None = None, extrapolate: bool = False,
              z: float = 0.0, make_machine=None) -> Prediction:
    """The six joint errors with σ on the ``shape = (NX, NY)`` grid over the table top
    (module docstring) at every table position.

    Arguments:
        fit, spec, positions, measured_points, nx, ny, extrapolate, z: as for
            :func:`~.predict.predict` (``nx``, ``ny``: the fit's mesh divisions, not the grid).
        shape: ``(NX, NY)`` grid points along X and Y (:func:`check_grid`).
        make_machine: an imported table's builder (``predict``'s) is refused: such a table
            knows only its retained nodes.

    Returns a :class:`~.predict.Prediction` with ``grid_shape = (NX, NY)``: ``errors`` and
    ``sigma`` ``(n_pos, NX·NY, 6)``, x-major (``reshape(n_pos, NX, NY, 6)``). The table's
    mesh is needed: an imported table (retained nodes only) has no error map.
    """
    if make_machine is not None:
        raise ValueError("no error map for an imported table (a reduced matrix): it knows only "
                         "its retained nodes; predict there")
    x = np.atleast_1d(np.asarray(positions, dtype=float))
    shape = check_grid(shape, len(x))
    pred = predict(fit, spec, grid_points(spec, shape), x, measured_points=measured_points,
                   nx=nx, ny=ny, extrapolate=extrapolate, z=z)
    return dataclasses.replace(pred, grid_shape=shape)
