"""File input/output at the edge of the library: atomic writes (and, later, validated readers).

Outputs are written to a temporary file in the destination folder and renamed into place, so an
interrupted run never leaves a half-written file that looks valid.
"""

import os
import tempfile
from collections.abc import Callable
from pathlib import Path


def atomic_write(path: str | os.PathLike, write: Callable[[str], None]) -> Path:
    """Call ``write(tmp_path)`` and rename the result to ``path`` atomically.

    The temporary file lives in the same folder (same file system), and keeps the destination's
    suffix so that writers choosing a format by extension (``savefig``) behave the same.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent or ".")
    os.close(fd)
    try:
        write(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the usual permissions
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (UTF-8)."""

    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)

    return atomic_write(path, write)


def atomic_savefig(fig, path: str | os.PathLike, **kwargs) -> Path:
    """Save a matplotlib figure to ``path`` atomically."""
    return atomic_write(path, lambda tmp: fig.savefig(tmp, **kwargs))


def _fail(path, line, field, message):
    where = f"{path}:{line}" if line is not None else f"{path}"
    field_part = f" field '{field}':" if field else ""
    raise ValueError(f"{where}:{field_part} {message}")


def read_rails_csv(path: str | os.PathLike, *, spacing: float | None = None):
    """Read rail profiles from CSV ``rail,s_mm,vertical_um,horizontal_um`` (header required).

    ``rail`` is 1 (at −Y) or 2 (at +Y); each rail needs at least 4 distinct ``s_mm``; a rail
    absent from the file is straight. Each rail is interpolated by a C² cubic B-spline
    (:meth:`diffguide.guideway.rails.SplineRail.fit`) and continued smoothly beyond its samples.

    Returns:
        ``(rail1, rail2)`` profiles (SI inside).

    Raises:
        ValueError: naming the file, line and field of the first bad entry.
    """
    import csv
    import math

    from ..guideway.rails import SplineRail, StraightRail

    path = Path(path)
    required = ("rail", "s_mm", "vertical_um", "horizontal_um")
    try:
        fh = open(path, newline="", encoding="utf-8")
    except OSError as exc:
        raise OSError(f"cannot read rails file {path}: {exc.strerror}") from None
    rows = {1: [], 2: []}
    with fh:
        try:
            reader = csv.reader(fh)
            header = next(reader, None)
            if header is None:
                _fail(path, 1, None, "empty file; expected header " + ",".join(required))
            header = [h.strip() for h in header]
            missing = [c for c in required if c not in header]
            if missing:
                _fail(
                    path,
                    1,
                    missing[0],
                    f"missing column; the header must contain {','.join(required)}",
                )
            col = {c: header.index(c) for c in required}
            for line, rec in enumerate(reader, start=2):
                if not rec or all(not c.strip() for c in rec):
                    continue
                if len(rec) < len(header):
                    _fail(path, line, None, f"{len(rec)} fields, expected {len(header)}")
                vals = {}
                for c in required:
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
                    (vals["s_mm"], vals["vertical_um"], vals["horizontal_um"])
                )
        except UnicodeDecodeError:
            _fail(path, None, None, "not a UTF-8 text file")
        except csv.Error as exc:
            _fail(path, None, None, f"malformed CSV ({exc})")
    if not rows[1] and not rows[2]:
        _fail(path, None, None, "no data rows")
    out = []
    for r in (1, 2):
        if not rows[r]:
            out.append(StraightRail())
            continue
        data = sorted(rows[r])
        s = [d[0] for d in data]
        if len(set(s)) != len(s):
            dup = next(v for v in s if s.count(v) > 1)
            _fail(path, None, "s_mm", f"rail {r} has s_mm = {dup} twice")
        if len(s) < 4:
            _fail(path, None, "s_mm", f"rail {r} has {len(s)} rows; at least 4 are needed")
        import numpy as np

        s_m = np.asarray(s) * 1e-3
        try:
            out.append(
                SplineRail.fit(
                    s_m,
                    np.asarray([d[1] for d in data]) * 1e-6,
                    np.asarray([d[2] for d in data]) * 1e-6,
                    spacing=spacing,
                )
            )
        except (ValueError, np.linalg.LinAlgError) as exc:
            _fail(path, None, "s_mm", f"rail {r}: {exc}")
    return tuple(out)
