r"""Measured joint kinematic errors: read and validate a measurement CSV (the merging of the
readings: :mod:`diffguide.inverse.merge`).

File format (UTF-8, one header line; blank lines and lines starting with ``#`` are skipped; the
separator is ``,``, ``;`` or tab, sniffed from the header line; with ``;`` or tab a decimal
comma is read; other layouts: :mod:`diffguide.io.importers`)::

    position_mm,point,x_mm,y_mm,quantity,value,unit[,sigma][,run][,direction][,instrument][,z_mm]
    [,reference][,resolution]

- ``position_mm``: table position ``x`` (mm). ``point``: the control point's name; ``x_mm``,
  ``y_mm``: where it is on the table top (mm, from the table centre; the same for every row of
  a point).
- ``quantity``: ``EXX``, ``EYX``, ``EZX`` (``µm``/``um``, ``mm``, ``nm``, ``in``, ``µin``/``uin``)
  or ``EAX``, ``EBX``, ``ECX`` (``µm/m``/``um/m``, ``µrad``/``urad``, ``mrad``, ``rad``, ``mm/m``,
  ``arcsec``/``arc-sec``/``"``, ``arcmin``, ``deg``; case and spaces do not matter).
  ``value`` and ``sigma`` (> 0, the standard uncertainty of *one reading*) are in ``unit``;
  ``value`` (and ``reference``) within
  ±10000 µm for a linear error, ±10000 µm/m (10 mrad) for an angle (:data:`VALUE_LIMIT`); a
  stated ``sigma`` must be > 0 and within the same limit.
- ``run``: a label of the run (default: one run); rows that repeat the position, point,
  quantity, instrument, run and direction of an earlier row are merged as further readings and
  named in a note (:func:`note_repeats`). ``direction``: ``forward``/``+``/``fwd``/
  ``positive`` or ``backward``/``reverse``/``-``/``bwd``/``negative`` (default: forward).
- ``reference``: a differential level pair's reference level reading (in ``unit``): the reading
  used is ``value − reference`` (measuring minus reference level); a channel has it on every
  row or on none (an empty cell among paired rows is an error, not a reference of 0). Its noise
  is not added to the default σ: with enough runs the pooled scatter
  (:mod:`diffguide.inverse.merge`, step 3) includes it.
- any other column (temperature, ...) is ignored and reported as a note, unless its name is
  close to one of the above (a typo: an error).
- ``instrument``: ``level`` or ``interferometer``. Default: ``level`` for roll and pitch
  (``EAX``, ``EBX``), ``interferometer`` otherwise (only an interferometer measures yaw and the
  linear errors).
- ``z_mm``: height of the instrument's sensing point above the table top (mm, default 0: on the
  surface) — an interferometer's optics or a straightness reflector on a riser. A linear error
  read there carries the Abbe terms of the table's rotation: ``EXX(z) = EXX + z·EBX``,
  ``EYX(z) = EYX − z·EAX``; the angles do not depend on it.
- ``resolution``: the rounding step ``q`` of ``value`` (and ``reference``) as the instrument
  wrote them, in ``unit`` (≥ 0; empty: the unit of the last digit written, as by default; 0:
  unknown, no rounding floor).
  ``diffguide import`` writes it, so that a file converted to 6 decimals keeps the original
  rounding (the floor of :mod:`diffguide.inverse.merge`, step 3).

The readings are merged per channel and position by
:func:`diffguide.inverse.merge.merge_readings` (outliers, runs, directions, σ of one reading and
its floors); :func:`read_measurements` reads and merges in one call.

Every row is validated; a bad row raises one ``ValueError`` ``"FILE:LINE: field 'f': ... (allowed
...)"``. Values are converted to SI (m, rad).
"""

import csv
import dataclasses
import io
import math
import os
import re

from ..inverse.data import LINEAR, QUANTITIES, Measurements
from ..inverse.data import Reading as Reading
from ..inverse.data import default_instrument as _default_instrument
from ..inverse.merge import COPIES_FRACTION as COPIES_FRACTION
from ..inverse.merge import DEFAULT_SIGMA as DEFAULT_SIGMA
from ..inverse.merge import MIN_RUNS_FOR_OUTLIERS as MIN_RUNS_FOR_OUTLIERS
from ..inverse.merge import MIN_SCATTER_DOF as MIN_SCATTER_DOF
from ..inverse.merge import OUTLIER_Z as OUTLIER_Z
from ..inverse.merge import SCATTER_FLOOR_FRACTION as SCATTER_FLOOR_FRACTION
from ..inverse.merge import leave_one_out_deviation as leave_one_out_deviation
from ..inverse.merge import merge_readings as merge_readings
from ..inverse.merge import quantity_kind as _kind
from ..inverse.merge import user_unit as _user_unit
from .csvtable import decimal_point as decimal_point
from .csvtable import iter_rows
from .csvtable import read_text as read_text
from .csvtable import sniff_delimiter as sniff_delimiter
from .csvtable import split_line as split_line

