r"""Measurement files in other layouts, read into the canonical readings (``diffguide import``).

Two layouts are supported; :func:`detect_layout` tells them apart from the first line that is
not blank or a ``#`` comment:

**long** (canonical, :mod:`diffguide.io.measurements`): one reading per row, a header line with
``position_mm``, ``point``, ``x_mm``, ``y_mm``, ``quantity``, ``value``, ``unit`` and optionally
``sigma``, ``run``, ``direction``, ``instrument``, ``z_mm``, ``reference``, ``resolution``.

**wide** ("targets × runs", as laser-calibration software and ISO 230-2 reports lay a
bidirectional positioning test out): one or more *blocks*, each a channel (one point, one
quantity, one instrument)::

    # any number of comment lines
    point;P5
    x_mm;0
    y_mm;0
    quantity;EBX
    unit;µm/m
    instrument;interferometer
    target_mm;run1_fwd;run1_bwd;run2_fwd;run2_bwd
    0;1,25;1,31;1,22;1,28
    20;...

- metadata lines ``key;value`` before the table: ``point``, ``x_mm``, ``y_mm`` (mm on the table
  top from its centre), ``quantity`` (EXX ... ECX), ``unit`` (any unit of the long format) are
  required; ``instrument``, ``sigma`` (standard uncertainty of one reading, in ``unit``),
  ``z_mm`` and ``resolution`` (the readings' rounding step, in ``unit``) are optional. Each
  block states its own metadata: a metadata line after a table starts the next block.
- the table header: ``target_mm`` (or ``position_mm``), then one column per run and direction,
  named ``run<k>_<dir>`` with ``<dir>`` one of ``fwd``/``forward``/``pos``/``positive``/``up``/``+``
  or ``bwd``/``backward``/``neg``/``negative``/``down``/``-`` (``run<k>`` alone: forward). A
  column ``run<k>_<dir>_ref`` is the *reference* reading of a differential level pair for that
  run and direction: the reading used is measuring − reference (a column without its partner is
  an error). Other columns (temperature, ...) are ignored with a note.
- one row per target position; an empty cell is a missing reading; a target repeated in a
  block is merged as further readings, with a note.
- a metadata line ``x0_mm;VALUE`` (anywhere, once per file) states the machine coordinate of
  the table position x = 0 (see below).

**x0, every layout alike**: a file's positions (``position_mm``, ``target_mm``, a profile's
position column) are machine coordinates ``X``; the table position is ``x = X − x0`` (x = 0 is
the model's reference position, the middle of the stroke). ``x0`` is the ``--x0-mm`` option
(a number, or ``middle``: the middle of the measured targets), else the file's own statement
(a wide file's ``x0_mm`` line, a profile's ``x0_mm``), else **0** (the positions are x already,
as in a file written by ``diffguide import``). The x0 used and where it came from are in
``info`` (and ``report.json``).

Both layouts: separator ``,``, ``;`` or tab (sniffed from the first table line), a decimal comma
is read when the separator is not ``,``; values, units and directions as in the long format
(units also ``nm``, ``in``, ``mm/m``, ``deg``, ``arcmin``; directions also ``positive``/
``negative``). Anything else fails with one line ``FILE:LINE: ...`` saying what was expected.
"""

import dataclasses
import hashlib
import io
import math
import os
import re

import numpy as np

from .measurements import (
    ANGULAR_UNITS,
    LINEAR_UNITS,
    OPTIONAL,
    REQUIRED,
    Reading,
    _parse_row,
    _RowError,
    merge_readings,
    note_repeats,
    parse_readings,
    read_text,
    sniff_delimiter,
    split_line,
)

