"""The joint kinematic errors of a sweep as a CSV: one row per (position, control point),
``position_mm,point,x_mm,y_mm`` and the six errors in user units (µm, µrad)."""

import numpy as np

from ..machine.errors import error_columns


def joint_errors_csv(positions, point_names, points_xy, errors_user) -> str:
    """The CSV text of a sweep.

    Arguments:
        positions: table positions (m), ``(n_pos,)``.
        point_names: the control points. points_xy: their ``(x, y)`` on the table top (m).
        errors_user: ``(n_pos, n_points, 6)`` errors in user units (µm, µrad), the order of
            :func:`~diffguide.machine.errors.error_columns`.
    """
    header = "position_mm,point,x_mm,y_mm," + ",".join(error_columns())
    lines = [header]
    xy = np.asarray(points_xy) * 1e3
    for i, x in enumerate(positions):
        for j, pname in enumerate(point_names):
            vals = ",".join(f"{v + 0.0:.6f}" for v in errors_user[i, j])
            lines.append(f"{x * 1e3:.6g},{pname},{xy[j, 0]:.6g},{xy[j, 1]:.6g},{vals}")
    return "\n".join(lines) + "\n"
