"""The rails CSV: rail straightness profiles, ``rail,s_mm,vertical_um,horizontal_um``.

One reader for every file of this format — ``simulate --rails`` and ``fit --truth`` (the bundled
``data/majda2012_truth.csv``) read it with the same rules:

- a header naming at least the four columns (others are ignored); lines starting with ``#`` and
  blank lines are skipped;
- ``rail`` is 1 (at −Y) or 2 (at +Y); ``s_mm`` (along the rail from the point under the table
  centre at x = 0) within ±100 000 mm; deviations finite, within ±10 000 µm;
- each rail present has at least 4 distinct ``s_mm``; a rail absent from the file is straight.

Every error names the file, the line and the field, in one line.
"""

import csv
import math
import os
from pathlib import Path

import numpy as np

#: The columns a rails CSV must have.
COLUMNS = ("rail", "s_mm", "vertical_um", "horizontal_um")
#: At least this many distinct ``s_mm`` per rail.
MIN_ROWS = 4


def _fail(path, line, field, message):
    where = f"{path}:{line}" if line is not None else f"{path}"
    field_part = f" field '{field}':" if field else ""
    raise ValueError(f"{where}:{field_part} {message}")


def read_rails_samples(path: str | os.PathLike) -> dict[int, np.ndarray]:
    """The samples of a rails CSV, SI: ``{rail: (n, 3) array of s, e_z, e_y}`` (m), sorted by
    ``s``, for the rails present (1 and/or 2).

    Raises:
        ValueError: naming the file, line and field of the first bad entry.
    """
    path = Path(path)
    try:
        fh = open(path, newline="", encoding="utf-8")
    except OSError as exc:
        raise OSError(f"cannot read rails file {path}: {exc.strerror}") from None
    rows = {1: [], 2: []}
    with fh:
        try:
            lines = ((k, text) for k, text in enumerate(fh, start=1))
            lines = ((k, t) for k, t in lines if t.strip() and not t.lstrip().startswith("#"))
            numbered = list(lines)
            reader = csv.reader(t for _, t in numbered)
            header = next(reader, None)
            if header is None:
                _fail(path, 1, None, "empty file; expected header " + ",".join(COLUMNS))
            header_line = numbered[0][0]
            header = [h.strip() for h in header]
            missing = [c for c in COLUMNS if c not in header]
            if missing:
                _fail(
                    path,
                    header_line,
                    missing[0],
                    f"missing column; the header must contain {','.join(COLUMNS)}",
                )
            col = {c: header.index(c) for c in COLUMNS}
            for (line, _), rec in zip(numbered[1:], reader):
                if not rec or all(not c.strip() for c in rec):
                    continue
                if len(rec) < len(header):
                    _fail(path, line, None, f"{len(rec)} fields, expected {len(header)}")
                vals = {}
                for c in COLUMNS:
                    text = rec[col[c]].strip()
                    try:
                        v = float(text)
                    except ValueError:
                        _fail(path, line, c, f"{text!r} is not a number")
                    if not math.isfinite(v):
                        _fail(path, line, c, f"{text!r} is not a finite number")
                    vals[c] = v
                if vals["rail"] not in (1.0, 2.0):
                    _fail(
                        path, line, "rail", f"{rec[col['rail']].strip()!r}: allowed values 1 or 2"
                    )
                if abs(vals["s_mm"]) > 1e5:
                    _fail(
                        path, line, "s_mm", f"{vals['s_mm']} outside the allowed range ±100000 mm"
                    )
                for c in ("vertical_um", "horizontal_um"):
                    if abs(vals[c]) > 1e4:
                        _fail(path, line, c, f"{vals[c]} outside the allowed range ±10000 µm")
                rows[int(vals["rail"])].append(
                    (vals["s_mm"] * 1e-3, vals["vertical_um"] * 1e-6, vals["horizontal_um"] * 1e-6)
                )
        except UnicodeDecodeError:
            _fail(path, None, None, "not a UTF-8 text file")
        except csv.Error as exc:
            _fail(path, None, None, f"malformed CSV ({exc})")
    if not rows[1] and not rows[2]:
        _fail(path, None, None, "no data rows")
    out = {}
    for r in (1, 2):
        if not rows[r]:
            continue
        data = np.array(sorted(rows[r]))
        s = data[:, 0]
        dup = s[1:][np.diff(s) == 0]
        if dup.size:
            _fail(path, None, "s_mm", f"rail {r} has s_mm = {dup[0] * 1e3:g} twice")
        if len(s) < MIN_ROWS:
            _fail(path, None, "s_mm", f"rail {r} has {len(s)} rows; at least {MIN_ROWS} are needed")
        out[r] = data
    return out


def read_rails_csv(path: str | os.PathLike, *, spacing: float | None = None):
    """Rail profiles from a rails CSV (module docstring): each rail interpolated by a C² cubic
    B-spline (:meth:`diffguide.guideway.rails.SplineRail.fit`, knot ``spacing`` in m, default the
    median sample spacing) and continued smoothly beyond its samples; a rail absent is straight.

    Returns:
        ``(rail1, rail2)`` profiles (SI inside).

    Raises:
        ValueError: naming the file, line and field of the first bad entry.
    """
    from ..guideway.rails import SplineRail, StraightRail

    samples = read_rails_samples(path)
    out = []
    for r in (1, 2):
        if r not in samples:
            out.append(StraightRail())
            continue
        s, v, h = samples[r].T
        try:
            out.append(SplineRail.fit(s, v, h, spacing=spacing))
        except (ValueError, np.linalg.LinAlgError) as exc:
            _fail(path, None, "s_mm", f"rail {r}: {exc}")
    return tuple(out)


def sampled_ranges(path: str | os.PathLike) -> dict[int, tuple[float, float]]:
    """``{rail index (0 = rail 1, 1 = rail 2): (first s, last s)}`` (m) of the rails present in a
    rails CSV: where its profiles are data (beyond, :func:`read_rails_csv` continues them)."""
    return {r - 1: (float(d[0, 0]), float(d[-1, 0])) for r, d in read_rails_samples(path).items()}


def rails_at(path: str | os.PathLike, s: np.ndarray) -> np.ndarray:
    """The profiles of a rails CSV linearly interpolated at ``s`` (m): ``(2 rails, 2 planes
    (vertical, horizontal), len(s))`` (m); a rail absent from the file is straight (zero)."""
    samples = read_rails_samples(path)
    s = np.asarray(s, dtype=float)
    out = np.zeros((2, 2, len(s)))
    for r, data in samples.items():
        out[r - 1, 0] = np.interp(s, data[:, 0], data[:, 1])
        out[r - 1, 1] = np.interp(s, data[:, 0], data[:, 2])
    return out