LAYOUTS = ("auto", "long", "wide")
WIDE_REQUIRED = ("point", "x_mm", "y_mm", "quantity", "unit")
WIDE_OPTIONAL = ("instrument", "sigma", "z_mm", "resolution", "x0_mm")
WIDE_TARGET = ("target_mm", "position_mm")
_RUN_COLUMN = re.compile(
    r"^run\s*_?\s*(?P<run>[0-9a-z]+?)(?:[_ ]?(?P<dir>forward|backward|positive|negative|fwd|bwd|"
    r"pos|neg|up|down|\+|-))?(?P<ref>[_ ]ref(?:erence)?)?$"
)
_EXPECTED = (
    "expected a long header (position_mm,point,x_mm,y_mm,quantity,value,unit[,...]) or a wide "
    "block (metadata lines 'point;NAME', 'x_mm;..', 'y_mm;..', 'quantity;..', 'unit;..', then "
    "'target_mm;run1_fwd;run1_bwd;...')"
)


def _content_lines(text: str):
    for number, line in enumerate(text.splitlines(), start=1):
        if line.strip() and not line.strip().startswith("#"):
            yield number, line


def detect_layout(text: str, name: str = "<text>") -> str:
    """``"long"`` or ``"wide"`` from the first content line; ``ValueError`` naming the file and
    line otherwise."""
    for number, line in _content_lines(text):
        fields = [f.lower() for f in split_line(line, sniff_delimiter(line), name, number)]
        if "position_mm" in fields and "quantity" in fields:
            return "long"
        if fields and (fields[0] in WIDE_REQUIRED + WIDE_OPTIONAL or fields[0] in WIDE_TARGET):
            return "wide"
        raise ValueError(f"{name}:{number}: unknown layout: {_EXPECTED}")
    raise ValueError(f"{name}:1: no content (only blank or comment lines): {_EXPECTED}")


def _wide_columns(header, name, number, notes):
    """``{column index: (run, direction, is_reference)}`` from a wide table header."""
    cols, ignored = {}, []
    for k, f in enumerate(header[1:], start=1):
        m = _RUN_COLUMN.match(f.lower())
        if not m:
            ignored.append(f)
            continue
        d = (m["dir"] or "fwd").lower()
        direction = (
            "backward" if d in ("bwd", "backward", "neg", "negative", "down", "-") else ("forward")
        )
        cols[k] = (m["run"], direction, bool(m["ref"]))
    if not cols:
        raise ValueError(
            f"{name}:{number}: wide table header without run columns (expected "
            f"{header[0]};run1_fwd;run1_bwd;... or run1_fwd_ref for a reference "
            "level)"
        )
    seen = {}
    for k, key in cols.items():
        if key in seen:
            raise ValueError(
                f"{name}:{number}: columns {header[seen[key]]!r} and {header[k]!r} "
                "are the same run and direction"
            )
        seen[key] = k
    for run, d, ref in list(seen):
        if ref and (run, d, False) not in seen:
            raise ValueError(
                f"{name}:{number}: reference column {header[seen[(run, d, ref)]]!r} "
                f"without its measuring column run{run}_{d[:3]}"
            )
    if ignored and notes is not None:
        text = f"column(s) {', '.join(ignored)} ignored (not run columns)"
        if not any(n.endswith(text) for n in notes):  # once per file, not per block
            notes.append(f"{name}:{number}: {text}")
    return cols, seen


