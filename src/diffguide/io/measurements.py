r"""Measured joint kinematic errors: read, validate and merge a measurement CSV.

File format (UTF-8, one header line; blank lines and lines starting with ``#`` are skipped; the
separator is ``,``, ``;`` or tab, sniffed from the header line; with ``;`` or tab a decimal
comma is read; other layouts: :mod:`diffguide.io.importers`)::

    position_mm,point,x_mm,y_mm,quantity,value,unit[,sigma][,run][,direction][,instrument][,z_mm]
    [,reference][,resolution]

- ``position_mm``: table position ``x`` (mm). ``point``: the control point's name; ``x_mm``,
  ``y_mm``: where it is on the table top (mm, from the table centre; the same for every row of
  a point).
- ``quantity``: ``EXX``, ``EYX``, ``EZX`` (``µm``/``um``, ``mm``, ``nm``, ``in``) or ``EAX``,
  ``EBX``, ``ECX`` (``µm/m``/``um/m``, ``µrad``/``urad``, ``mrad``, ``mm/m``, ``arcsec``,
  ``arcmin``, ``deg``; case and spaces do not matter). ``value`` and ``sigma`` (> 0,
  the standard uncertainty of *one reading*) are in ``unit``; ``value`` (and ``reference``) within
  ±10000 µm for a linear error, ±10000 µm/m (10 mrad) for an angle (:data:`VALUE_LIMIT`); a
  stated ``sigma`` must be > 0 and within the same limit.
- ``run``: a label of the run (default: one run); rows that repeat the position, point,
  quantity, instrument, run and direction of an earlier row are merged as further readings and
  named in a note (:func:`note_repeats`). ``direction``: ``forward``/``+``/``fwd``/
  ``positive`` or ``backward``/``reverse``/``-``/``bwd``/``negative`` (default: forward).
- ``reference``: a differential level pair's reference level reading (in ``unit``): the reading
  used is ``value − reference`` (measuring minus reference level); a channel has it on every
  row or on none (an empty cell among paired rows is an error, not a reference of 0). Its noise
  is not added to the default σ: with enough runs the pooled scatter (step 3) includes it.
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
  rounding (the floor of step 3 below).

Merging (what a metrologist does with ISO 230-2 style runs), per channel = (point, quantity,
instrument) — so a level and an interferometer at one point are two channels, each with its own
zero — and position:

0. gross outliers are set aside: within each direction at a position, with at least
   :data:`MIN_RUNS_FOR_OUTLIERS` runs, a reading further than :data:`OUTLIER_Z` robust standard
   deviations from the median of the other readings (the scale: 1.4826 × the median of that
   same distance over the channel) is not used, and reported (:attr:`Measurements.rejected`);
1. the readings of each direction are averaged over the runs;
2. the value is the mean of the forward and backward means (so unequal run counts do not bias it;
   the reversal value, forward − backward, is kept for the report);
3. the standard uncertainty of one reading is, in this order: the ``sigma`` column; else the
   repeatability from the scatter — the pooled within-direction standard deviation over *all*
   positions of the channel, when it has at least :data:`MIN_SCATTER_DOF` degrees of freedom (a
   per-position scatter from five runs would be too noisy: its inverse square biases χ² by
   ν/(ν−2)), but never below the channel's *floor* (below); else the instrument default
   (:data:`DEFAULT_SIGMA`: 4 µm/m for levels, 2 µm/m for interferometers, 1 µm for linear
   interferometer optics);

   the floor is the larger of (a) the rounding of the written readings — half a unit of the last
   digit written, ``q/2``, uniform: ``q/√12`` (GUM F.2.2.1), ``q`` the finest step among the
   channel's readings (a writer that strips trailing zeros writes some readings coarser), in
   quadrature for a differential pair — and (b) :data:`SCATTER_FLOOR_FRACTION` (1/10) of the
   instrument default: 0.4 µm/m for a level, 0.2 µm/m for angular and 0.1 µm for linear
   interferometer optics, about the resolution class of these instruments and finer than any
   repeatability a machine tool's axis shows over runs. A smaller pooled scatter (runs that agree
   to rounding, or a resolution coarser than the file shows) is not a repeatability: it would
   give the channel a weight the data do not have. The rows are then marked ``"floor"`` in
   :attr:`Measurements.sigma_source` and a note names the channel;
4. the merged value's σ follows from step 2: ``σ_m² = ¼ (σ²/n_f + σ²/n_b)`` (``σ²/n`` with one
   direction) — except where a channel's runs are **identical at (nearly) every position**: in
   :data:`COPIES_FRACTION` (80 %) or more of its (position, direction) groups of more than one
   reading (copies of one
   run, perhaps with a reading edited, or a display coarser than the noise): their mean is no
   better than one reading and they say nothing of the repeatability, so each direction counts
   as one reading (``n = 1``) with the ``sigma`` column or else the instrument default (never
   below the readings' rounding); the rows' source then includes ``copies``
   (``"copies+default"``, ``"column+copies"``) and a note names the channel. (Copying one noisy
   run of the bundled data's yaw five times gave, with the floor, χ²/dof 1.9, no convergence
   and rails 5.6 µm off; merged as one run the fit is as good as with the real runs. Before the
   80 % rule, copies with one reading changed took the floor branch: 10–30× the weight of exact
   copies, for the same information.) Real runs agree exactly at a position only when their
   noise is below the display step; at 80 % of the positions it is well below it, and the
   rounding, which the runs share, then dominates the mean's error.

Every row is validated; a bad row raises one ``ValueError`` ``"FILE:LINE: field 'f': ... (allowed
...)"``. Values are converted to SI (m, rad).
"""

