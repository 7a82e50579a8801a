"""The motion of any point of the table top from a condensed table
(:func:`diffguide.fe.recovery.point_rows`): the rows the condensation itself builds for its
control points (at and between nodes), and, between nodes, convergent under mesh refinement
towards a table condensed with a grid line through the point."""

import dataclasses

import numpy as np
import pytest

from diffguide.fe.condense import condense
from diffguide.fe.recovery import point_rows
from diffguide.machine.build import table_from_spec, with_overrides
from diffguide.machine.paper import majda2012_spec

#: On a node of the 20 x 10 mesh, inside elements, on the table's edge and in its corners.
POINTS = np.array([[0.3, 0.1], [0.333, -0.077], [-0.4711, 0.2213], [0.5, 0.031],
                   [-0.5, -0.25], [0.5, 0.25], [0.01, -0.1471]])


def _model(nx, ny, points=None):
    """The majda2012 table on an ``nx`` x ``ny`` mesh; grid lines through ``points`` (default
    the centre, through which the nut's footprint lines run anyway)."""
    return table_from_spec(with_overrides(majda2012_spec(), nx=nx, ny=ny,
                                          points=points or {"O": (0.0, 0.0)}))


def test_rows_are_the_condensations_own():
    """The rows of points that are not nodes (no grid line through them) equal the rows
    :func:`~diffguide.fe.condense.condense` builds for the same points on the same mesh."""
    model = _model(20, 10)
    assert model.mesh.node_at(0.3, 0.1) >= 0 and not np.isclose(model.mesh.xs, 0.333).any()
    table = condense(model.mesh, model.plate, model.patches, [tuple(p) for p in POINTS])
    R, r0 = point_rows(table, model.mesh, POINTS)
    m = table.K.shape[0]
    np.testing.assert_allclose(R, np.asarray(table.R).reshape(-1, 6, m), rtol=0,
                               atol=1e-12 * np.abs(table.R).max())
    np.testing.assert_allclose(r0, np.asarray(table.r0).reshape(-1, 6), rtol=0,
                               atol=1e-12 * np.abs(table.r0).max())
    # a node's rows are its nodal motion carried to the top surface
    k = model.mesh.node_at(0.3, 0.1)
    t = model.plate.thickness
    u = np.asarray(table.node_u0)[k]
    np.testing.assert_allclose(r0[0], u + np.r_[np.cross(u[3:], [0, 0, t / 2]), 0, 0, 0],
                               rtol=1e-13, atol=0)


def test_refused_off_the_table_and_without_nodes():
    model = _model(4, 2)
    table = model.condense()
    with pytest.raises(ValueError, match="off the table"):
        point_rows(table, model.mesh, [[0.6, 0.0]])
    bare = dataclasses.replace(table, nodes=np.zeros((0, 3)))
    with pytest.raises(ValueError, match="no mesh nodes"):
        point_rows(bare, model.mesh, [[0.0, 0.0]])


def test_between_nodes_converges_to_a_refined_table():
    """At a point between nodes (away from the carriages' rigid footprints) the interpolated
    motion — gravity sag with the carriages held, and every interface mode — approaches that
    of a 80 x 40 table meshed with grid lines through the point, at the rate of the bilinear
    elements (h²: measured 12.5 %, 3.4 %, 0.78 % at 10 x 5, 20 x 10, 40 x 20), no farther than
    the same mesh with a grid line through the point (14.7 %, 4.4 %, 0.83 %)."""
    p = np.array([[0.33, 0.03]])
    ref_model = _model(80, 40, {"P": tuple(p[0])})
    ref = ref_model.condense()
    m = ref.K.shape[0]
    R_ref = np.asarray(ref.R).reshape(1, 6, m)
    r0_ref = np.asarray(ref.r0).reshape(1, 6)
    scale_R = np.abs(R_ref).max(axis=(0, 2))  # per component (m/m, m/rad, rad/m, ...)
    scale_0 = np.abs(r0_ref).max()

    def error(R, r0):
        return max(np.max(np.abs(R - R_ref).max(axis=(0, 2)) / scale_R),
                   np.max(np.abs(r0 - r0_ref)) / scale_0)

    h, err, err_lines = [], [], []
    for nx, ny in ((10, 5), (20, 10), (40, 20)):
        model = _model(nx, ny)
        h.append(1.0 / nx)
        err.append(error(*point_rows(model.condense(), model.mesh, p)))
        lined = _model(nx, ny, {"P": tuple(p[0])}).condense()  # a grid line through P
        err_lines.append(error(np.asarray(lined.R).reshape(1, 6, m),
                               np.asarray(lined.r0).reshape(1, 6)))
    rate = np.polyfit(np.log(h), np.log(err), 1)[0]
    assert rate > 1.7, (rate, err)
    assert err[1] < 0.05 and err[2] < 0.01, err  # the default 20 x 10 mesh: within 5 %
    # interpolating costs no more than the mesh's own error at P
    assert all(e < 1.5 * el for e, el in zip(err, err_lines)), (err, err_lines)
