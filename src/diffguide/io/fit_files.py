"""The text files of a fit's output folder: ``rails.csv`` (the profiles with σ), ``fit.csv``
(every reading with fitted value and residual) and ``layout.csv`` (the measured layout, in the
planner's format). SI inside; mm and µm (or the reading's own unit) in the files."""

import numpy as np

from ..inverse.data import QUANTITIES
from ..planning.instruments import KINDS
from .measurements import ANGULAR_UNITS, LINEAR_UNITS, format_csv

#: Spacing (mm) of the ``s`` grid of ``rails.csv`` and the figures.
S_STEP_MM = 2.0


def profile_grid(basis, step_mm: float = S_STEP_MM) -> np.ndarray:
    """The ``s`` grid (m) of ``rails.csv``: every ``step_mm`` (mm) on multiples of it over the
    fitted range ``[basis.start, basis.end]`` (m), with both ends — distinct as written (a grid
    point that the file's 0.001 mm resolution would not tell from an end is left out: an end
    computed as −432.00000000000005 mm next to the multiple −432 mm would otherwise be written
    as the same ``s_mm`` twice, which no reader accepts)."""
    s0 = np.ceil(basis.start * 1e3 / step_mm - 1e-9) * step_mm
    s_m = np.arange(s0, basis.end * 1e3 + 1e-9, step_mm) * 1e-3
    s_m = s_m[(s_m > basis.start) & (s_m < basis.end)]
    keys = _s_text(s_m)
    ends = set(_s_text([basis.start, basis.end]))
    inner = s_m[[k not in ends for k in keys]]
    return np.concatenate([[basis.start], inner, [basis.end]])


def _s_text(s_m) -> list[str]:
    """``s`` (m) as ``rails.csv`` writes it (mm, 3 decimals)."""
    return [f"{s * 1e3:.3f}" for s in np.asarray(s_m, float)]


def rails_csv_text(s_m, val, sig) -> str:
    """``rails.csv``: ``rail,s_mm,vertical_um,vertical_sigma_um,horizontal_um,
    horizontal_sigma_um``, one row per rail and ``s``; ``s_m`` (m), profiles ``val`` and σ
    ``sig`` ``(2 rails, 2 planes, len(s))`` (m), written in mm and µm. ``s_m`` must increase
    by at least the file's resolution, 0.001 mm (:func:`profile_grid` does), so that the file
    reads back (:func:`diffguide.io.rails_csv.read_rails_samples`); ``ValueError`` otherwise."""
    s_text = _s_text(s_m)
    s_back = np.array([float(s) for s in s_text])
    if np.any(np.diff(s_back) <= 0):
        i = int(np.flatnonzero(np.diff(s_back) <= 0)[0])
        raise ValueError(f"rails.csv: s must increase by at least 0.001 mm, the file's "
                         f"resolution; rows {i + 1} and {i + 2} read {s_text[i]} and "
                         f"{s_text[i + 1]} mm")
    lines = ["rail,s_mm,vertical_um,vertical_sigma_um,horizontal_um,horizontal_sigma_um"]
    for r in range(2):
        for i, s in enumerate(s_text):
            lines.append(f"{r + 1},{s},{val[r, 0, i] * 1e6:.5f},"
                         f"{sig[r, 0, i] * 1e6:.5f},{val[r, 1, i] * 1e6:.5f},"
                         f"{sig[r, 1, i] * 1e6:.5f}")
    return "\n".join(lines) + "\n"


def fit_csv_text(meas, fits: dict) -> str:
    """``fit.csv``: every input reading (``meas.readings``, in its own unit) with its status
    (used, an outlier reading set aside when merging, an outlier value given zero weight) and,
    per fit in ``fits`` (``{label: RailFit}``, ``""`` the elastic fit, whose outliers are
    reported), the fitted value and the residual ``measured − fitted`` in the reading's unit.

    The file is a measurement file in the long format (:mod:`.measurements`; the extra columns
    are ignored there): the reading's ``sigma`` (empty where none was given), ``z_mm`` and
    ``resolution`` (the rounding step ``√12·u`` of the value as first written, 0 where unknown)
    are written with it, so ``diffguide fit --measurements fit.csv`` merges the same data."""
    cols = ["line", "position_mm", "point", "x_mm", "y_mm", "quantity", "value", "unit", "run",
            "direction", "instrument", "sigma", "z_mm", "resolution", "status"]
    for label in fits:
        cols += [f"fitted{label}", f"residual{label}"]
    outlier_rows = set(int(i) for i in fits[""].outliers)
    rows = []
    for r, k in zip(meas.readings, meas.row_of_reading):
        f = {**LINEAR_UNITS, **ANGULAR_UNITS}[r.unit]
        status = ("outlier reading (not used)" if k < 0 else
                  "outlier value (zero weight)" if int(k) in outlier_rows else "used")
        row = {"line": r.line, "position_mm": float(r.position * 1e3), "point": r.point,
               "x_mm": float(r.xy[0] * 1e3), "y_mm": float(r.xy[1] * 1e3),
               "quantity": r.quantity, "value": float(r.value / f), "unit": r.unit,
               "run": r.run, "direction": r.direction, "instrument": r.instrument,
               "sigma": "" if r.sigma is None else float(r.sigma / f),
               "z_mm": float(r.z * 1e3), "resolution": float(np.sqrt(12.0) * r.resolution / f),
               "status": status}
        for label, fit in fits.items():
            row[f"fitted{label}"] = "" if k < 0 else float(fit.fitted[k] / f)
            row[f"residual{label}"] = "" if k < 0 else float((r.value - fit.fitted[k]) / f)
        rows.append(row)
    return format_csv(rows, tuple(cols))


def layout_csv_text(meas) -> str:
    """The measured layout in ``diffguide plan``'s plan format (``--start``/``--compare``):
    ``instrument,point,x_mm,y_mm,reads`` — one row per point and instrument kind (``level``,
    ``interferometer`` for angular optics, ``straightness`` for straightness optics; what the
    planner does not model — positioning, an interferometer reading roll — is left out),
    ``reads`` the quantities read there, ``+``-joined."""
    reads: dict[tuple[int, str], list[str]] = {}
    for p, q, inst in meas.channels:
        quantity = QUANTITIES[q]
        # a level is a level; an interferometer's optics are the planner's angular
        # interferometer or its straightness optics, by what they read
        kinds = ("level",) if inst == "level" else ("interferometer", "straightness")
        kind = next((k for k in kinds if quantity in KINDS[k]), None)
        if kind is not None and quantity not in reads.setdefault((p, kind), []):
            reads[(p, kind)].append(quantity)
    rows = [{"instrument": kind, "point": meas.point_names[p],
             "x_mm": float(meas.points_xy[p][0] * 1e3), "y_mm": float(meas.points_xy[p][1] * 1e3),
             "reads": "+".join(qs)} for (p, kind), qs in sorted(reads.items())]
    return format_csv(rows, ("instrument", "point", "x_mm", "y_mm", "reads"))