def parse_wide(
    text: str,
    name: str = "<text>",
    x0_mm: float | None = None,
    notes: list | None = None,
    info: dict | None = None,
) -> tuple[Reading, ...]:
    """Validated readings of a wide file (module docstring); ``x0_mm`` ``None``: the middle of
    the measured targets."""
    readings, meta, meta_line, stated = [], {}, {}, None
    table = None  # (columns, lookup, header, header line) while inside a table
    delimiter = None
    for number, line in _content_lines(text):
        if delimiter is None:
            delimiter = sniff_delimiter(line)
        fields = split_line(line, delimiter, name, number)
        key = fields[0].lower()
        if key in WIDE_REQUIRED + WIDE_OPTIONAL:
            if table is not None:  # a new block
                table, meta, meta_line = None, {}, {}
            values = [f for f in fields[1:] if f]
            if len(values) != 1:
                raise ValueError(
                    f"{name}:{number}: metadata line {key!r} needs one value "
                    f"('{key}{delimiter}VALUE')"
                )
            if key == "x0_mm":  # the file's, not the block's
                stated = _stated_x0(values[0], stated, name, number)
                continue
            meta[key], meta_line[key] = values[0], number
            continue
        if key in WIDE_TARGET:
            missing = [k for k in WIDE_REQUIRED if k not in meta]
            if missing:
                raise ValueError(
                    f"{name}:{number}: wide block without metadata line(s) "
                    f"{', '.join(missing)} before its '{fields[0]}' header "
                    f"(required {', '.join(WIDE_REQUIRED)}; optional "
                    f"{', '.join(WIDE_OPTIONAL)})"
                )
            cols, lookup = _wide_columns(fields, name, number, notes)
            table = (cols, lookup, fields, number)
            if info is not None:
                info.setdefault("blocks", []).append(
                    f"line {number}: {meta['quantity']} [{meta['unit']}] at {meta['point']}"
                    f" ({meta.get('instrument', 'default instrument')}), "
                    f"{len([c for c in cols.values() if not c[2]])} run columns")
            continue
        if table is None:
            raise ValueError(
                f"{name}:{number}: unknown line {line.strip()[:40]!r} in a wide file: {_EXPECTED}"
            )
        cols, lookup, header, hline = table
        if len(fields) != len(header):
            raise ValueError(
                f"{name}:{number}: {len(fields)} fields, the table header (line "
                f"{hline}) has {len(header)}"
            )
        for k, (run, direction, ref) in cols.items():
            if ref or not fields[k]:
                continue
            row = {
                "position_mm": fields[0],
                "point": meta["point"],
                "x_mm": meta["x_mm"],
                "y_mm": meta["y_mm"],
                "quantity": meta["quantity"],
                "unit": meta["unit"],
                "value": fields[k],
                "sigma": meta.get("sigma", ""),
                "run": run,
                "direction": direction,
                "instrument": meta.get("instrument", ""),
                "z_mm": meta.get("z_mm", ""),
                "resolution": meta.get("resolution", ""),
            }
            kref = lookup.get((run, direction, True))
            if kref is not None:
                if not fields[kref]:
                    raise ValueError(
                        f"{name}:{number}: column {header[kref]!r}: the reference "
                        f"reading is missing (column {header[k]!r} has one)"
                    )
                row["reference"] = fields[kref]
            try:
                readings.append(_parse_row(row, number))
            except _RowError as exc:
                what = (
                    str(exc)
                    .replace("field 'value'", f"column {header[k]!r}")
                    .replace("field 'position_mm'", f"column {header[0]!r}")
                )
                if kref is not None:
                    what = what.replace("field 'reference'", f"column {header[kref]!r}")
                raise ValueError(f"{name}:{number}: {what}") from None
    if not readings:
        raise ValueError(f"{name}:1: no readings in the wide file: {_EXPECTED}")
    note_repeats(readings, name, notes)
    return shift_x0(readings, x0_mm, stated, name, notes, info)


def _stated_x0(raw, stated, name, number):
    try:
        value = float(raw)
    except ValueError:
        raise ValueError(f"{name}:{number}: metadata line 'x0_mm': not a number, got {raw!r} "
                         "(allowed the machine coordinate of x = 0 in mm)") from None
    if stated is not None and stated[0] != value:
        raise ValueError(f"{name}:{number}: metadata line 'x0_mm' = {value:g} mm, but line "
                         f"{stated[1]} says {stated[0]:g} mm (allowed: one x0 per file)")
    return value, number


