"""The files of ``diffguide predict``: the points and positions it reads, and the prediction
CSV it writes (mm, µm, µrad at the edge; SI inside).

- points file: ``point,x_mm,y_mm`` (one point a line; :mod:`.csvtable` rules);
- positions file: ``position_mm`` (one table position a line);
- prediction CSV: ``position_mm,point,x_mm,y_mm,EXX_um,EYX_um,EZX_um,EAX_urad,EBX_urad,
  ECX_urad``, then the six σ (``EXX_sigma_um`` …) and ``extrapolated`` (0/1), under a ``#``
  header stating units, signs and what EXX holds.
"""

import os

import numpy as np

from .._core.comments import CommentSyntax
from .._core.limits import MAX_POSITIONS
from ..machine.errors import error_columns
from .csvtable import iter_rows, number, read_table, read_text

_COMMENT = CommentSyntax("#", ascii_only=False)  # the header's "#" lines (UTF-8)


def read_points_file(path: str | os.PathLike) -> dict[str, tuple[float, float]]:
    """``{name: (x, y)}`` (m) from a ``point,x_mm,y_mm`` CSV; a name given twice is refused
    (``ValueError`` naming the file and line)."""
    name = os.fspath(path)
    out: dict[str, tuple[float, float]] = {}
    for line, row in read_table(path, ("point", "x_mm", "y_mm")):
        p = row["point"].strip()
        if not p:
            raise ValueError(f"{name}:{line}: field 'point': empty (allowed a name)")
        if p in out:
            raise ValueError(f"{name}:{line}: point {p!r} given twice")
        out[p] = (number(row, "x_mm", name, line, "mm") * 1e-3,
                  number(row, "y_mm", name, line, "mm") * 1e-3)
    if not out:
        raise ValueError(f"{name}: no points (expected point,x_mm,y_mm rows)")
    return out


def read_positions_file(path: str | os.PathLike) -> np.ndarray:
    """Table positions (m) from a ``position_mm`` CSV."""
    name = os.fspath(path)
    x = []
    for line, row in iter_rows(read_text(path), name, ("position_mm",)):
        if len(x) == MAX_POSITIONS:
            raise ValueError(f"{name}:{line}: more than {MAX_POSITIONS} positions (allowed "
                             f"1..{MAX_POSITIONS}: about 10 kB of memory per position)")
        x.append(number(row, "position_mm", name, line, "mm") * 1e-3)
    if not x:
        raise ValueError(f"{name}: no positions (expected position_mm rows)")
    return np.asarray(x)


def parse_point(text: str) -> tuple[str, tuple[float, float]]:
    """``NAME:X_MM,Y_MM`` → ``(name, (x, y))`` (m); a clear ``ValueError`` otherwise."""
    name, sep, xy = str(text).partition(":")
    parts = xy.split(",")
    try:
        if not sep or not name.strip() or len(parts) != 2:
            raise ValueError
        x, y = float(parts[0]), float(parts[1])
        if not (np.isfinite(x) and np.isfinite(y)):
            raise ValueError
    except ValueError:
        raise ValueError(f"--point must be NAME:X_MM,Y_MM (e.g. Q1:300,-100), got {text!r}") \
            from None
    return name.strip(), (x * 1e-3, y * 1e-3)


def prediction_csv_text(pred, source: str = "", x0_mm: float | None = None) -> str:
    """The prediction CSV of a :class:`~diffguide.inverse.predict.Prediction` (module
    docstring); ``source`` a line for the header, ``x0_mm`` the machine coordinate of x = 0
    (mentioned in the header when known)."""
    err, sig = pred.user_units()
    cols = error_columns()
    sig_cols = error_columns("_sigma")
    lo, hi = (v * 1e3 for v in pred.position_range)
    lead = ("EXX includes the feed screw's lead error fitted to the EXX data"
            if pred.lead else "no EXX data were fitted: EXX holds no lead error (the model's "
            "elastic part only)")
    head = [
        _COMMENT.lines([f"diffguide predict: joint errors of the X axis at points of the "
                        f"table; {source}".rstrip("; ")])[0],
        "# units: position, x, y in mm; EXX EYX EZX and their sigma in um; EAX (roll) EBX "
        "(pitch) ECX (yaw) and their sigma in urad (um/m)",
        f"# signs: ISO 230-1 errors (a controller compensates by their negatives), relative to "
        f"the reference position x = {pred.x_ref * 1e3:g} mm"
        + ("" if x0_mm is None else f" (machine coordinate {x0_mm:g} mm)")
        + (f"; at {pred.z * 1e3:g} mm above the table top (the tool point: EXX holds z*EBX, "
           "EYX -z*EAX)" if getattr(pred, "z", 0.0) else
           "; at the table top (a tool point z above it adds z*EBX to EXX and -z*EAX to EYX: "
           "diffguide predict --z-mm)"),
        f"# {lead}; straightness (EYX, EZX) in the fit's gauge (the rails' common slope per "
        "plane, which no reading determines, fixed as in the fit)",
        "# sigma: 1 standard deviation from the fit's full posterior (rails, structure, lead "
        f"and alignment nuisances); measured range {lo:g} .. {hi:g} mm; extrapolated = 1 "
        "outside it (the data say nothing there)",
        ",".join(["position_mm", "point", "x_mm", "y_mm", *cols, *sig_cols, "extrapolated"]),
    ]
    rows = []
    for i, x in enumerate(pred.positions):
        for j, name in enumerate(pred.point_names):
            px, py = pred.points_xy[j] * 1e3
            vals = [f"{v + 0.0:.5f}" for v in err[i, j]] + [f"{v:.5f}" for v in sig[i, j]]
            rows.append(",".join([f"{x * 1e3:.4f}", name, f"{px:g}", f"{py:g}", *vals,
                                  str(int(pred.extrapolated[i]))]))
    return "\n".join(head + rows) + "\n"