#: unit -> factor to SI (m or rad)
LINEAR_UNITS = {"µm": 1e-6, "um": 1e-6, "μm": 1e-6, "mm": 1e-3, "nm": 1e-9, "in": 0.0254,
                "µin": 0.0254e-6, "uin": 0.0254e-6, "μin": 0.0254e-6}
ANGULAR_UNITS = {
    "µm/m": 1e-6, "um/m": 1e-6, "μm/m": 1e-6, "µrad": 1e-6, "urad": 1e-6, "μrad": 1e-6,
    "mrad": 1e-3, "mm/m": 1e-3, "arcsec": math.pi / (180 * 3600),
    "arcmin": math.pi / (180 * 60), "deg": math.pi / 180, "°": math.pi / 180, "rad": 1.0,
}
#: Other spellings of the units above (read case-insensitively, spaces removed).
UNIT_SPELLINGS = {"µ": "µm", "micron": "µm", "microns": "µm", "mic": "µm", "inch": "in",
                  "µm/1m": "µm/m", "um/1m": "µm/m", "μm/1m": "µm/m", "micron/m": "µm/m",
                  "µradian": "µrad", "sec": "arcsec", '"': "arcsec", "min": "arcmin",
                  "'": "arcmin", "degree": "deg", "degrees": "deg", "mm/1000mm": "mm/m",
                  "arc-sec": "arcsec", "arcsecond": "arcsec", "arcseconds": "arcsec",
                  "arc-min": "arcmin", "inches": "in", "microinch": "µin", "microinches": "µin",
                  "µinch": "µin", "radian": "rad", "radians": "rad"}
INSTRUMENTS = ("level", "interferometer")
REQUIRED = ("position_mm", "point", "x_mm", "y_mm", "quantity", "value", "unit")
OPTIONAL = ("sigma", "run", "direction", "instrument", "z_mm", "reference", "resolution")
_FORWARD = ("forward", "fwd", "f", "+", "+1", "1", "up", "positive", "pos")
_BACKWARD = ("backward", "bwd", "b", "reverse", "rev", "r", "-", "-1", "down", "negative", "neg")
#: Largest plausible |reading| (SI): 10 mrad = 10000 µm/m for an angle, 10 mm = 10000 µm for a
#: linear error — far beyond any guideway's errors (a few to a few hundred µm, µm/m), and the
#: limit ``simulate --rails`` puts on a rail's deviation (±10000 µm). A larger number is a unit or
#: export mistake, not a reading: it is refused, not set aside as an outlier.
VALUE_LIMIT = {"angular": 1e-2, "linear": 1e-2}
#: Field separators recognised (the header line decides: tab, then ';', else ',').
DELIMITERS = ("\t", ";", ",")


class _RowError(ValueError):
    pass


def _field_error(field, value, why, allowed=None):
    text = f"field '{field}': {why}, got {value!r}"
    if allowed:
        text += f" (allowed {allowed})"
    raise _RowError(text)


def _number(row, field, unit_hint):
    raw = row[field].strip()
    try:
        v = float(raw)
    except ValueError:
        _field_error(field, raw, "not a number", f"a finite number in {unit_hint}")
    if not math.isfinite(v):
        _field_error(field, raw, "not finite", f"a finite number in {unit_hint}")
    return v


_DECIMAL = re.compile(r"^[+-]?(?:\d+\.?(\d*)|\.(\d+))(?:[eE]([+-]?\d+))?$")


def written_step(raw: str) -> float:
    """The unit of the last digit of a number as written (``"1.250"`` → 0.001, ``"12"`` → 1,
    ``"1.5e-3"`` → 1e-4), in the number's own unit; 0 when the text is not a plain decimal."""
    m = _DECIMAL.match(raw.strip())
    if not m:
        return 0.0
    decimals = len(m[1] or m[2] or "") - int(m[3] or 0)
    return 10.0 ** -decimals


def unit_key(unit: str, units: dict) -> str:
    """The key of ``units`` that ``unit`` spells (``"UM/M"``, ``"µm / m"``, ``"micron"``...);
    ``unit`` itself when it is none."""
    if unit in units:
        return unit
    u = unit.replace(" ", "").lower().replace("μ", "µ")
    u = UNIT_SPELLINGS.get(u, u)
    for k in units:
        if k.lower() == u:
            return k
    return unit