import csv
import dataclasses
import io
import math
import os
import re
from collections import defaultdict

import numpy as np

from ..inverse.data import LINEAR, QUANTITIES, Measurements
from ..inverse.data import default_instrument as _default_instrument
from .csvtable import decimal_point as decimal_point
from .csvtable import iter_rows
from .csvtable import read_text as read_text
from .csvtable import sniff_delimiter as sniff_delimiter
from .csvtable import split_line as split_line

#: unit -> factor to SI (m or rad)
LINEAR_UNITS = {"µm": 1e-6, "um": 1e-6, "μm": 1e-6, "mm": 1e-3, "nm": 1e-9, "in": 0.0254}
ANGULAR_UNITS = {
    "µm/m": 1e-6, "um/m": 1e-6, "μm/m": 1e-6, "µrad": 1e-6, "urad": 1e-6, "μrad": 1e-6,
    "mrad": 1e-3, "mm/m": 1e-3, "arcsec": math.pi / (180 * 3600),
    "arcmin": math.pi / (180 * 60), "deg": math.pi / 180, "°": math.pi / 180,
}
#: Other spellings of the units above (read case-insensitively, spaces removed).
UNIT_SPELLINGS = {"µ": "µm", "micron": "µm", "microns": "µm", "mic": "µm", "inch": "in",
                  "µm/1m": "µm/m", "um/1m": "µm/m", "μm/1m": "µm/m", "micron/m": "µm/m",
                  "µradian": "µrad", "sec": "arcsec", '"': "arcsec", "min": "arcmin",
                  "'": "arcmin", "degree": "deg", "degrees": "deg", "mm/1000mm": "mm/m"}
INSTRUMENTS = ("level", "interferometer")
#: Repeatability of one reading when the file gives no sigma and there are too few runs (SI).
DEFAULT_SIGMA = {("level", "angular"): 4e-6, ("interferometer", "angular"): 2e-6,
                 ("interferometer", "linear"): 1e-6}