def shift_x0(readings, x0_mm, stated, name: str, notes: list | None, info: dict | None):
    """``readings`` with ``x = X − x0`` (module docstring: x0 is ``x0_mm`` when given — a
    number or ``"middle"`` — else the file's ``stated`` ``(x0, line)``, else 0); ``info``
    receives ``x0_mm`` and ``x0_source``."""
    if x0_mm is None and stated is not None:
        x0_mm, source = stated[0], f"{name}:{stated[1]}" if stated[1] else "the profile"
    elif x0_mm is None:
        x0_mm, source = 0.0, "default (the positions are table positions x)"
    elif x0_mm == "middle":
        pos = [r.position for r in readings]
        x0_mm, source = (min(pos) + max(pos)) / 2 * 1e3, "middle of the measured targets"
    else:
        x0_mm, source = float(x0_mm), "--x0-mm"
        if stated is not None and stated[0] != x0_mm and notes is not None:
            notes.append(f"{name}: x0 = {x0_mm:g} mm (--x0-mm) replaces the file's "
                         f"{stated[0]:g} mm")
    if x0_mm and notes is not None:
        notes.append(f"{name}: positions shifted by x0 = {x0_mm:g} mm ({source})")
    if info is not None:
        info["x0_mm"], info["x0_source"] = x0_mm, source
    x0 = x0_mm * 1e-3
    return tuple(dataclasses.replace(r, position=r.position - x0, source=name)
                 for r in readings)


def import_readings(
    path: str | os.PathLike,
    layout: str = "auto",
    x0_mm: float | str | None = None,
    notes: list | None = None,
    info: dict | None = None,
    *,
    profile: str | dict | None = None,
    encoding: str | None = None,
) -> tuple[Reading, ...]:
    """Readings of a measurement file in any supported layout (module docstring), or read
    through a ``profile`` (:mod:`diffguide.io.profiles`: a path, a built-in name or a loaded
    profile). ``x0_mm``: a number (mm), ``"middle"`` or ``None`` (the file's own x0, else 0).
    ``encoding``: ``None``/``"auto"`` (detected) or a codec name. ``info`` (a dict) receives
    what was used: ``layout``, ``encoding``, ``x0_mm``, ``x0_source`` and, per layout, the
    separator, decimal mark, columns, metadata, rows read and lines skipped."""
    from .profiles import load_profile, parse_profile

    name = os.fspath(path)
    info = {} if info is None else info
    prof = load_profile(profile) if isinstance(profile, str) else profile
    wanted = encoding or (prof.get("encoding", "auto") if prof else "auto")
    text = read_text(path, wanted, info)
    if prof is not None:
        if layout != "auto":
            raise ValueError(f"{name}: layout {layout!r} and a profile both given (a profile "
                             "says how the file is laid out: give one of them)")
        readings = parse_profile(text, prof, name, notes, info)
        x = prof.get("x0_mm")
        stated = info.pop("x0_stated", None)
        if x == "middle":
            x0_mm = x if x0_mm is None else x0_mm
        elif x is not None and stated is None:
            stated = (float(x), 0)
        info["layout"] = f"profile {prof['_source']}"
        return shift_x0(readings, x0_mm, stated, name, notes, info)
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
    if layout == "auto":
        layout = detect_layout(text, name)
    info["layout"] = layout
    _explain_csv(text, name, layout, info)
    if layout == "wide":
        return parse_wide(text, name, x0_mm, notes, info)
    readings = parse_readings(text, name, notes=notes)
    return shift_x0(readings, x0_mm, None, name, notes, info)


def _explain_csv(text, name, layout, info) -> None:
    """The separator, decimal mark and header of a canonical file, for ``--explain``."""
    for number, line in _content_lines(text):
        d = sniff_delimiter(line)
        if layout == "wide" and split_line(line, d, name, number)[0].lower() not in WIDE_TARGET:
            continue
        info["separator"] = {"\t": "tab"}.get(d, d)
        info["decimal"] = "," if d != "," else "."
        info["header_line"] = number
        info["header"] = split_line(line, d, name, number)
        return