def _plausible(row, field, unit, factor, quantity) -> float:
    """``row[field]`` in SI, refused beyond ``±limit`` (:data:`VALUE_LIMIT`), the allowed range
    said in the row's unit and in µm or µm/m."""
    limit = VALUE_LIMIT[_kind(quantity)]
    v = _number(row, field, unit) * factor
    if abs(v) > limit:
        _field_error(field, row[field].strip(), "not a plausible reading",
                     f"-{limit / factor:.6g} to {limit / factor:.6g} {unit}, i.e. "
                     f"±{limit * 1e6:g} {_user_unit(quantity)}: more is no guideway's error, "
                     "check the unit")
    return v


def _parse_row(row: dict, line: int) -> Reading:
    position = _number(row, "position_mm", "mm") * 1e-3
    point = row["point"].strip()
    if not point:
        _field_error("point", row["point"], "empty", "a non-empty point name")
    xy = (_number(row, "x_mm", "mm") * 1e-3, _number(row, "y_mm", "mm") * 1e-3)
    quantity = row["quantity"].strip().upper()
    if quantity not in QUANTITIES:
        _field_error("quantity", row["quantity"], "unknown quantity", ", ".join(QUANTITIES))
    units = LINEAR_UNITS if quantity in LINEAR else ANGULAR_UNITS
    unit = row["unit"].strip()
    key = unit_key(unit, units)
    if key not in units:
        allowed = ", ".join(u for u in units if "μ" not in u)
        _field_error("unit", unit, f"not a unit of {quantity}", allowed)
    factor = units[key]
    value = _plausible(row, "value", unit, factor, quantity)
    steps = [written_step(row["value"])]
    if (row.get("reference") or "").strip():  # differential pair: measuring minus reference
        value -= _plausible(row, "reference", unit, factor, quantity)
        steps.append(written_step(row["reference"]))
    if (row.get("resolution") or "").strip():  # the stated rounding step replaces the digits'
        step = _number(row, "resolution", unit)
        limit = VALUE_LIMIT[_kind(quantity)]
        if not 0 <= step * factor <= limit:
            _field_error("resolution", row["resolution"].strip(), "not a plausible rounding step",
                         f"0 (unknown) or more, up to {limit / factor:.6g} {unit}")
        steps = [step] * len(steps)
    resolution = math.sqrt(sum(q * q for q in steps) / 12) * factor if all(steps) else 0.0
    sigma = None
    if (row.get("sigma") or "").strip():
        sigma = _number(row, "sigma", unit) * factor
        limit = VALUE_LIMIT[_kind(quantity)]
        if not 0 < sigma <= limit:
            _field_error("sigma", row["sigma"].strip(), "not a plausible σ",
                         f"> 0 and up to {limit / factor:.6g} {unit}, i.e. "
                         f"{limit * 1e6:g} {_user_unit(quantity)}, the readings' own limit")
    run = (row.get("run") or "").strip() or "1"
    d = (row.get("direction") or "").strip().lower() or "forward"
    if d in _FORWARD:
        direction = "forward"
    elif d in _BACKWARD:
        direction = "backward"
    else:
        _field_error("direction", row["direction"], "unknown direction",
                     "forward/fwd/+, backward/bwd/reverse/-")
    instrument = (row.get("instrument") or "").strip().lower() or _default_instrument(quantity)
    if instrument not in INSTRUMENTS:
        _field_error("instrument", row["instrument"], "unknown instrument", ", ".join(INSTRUMENTS))
    if instrument == "level" and quantity not in ("EAX", "EBX"):
        _field_error("instrument", row["instrument"], f"a level cannot measure {quantity}",
                     "level for EAX/EBX, interferometer for any quantity")
    z = 0.0
    if (row.get("z_mm") or "").strip():
        z = _number(row, "z_mm", "mm") * 1e-3
        if not abs(z) <= 2.0:
            _field_error("z_mm", row["z_mm"], "out of range", "-2000 to 2000 mm")
    return Reading(line, position, point, xy, quantity, value, key, sigma, run, direction,
                   instrument, z, resolution)


def read_readings(path: str | os.PathLike, x0_mm: float = 0.0,
                  notes: list | None = None) -> tuple[Reading, ...]:
    """Validated rows of a measurement CSV (not merged). Raises ``ValueError`` on bad input."""
    return parse_readings(read_text(path), os.fspath(path), x0_mm=x0_mm, notes=notes)