#: Degrees of freedom a channel's pooled scatter needs before it replaces the default σ.
MIN_SCATTER_DOF = 20
#: A channel whose runs are identical at this fraction of the positions read more than once (or
#: more) is merged as copies of one run (module docstring, step 4).
COPIES_FRACTION = 0.8
#: The pooled scatter's floor, as a fraction of :data:`DEFAULT_SIGMA` (module docstring, step 3;
#: the rounding of the written readings is the other floor).
SCATTER_FLOOR_FRACTION = 0.1
#: Readings per direction and position needed before a reading can be called an outlier.
MIN_RUNS_FOR_OUTLIERS = 3
#: Distance from the median of the other readings (robust σ) beyond which a reading is an outlier.
OUTLIER_Z = 6.0

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


@dataclasses.dataclass(frozen=True)
class Reading:
    """One validated row of the file (SI units; ``line`` is its line number)."""

    line: int
    position: float
    point: str
    xy: tuple[float, float]
    quantity: str
    value: float
    unit: str
    sigma: float | None
    run: str
    direction: str  # "forward" or "backward"
    instrument: str
    z: float = 0.0  # height of the sensing point above the table top (m)
    #: standard uncertainty of the rounding of the value as written (SI; ``q/√12``, ``q`` a unit
    #: of its last digit; a differential pair's two roundings in quadrature; 0: unknown)
    resolution: float = 0.0


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


def _reject_outliers(groups) -> set[int]:
    """``id``s of gross outliers (module docstring, step 0). The statistic of a reading is its
    distance from the median of the *other* readings of its direction at that position; its
    robust scale, pooled over the channel, is 1.4826 × the median of the same statistic, so the
    ratio is a standard normal deviate for clean data whatever the run count."""
    dev = defaultdict(list)
    stats = []  # (channel, rows, statistics) of every group with enough runs
    for (p, q, inst, _), dirs in groups.items():
        for rows in dirs.values():
            if len(rows) >= MIN_RUNS_FOR_OUTLIERS:
                d = leave_one_out_deviation(np.array([r.value for r in rows]))
                dev[(p, q, inst)].append(d)
                stats.append(((p, q, inst), rows, d))
    scale = {k: 1.4826 * float(np.median(np.concatenate(d))) for k, d in dev.items()
             if sum(map(len, d)) >= 10}
    out = set()
    for key, rows, d in stats:
        sc = scale.get(key)
        if sc:
            out.update(id(r) for r, dk in zip(rows, d) if dk > OUTLIER_Z * sc)
    return out


