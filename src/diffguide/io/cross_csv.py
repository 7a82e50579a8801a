"""The cross table's errors over an ``(X, Y)`` grid as a CSV: one row per (X, Y, control
point), ``X_mm,Y_mm,point,x_mm,y_mm``, the six errors of the table relative to the bed in user
units (µm, µrad), and ``converged``."""

import numpy as np

from ..machine.errors import to_user
from ..machine.volumetric import TABLE_ERROR_NAMES, CrossErrors

#: The columns, in order.
COLUMNS = ("X_mm", "Y_mm", "point", "x_mm", "y_mm",
           *(f"{n}_{'um' if k < 3 else 'urad'}" for k, n in enumerate(TABLE_ERROR_NAMES)),
           "converged")


def cross_errors_csv(errors: CrossErrors) -> str:
    """The CSV text of :class:`~diffguide.machine.volumetric.CrossErrors` (positions and point
    coordinates in mm, errors in µm and µrad, relative to the reference position)."""
    e = to_user(errors.errors)  # the same factors as the one-axis errors (1e6)
    X, Y = np.asarray(errors.X) * 1e3, np.asarray(errors.Y) * 1e3
    pts = np.asarray(errors.points) * 1e3
    ok = np.asarray(errors.converged)
    lines = [",".join(COLUMNS)]
    for i, x in enumerate(X):
        for j, y in enumerate(Y):
            for k, name in enumerate(errors.point_names):
                vals = ",".join(f"{v + 0.0:.6f}" for v in e[i, j, k])
                lines.append(f"{x:.6g},{y:.6g},{name},{pts[k, 0]:.6g},{pts[k, 1]:.6g},{vals},"
                             f"{int(ok[i, j])}")
    return "\n".join(lines) + "\n"