def parse_readings(text: str, name: str = "<text>", x0_mm: float = 0.0,
                   notes: list | None = None) -> tuple[Reading, ...]:
    """Validated rows from the text of a long measurement CSV (module docstring).

    The CSV rules are :mod:`diffguide.io.csvtable`'s (separator sniffed from the header line,
    decimal comma with ``;`` or tab, ``#`` comments, other columns ignored and named in
    ``notes`` unless close to a column of the format). ``x0_mm``: the machine coordinate of the
    table position x = 0 (subtracted from ``position_mm``).
    """
    readings = []
    points: dict[str, tuple[tuple[float, float], int]] = {}
    paired: dict[tuple[str, str, str], tuple[bool, int]] = {}  # channel: (reference?, line)
    header_line = None
    for number, row in iter_rows(text, name, REQUIRED, OPTIONAL, notes):
        header_line = header_line or number
        try:
            reading = _parse_row(row, number)
        except _RowError as exc:
            raise ValueError(f"{name}:{number}: {exc}") from None
        if x0_mm:
            reading = dataclasses.replace(reading, position=reading.position - x0_mm * 1e-3)
        prev = points.get(reading.point)
        if prev is None:
            points[reading.point] = (reading.xy, number)
        elif max(abs(a - b) for a, b in zip(prev[0], reading.xy)) > 1e-9:
            raise ValueError(
                f"{name}:{number}: field 'x_mm'/'y_mm': point {reading.point!r} is at "
                f"({reading.xy[0] * 1e3:g}, {reading.xy[1] * 1e3:g}) mm here but at "
                f"({prev[0][0] * 1e3:g}, {prev[0][1] * 1e3:g}) mm on line {prev[1]} (allowed: "
                "one location per point name)"
            )
        if "reference" in row:
            _check_pairing(row, reading, paired, name, number)
        readings.append(reading)
    if not readings:
        raise ValueError(f"{name}:{_header_line(text)}: no data rows after the header")
    note_repeats(readings, name, notes)
    return tuple(readings)


def _check_pairing(row, reading, paired, name, number) -> None:
    """A channel is a differential pair on every row or on none: an empty ``reference`` cell in
    a paired channel would be read as a reference level at 0."""
    has = bool(row["reference"].strip())
    channel = (reading.point, reading.quantity, reading.instrument)
    prev = paired.setdefault(channel, (has, number))
    if prev[0] != has:
        what = ("empty, but line {} of the same channel has one" if prev[0] else
                "a reference reading, but line {} of the same channel has none").format(prev[1])
        raise ValueError(
            f"{name}:{number}: field 'reference': {what} ({reading.quantity} at {reading.point}, "
            f"{reading.instrument}; allowed: a reference reading on every row of a channel — a "
            "differential pair — or on none)"
        )


def note_repeats(readings, name: str, notes: list | None) -> None:
    """A note in ``notes`` when readings repeat the position (to 1 µm), point, quantity,
    instrument, run and direction of an earlier one — a row pasted twice, or runs not told apart
    by a ``run`` label: they are merged as further readings of that run, which is what the
    merge would do with distinct runs too, but it is said (the first 10 lines, each with the
    line it repeats)."""
    if notes is None:
        return
    first, pairs, count = {}, [], 0
    for r in readings:
        key = (round(r.position * 1e6), r.point, r.quantity, r.instrument, r.run, r.direction)
        if key not in first:
            first[key] = r.line
            continue
        count += 1
        if (r.line, first[key]) not in pairs:
            pairs.append((r.line, first[key]))
    if count:
        shown = ", ".join(f"{line} (as {was})" for line, was in pairs[:10])
        more = " ..." if len(pairs) > 10 else ""
        notes.append(
            f"{name}: {count} reading(s) repeat the position, point, quantity, instrument, run "
            f"and direction of an earlier one, on line(s) {shown}{more}: merged as further "
            "readings (if they are separate runs, give each its own 'run' label)"
        )


def _header_line(text: str) -> int:
    for number, line in enumerate(text.splitlines(), start=1):
        if line.strip() and not line.strip().startswith("#"):
            return number
    return 1


def read_measurements(path: str | os.PathLike, x0_mm: float = 0.0,
                      notes: list | None = None, *,
                      allow_many_positions: bool = False) -> Measurements:
    """Read, validate and merge a long measurement CSV (see the module docstring); SI units.
    More than :data:`~diffguide.inverse.merge.MAX_POSITIONS` distinct positions (the position and
    value columns swapped, as a rule) raise ``ValueError`` unless ``allow_many_positions``.
    Other layouts: :func:`diffguide.io.importers.read_any`."""
    return merge_readings(read_readings(path, x0_mm, notes), source=os.fspath(path), notes=notes,
                          allow_many_positions=allow_many_positions)


def format_csv(rows: list[dict], columns: tuple[str, ...]) -> str:
    """A CSV text with ``columns`` from ``rows`` (dicts; floats written with 10 significant
    digits)."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(columns)
    for row in rows:
        w.writerow([f"{v:.10g}" if isinstance(v, float) else v for v in (row[c] for c in columns)])
    return out.getvalue()
