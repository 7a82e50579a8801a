r"""The motion of any point of the table top from a condensed table, without condensing again.

A :class:`~diffguide.fe.condense.CondensedTable` keeps the back-substitution of the static
condensation for every mesh node, ``u_n = M_n u_b + u0_n`` (``node_modes``, ``node_u0``: the
interior ``u_i = K_ii⁻¹ (f_i − K_ib u_b)``, the gravity load included; a footprint node the
rigid map of its patch). The motion of the material point of the top surface above
``P = (x, y)`` follows with the shell's own bilinear shape functions ``N_k`` of the quad that
contains ``P`` and the offset ``o = (t/2) n`` from the mid-surface (n the element normal, +Z):

.. math::  u_P = \sum_k N_k(ξ, η)\,(u_k + θ_k × o),\qquad θ_P = \sum_k N_k(ξ, η)\,θ_k,

the rows :func:`~diffguide.fe.condense.condense` itself builds for its control points (at a node
the nodal values). ``[u_P, θ_P] = R_P u_b + r0_P``: :func:`point_rows` returns ``R_P`` and
``r0_P`` for any points at once, NumPy, from the table's nodes (moved ones included: the mesh's
grid lines are read from ``table.nodes``).
"""

import numpy as np

from .._core.rigid import rigid_transfer
from .mesh import TableMesh
from .shell import shell_frame, shell_shape

#: A point this far (m) outside the table still counts as on its edge (round-off).
_TOL = 1e-9


def point_rows(table, mesh: TableMesh, points, thickness: float | None = None):
    """Recovery rows of the top-surface points above ``points`` (module docstring).

    Arguments:
        table: a :class:`~diffguide.fe.condense.CondensedTable` condensed on ``mesh`` (its
            ``node_modes``, ``node_u0`` and ``nodes``).
        mesh: the mesh's topology (grid lines and quads; the coordinates are ``table.nodes``).
        points: ``(q, 2)`` points (x, y) on the table top (m).
        thickness: the plate thickness (m); default read from the table, whose interface
            reference points sit on the plate underside ``z = −t/2``.

    Returns ``(R, r0)``: ``(q, 6, m)`` motion ``(ux, uy, uz, rx, ry, rz)`` (m, rad) per interface
    DOF and ``(q, 6)`` the motion under the table's own loads with the interfaces held.
    ``ValueError`` for a table without nodes (imported as a reduced matrix), a point off the
    table or a mesh that is not the table's.
    """
    nodes = np.asarray(table.nodes, dtype=float)
    nx, ny = len(mesh.xs), len(mesh.ys)
    if nodes.shape[0] == 0:
        raise ValueError("this table has no mesh nodes (a table imported as a reduced matrix "
                         "knows only its retained nodes): predict at those")
    if nodes.shape != (nx * ny, 3):
        raise ValueError(f"the table has {nodes.shape[0]} nodes; the mesh has {nx} x {ny} grid "
                         "lines: not the mesh it was condensed on")
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    grid = nodes.reshape(nx, ny, 3)
    xs, ys = grid[:, 0, 0], grid[0, :, 1]
    off = (pts[:, 0] < xs[0] - _TOL) | (pts[:, 0] > xs[-1] + _TOL) | \
          (pts[:, 1] < ys[0] - _TOL) | (pts[:, 1] > ys[-1] + _TOL)
    if off.any():
        x, y = pts[off][0]
        raise ValueError(f"point ({x}, {y}) m is off the table [{xs[0]}, {xs[-1]}] x "
                         f"[{ys[0]}, {ys[-1]}] m")
    i = np.clip(np.searchsorted(xs, pts[:, 0], side="right") - 1, 0, nx - 2)
    j = np.clip(np.searchsorted(ys, pts[:, 1], side="right") - 1, 0, ny - 2)
    xi = 2.0 * (pts[:, 0] - xs[i]) / (xs[i + 1] - xs[i]) - 1.0
    eta = 2.0 * (pts[:, 1] - ys[j]) / (ys[j + 1] - ys[j]) - 1.0
    qn = np.asarray(mesh.quads)[i * (ny - 1) + j]  # (q, 4), counter-clockwise
    t = -2.0 * float(np.asarray(table.ref_points)[0, 2]) if thickness is None else thickness
    N = shell_shape(xi, eta, np)  # (q, 4)
    frame, _ = shell_frame(nodes[qn], np)
    W = N[:, :, None, None] * rigid_transfer(0.5 * t * frame[:, 2], np)[:, None]
    modes, u0 = np.asarray(table.node_modes), np.asarray(table.node_u0)
    R = np.einsum("pkab,pkbm->pam", W, modes[qn])
    r0 = np.einsum("pkab,pkb->pa", W, u0[qn])
    return R, r0