def import_many(paths, layout: str = "auto", x0_mm=None, notes: list | None = None,
                infos: list | None = None, *, profile=None, encoding=None):
    """The readings of several files as one data set (:func:`import_readings` each; every
    reading's ``source`` is its file). A point at different (x, y) in two files, or a channel
    (point, quantity, instrument) at different heights ``z_mm``, is refused naming both files;
    a run label that two files use for the same channel and direction is made distinct (the
    second file's runs are other runs), with a note. ``x0_mm="middle"``: the middle of all
    files' targets. ``profile``: one for every file, or a list, one per file (``None``: a
    canonical layout)."""
    paths = [os.fspath(p) for p in paths]
    if not paths:
        raise ValueError("no measurement file given")
    _refuse_duplicates(paths)
    profiles = list(profile) if isinstance(profile, (list, tuple)) else [profile] * len(paths)
    if len(profiles) != len(paths):
        raise ValueError(f"{len(profiles)} profiles for {len(paths)} files (one per file)")
    per_file = []
    for path, prof in zip(paths, profiles):
        info: dict = {"file": path}
        rs = import_readings(path, layout, None if x0_mm == "middle" else x0_mm, notes, info,
                             profile=prof, encoding=encoding)
        per_file.append(rs)
        if infos is not None:
            infos.append(info)
    if x0_mm == "middle":
        pos = [r.position for rs in per_file for r in rs]
        mid = (min(pos) + max(pos)) / 2
        per_file = [tuple(dataclasses.replace(r, position=r.position - mid) for r in rs)
                    for rs in per_file]
        for info in infos or []:
            info["x0_mm"] += mid * 1e3
            info["x0_source"] = "middle of the measured targets (all files)"
    return _join(per_file, notes)


def _refuse_duplicates(paths) -> None:
    """Refuse a measurement file given twice — by the same path, another path to it (``./``,
    ``..``, a symbolic or hard link) or a copy (the same bytes) — naming both: merged as new
    data, its readings would count twice and narrow every σ by √2."""
    seen: dict = {}
    for p in paths:
        try:
            st = os.stat(p)
            with open(p, "rb") as fh:
                digest = hashlib.file_digest(fh, "sha256").hexdigest()
        except OSError:
            continue  # import_readings says why it cannot be read
        for key, why in (((st.st_dev, st.st_ino), "the same file"),
                         (digest, f"the same content (SHA-256 {digest[:12]}…)")):
            if key in seen:
                raise ValueError(f"{seen[key]} and {p}: {why}, given twice as measurement "
                                 "files; give each file once (merged with itself, its "
                                 "readings would count twice and narrow every σ by √2)")
        seen[(st.st_dev, st.st_ino)] = seen[digest] = p


def _join(per_file, notes):
    """The readings of several files, checked against each other (:func:`import_many`)."""
    points, channels, runs, out = {}, {}, {}, []
    for rs in per_file:
        renamed = set()
        for r in rs:
            prev = points.setdefault(r.point, (r.xy, r.source, r.line))
            if max(abs(a - b) for a, b in zip(prev[0], r.xy)) > 1e-9:
                raise ValueError(
                    f"{r.source}:{r.line}: point {r.point!r} is at ({r.xy[0] * 1e3:g}, "
                    f"{r.xy[1] * 1e3:g}) mm here but at ({prev[0][0] * 1e3:g}, "
                    f"{prev[0][1] * 1e3:g}) mm in {prev[1]}:{prev[2]} (allowed: one location "
                    "per point name in all the files merged)")
            ch = (r.point, r.quantity, r.instrument)
            prev = channels.setdefault(ch, (r.z, r.source, r.line))
            if abs(prev[0] - r.z) > 1e-9:
                raise ValueError(
                    f"{r.source}:{r.line}: {r.quantity} at {r.point} ({r.instrument}) is read "
                    f"at z = {r.z * 1e3:g} mm here but at z = {prev[0] * 1e3:g} mm in "
                    f"{prev[1]}:{prev[2]} (allowed: one sensing height per channel in all the "
                    "files merged; name the points apart if the setups differ)")
            key = (ch, r.run, r.direction)
            first = runs.setdefault(key, r.source)
            if first != r.source:
                renamed.add(r.run)
                r = dataclasses.replace(r, run=f"{r.run}@{os.path.basename(r.source)}")
                runs.setdefault((ch, r.run, r.direction), r.source)
            out.append(r)
        if renamed and notes is not None:
            notes.append(f"{rs[0].source}: run(s) {', '.join(sorted(renamed))} of a channel "
                         "already read from an earlier file are other runs: relabelled "
                         "RUN@FILE")
    return tuple(out)