def leave_one_out_deviation(v) -> np.ndarray:
    """``|v_k − median(v without v_k)|`` for every ``k``, without a median per ``k``: the median
    of the other ``n − 1`` values is one order statistic of ``v`` (two, averaged, when ``n − 1``
    is even), the ``j``-th of the others being the ``j``-th of ``v`` below ``v_k``'s rank and
    the ``(j+1)``-th from it on."""
    v = np.asarray(v, dtype=float)
    n = v.size
    order = np.argsort(v, kind="stable")
    s = v[order]
    rank = np.empty(n, dtype=int)
    rank[order] = np.arange(n)

    def others(j: int) -> np.ndarray:
        return s[np.where(j < rank, j, j + 1)]

    m = n - 1
    med = others((m - 1) // 2) if m % 2 else 0.5 * (others(m // 2 - 1) + others(m // 2))
    return np.abs(v - med)


def _kind(quantity: str) -> str:
    return "linear" if quantity in LINEAR else "angular"


def _user_unit(quantity: str) -> str:
    return "µm" if quantity in LINEAR else "µm/m"


def merge_readings(readings, source: str = "<readings>",
                   notes: list | None = None) -> Measurements:
    """Merge runs and directions (see the module docstring) into :class:`Measurements`.

    ``notes`` (a list) receives a line for every channel whose pooled scatter was raised to its
    floor (step 3) and for every channel merged as copies of one run (step 4)."""
    readings = tuple(readings)
    if not readings:
        raise ValueError(f"{source}: no measurements")
    names, xy = [], []
    for r in readings:
        if r.point not in names:
            names.append(r.point)
            xy.append(r.xy)
    # positions are grouped on a 1 µm grid (files often print 100.0 and 100.0001)
    groups: dict[tuple, dict[str, list[Reading]]] = defaultdict(lambda: {"forward": [],
                                                                         "backward": []})
    for r in readings:
        key = (names.index(r.point), QUANTITIES.index(r.quantity), r.instrument,
               round(r.position * 1e6))
        groups[key][r.direction].append(r)
    rejected = _reject_outliers(groups)
    if rejected:
        for dirs in groups.values():
            for d in dirs:
                dirs[d] = [r for r in dirs[d] if id(r) not in rejected]
    # repeatability of one reading per channel from the within-direction scatter
    ss, dof = defaultdict(float), defaultdict(int)
    repeated, same = defaultdict(int), defaultdict(int)  # positions read more than once; alike
    for (p, q, inst, _), dirs in groups.items():
        for rows in dirs.values():
            if len(rows) > 1:
                v = np.array([r.value for r in rows])
                ss[(p, q, inst)] += float(np.sum((v - v.mean()) ** 2))
                dof[(p, q, inst)] += len(rows) - 1
                repeated[(p, q, inst)] += 1
                same[(p, q, inst)] += int(np.ptp(v) == 0.0)
    # runs identical at (nearly) every position: copies of one run (or a display coarser than
    # the noise), which carry the information of one run — merged as one reading per direction
    copies = {ch for ch in dof if same[ch] >= COPIES_FRACTION * repeated[ch]}
    for p, q, inst in sorted(copies) if notes is not None else ():
        quantity = QUANTITIES[q]
        stated = any(r.sigma is not None for (pp, qq, ii, _), dirs in groups.items()
                     if (pp, qq, ii) == (p, q, inst) for rows in dirs.values() for r in rows)
        one = ("its sigma column" if stated else
               f"the instrument's default {DEFAULT_SIGMA[(inst, _kind(quantity))] * 1e6:g} "
               f"{_user_unit(quantity)} (or the readings' rounding, if coarser)")
        where = ("every position read more than once" if same[(p, q, inst)] == repeated[
            (p, q, inst)] else f"{same[(p, q, inst)]} of the {repeated[(p, q, inst)]} "
            "position-and-direction groups read more than once")
        notes.append(f"{source}: {quantity} at {names[p]} ({inst}): the runs are identical at "
                     f"{where} (copies of one run, or a display coarser than the noise?): "
                     f"merged as one run, σ of one reading {one}")
    # the finest rounding step written in each channel (0: unknown)
    res = {}
    for (p, q, inst, _), dirs in groups.items():
        for rows in dirs.values():
            for r in rows:
                if r.resolution > 0:
                    res[(p, q, inst)] = min(res.get((p, q, inst), math.inf), r.resolution)
    scatter, floored = {}, set()
    for ch in sorted(dof):
        if dof[ch] < MIN_SCATTER_DOF or ch in copies:
            continue
        p, q, inst = ch
        quantity = QUANTITIES[q]
        s = math.sqrt(ss[ch] / dof[ch])
        floor = max(res.get(ch, 0.0),
                    SCATTER_FLOOR_FRACTION * DEFAULT_SIGMA[(inst, _kind(quantity))])
        if s < floor:
            floored.add(ch)
            if notes is not None:
                u = _user_unit(quantity)
                notes.append(
                    f"{source}: {quantity} at {names[p]} ({inst}): the runs' pooled scatter "
                    f"{s * 1e6:.3g} {u} ({dof[ch]} degrees of freedom) is below the floor "
                    f"{floor * 1e6:.3g} {u} (the larger of the readings' rounding and "
                    f"{SCATTER_FLOOR_FRACTION:g} × the instrument's default σ): identical runs? "
                    "σ of one reading set to the floor"
                )
            s = floor
        scatter[ch] = s
    keys = sorted((k for k, d in groups.items() if d["forward"] or d["backward"]),
                  key=lambda k: (k[0], k[1], k[2], k[3]))
    cols = defaultdict(list)
    row_of = {}
    for k, key in enumerate(keys):
        p, q, inst, _ = key
        ch = (p, q, inst)
        dirs = groups[key]
        rows = dirs["forward"] + dirs["backward"]
        zs = {round(r.z * 1e6) for r in rows}
        if len(zs) > 1:
            r0 = rows[-1]
            raise ValueError(
                f"{source}:{r0.line}: field 'z_mm': {names[p]} {QUANTITIES[q]} ({inst}) at "
                f"{r0.position * 1e3:g} mm is read at several heights (allowed: one height per "
                "point, quantity and instrument; use another point name)"
            )
        means, var = [], []
        sources = set()
        for d in ("forward", "backward"):
            rs = dirs[d]
            if not rs:
                continue
            n = len(rs)
            means.append(float(np.mean([r.value for r in rs])))
            sig = []
            for r in rs:
                if r.sigma is not None:
                    sig.append(r.sigma)
                    sources.add("column")
                elif ch in scatter:
                    sig.append(scatter[ch])
                    sources.add("floor" if ch in floored else "scatter")
                else:
                    default = DEFAULT_SIGMA[(inst, _kind(QUANTITIES[q]))]
                    sig.append(max(default, res.get(ch, 0.0)) if ch in copies else default)
                    sources.add("default")
            if ch in copies:  # one reading's worth: the mean of copies is no better than one
                sources.add("copies")
                var.append(float(np.mean(np.square(sig))))
            else:
                var.append(float(np.sum(np.square(sig))) / n**2)
        value = float(np.mean(means))
        sigma = math.sqrt(sum(var)) / len(var)  # > 0: every σ above is
        cols["position"].append(rows[0].position)
        cols["point"].append(p)
        cols["quantity"].append(q)
        cols["value"].append(value)
        cols["sigma"].append(sigma)
        cols["n"].append(len(rows))
        cols["reversal"].append(means[0] - means[1] if len(means) == 2 else math.nan)
        cols["instrument"].append(inst)
        cols["source"].append("+".join(sorted(sources)))
        cols["z"].append(rows[0].z)
        for r in rows:
            row_of[id(r)] = k
    return Measurements(
        point_names=tuple(names),
        points_xy=np.array(xy, float),
        position=np.array(cols["position"]),
        point=np.array(cols["point"], int),
        quantity=np.array(cols["quantity"], int),
        value=np.array(cols["value"]),
        sigma=np.array(cols["sigma"]),
        n_readings=np.array(cols["n"], int),
        reversal=np.array(cols["reversal"]),
        instrument=tuple(cols["instrument"]),
        sigma_source=tuple(cols["source"]),
        z=np.array(cols["z"]),
        readings=readings,
        row_of_reading=np.array([row_of.get(id(r), -1) for r in readings], int),
        rejected=tuple(sorted(r.line for r in readings if id(r) in rejected)),
        source=source,
    )


def read_measurements(path: str | os.PathLike, x0_mm: float = 0.0,
                      notes: list | None = None) -> Measurements:
    """Read, validate and merge a long measurement CSV (see the module docstring); SI units.
    Other layouts: :func:`diffguide.io.importers.read_any`."""
    return merge_readings(read_readings(path, x0_mm, notes), source=os.fspath(path), notes=notes)


def format_csv(rows: list[dict], columns: tuple[str, ...]) -> str:
    """A CSV text with ``columns`` from ``rows`` (dicts; floats written with 10 significant
    digits)."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(columns)
    for row in rows:
        w.writerow([f"{v:.10g}" if isinstance(v, float) else v for v in (row[c] for c in columns)])
    return out.getvalue()