def read_any(
    path,
    layout: str = "auto",
    x0_mm: float | str | None = None,
    notes: list | None = None,
    info: dict | None = None,
    *,
    allow_many_positions: bool = False,
    allow_conflicts: bool = False,
    profile=None,
    encoding: str | None = None,
):
    """Read and merge one measurement file, or several (``path`` a list: one data set,
    :func:`import_many`), in any supported layout or through a ``profile``
    (:class:`~diffguide.inverse.data.Measurements`, SI units; ``allow_many_positions``,
    ``allow_conflicts``: see :func:`~diffguide.inverse.merge.merge_readings`). ``info``
    receives the first file's :func:`import_readings` info and, under ``"files"``, every
    file's."""
    paths = [path] if isinstance(path, (str, os.PathLike)) else list(path)
    infos: list = []
    readings = import_many(paths, layout, x0_mm, notes, infos, profile=profile,
                           encoding=encoding)
    if info is not None:
        info.update(infos[0])
        info["files"] = infos
    source = ", ".join(os.fspath(p) for p in paths)
    return merge_readings(readings, source=source, notes=notes,
                          allow_many_positions=allow_many_positions,
                          allow_conflicts=allow_conflicts)


#: Units of the canonical file written by :func:`format_long`.
CANONICAL_UNIT = {"linear": "um", "angular": "um/m"}


def format_long(readings, comment: str = "") -> str:
    """The canonical long CSV of ``readings`` (µm for EXX/EYX/EZX, µm/m for the angles; a
    differential pair already reduced to measuring − reference; 6 decimals, i.e. 1 pm or
    1 prad — below any instrument's resolution). The ``resolution`` column keeps the rounding
    step of the readings as read (``√12 ×`` their rounding's standard uncertainty, so a reduced
    pair's two roundings stay in quadrature; 0 where unknown)."""
    cols = [c for c in REQUIRED + OPTIONAL if c != "reference"]
    out = io.StringIO()
    for line in comment.splitlines():
        out.write(f"# {line}\n")
    out.write(",".join(cols) + "\n")
    for r in readings:
        kind = "linear" if r.unit in LINEAR_UNITS else "angular"
        assert r.unit in (LINEAR_UNITS if kind == "linear" else ANGULAR_UNITS)
        sigma = "" if r.sigma is None else f"{r.sigma * 1e6:.6f}"
        step = f"{r.resolution * math.sqrt(12) * 1e6:.12g}"  # 0: unknown
        point = f'"{r.point}"' if ("," in r.point or '"' in r.point) else r.point
        out.write(
            f"{r.position * 1e3:.6f},{point},{r.xy[0] * 1e3:.6f},{r.xy[1] * 1e3:.6f},"
            f"{r.quantity},{r.value * 1e6:.6f},{CANONICAL_UNIT[kind]},{sigma},{r.run},"
            f"{r.direction},{r.instrument},{r.z * 1e3:.6f},{step}\n"
        )
    return out.getvalue()


def merged_table(meas) -> np.ndarray:
    """``(n, 5)``: position (mm), point (its rank among the names, sorted), quantity index,
    value and σ (µm, µm/m) of merged data, sorted — for comparing two files' merged data."""
    rank = np.argsort(np.argsort(np.array(meas.point_names)))
    a = np.column_stack(
        [meas.position * 1e3, rank[meas.point], meas.quantity, meas.value * 1e6,
         meas.sigma * 1e6]
    )
    return a[np.lexsort((a[:, 2], a[:, 1], np.round(a[:, 0], 6)))]  # positions to 1 nm
