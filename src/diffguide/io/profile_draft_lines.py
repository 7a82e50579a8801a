"""The pieces of a draft profile (:mod:`.profile_draft`): its lines and the keys left to write,
and the lines every layout shares — the point and its place, x0, the instrument, the words of
a direction — each written from what the file states, else marked ``# REQUIRED`` with the value
``"?"``, or ``# CHECK`` where it is a guess."""

import json
import re

from .measurements import _BACKWARD, _FORWARD, ANGULAR_UNITS, LINEAR_UNITS, unit_key
from .profile_words import DIRECTION_WORDS, INSTRUMENT_WORDS
#: the placeholder of a value the user must write (refused by the profile loader)
TODO = "?"
_NUMBER = re.compile(r"^[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?$")
_BRACKET = re.compile(r"[(\[]\s*([^)\]]*?)\s*[)\]]")
_SEPARATORS = (("\t", "tab"), (";", ";"), (",", ","), (" ", "whitespace"))


def _q(text) -> str:
    """A TOML basic string (JSON's escaping is TOML's for these)."""
    return json.dumps(str(text), ensure_ascii=False)


def _lit(text: str) -> str:
    """A TOML literal string for a regular expression (no escapes)."""
    return f"'{text}'" if "'" not in text else _q(text)


def _split(line: str, sep: str) -> list[str]:
    import csv
    import io

    if sep == " ":
        return line.split()
    try:
        return [f.strip().strip('"') for f in next(csv.reader(io.StringIO(line), delimiter=sep))]
    except (csv.Error, StopIteration):
        return [line]


def _num(text: str, comma: bool) -> bool:
    t = text.strip().replace("\u2212", "-")
    if comma and re.fullmatch(r"[+-]?\d*,\d+(?:[eE][+-]?\d+)?", t):
        t = t.replace(",", ".")
    return bool(_NUMBER.match(t))


def _unit_of(header: str) -> str | None:
    """The unit in a column name's brackets, as diffguide spells it; ``None``: none known."""
    for m in _BRACKET.finditer(header):
        for units in (LINEAR_UNITS, ANGULAR_UNITS):
            if unit_key(m.group(1), units) in units:
                return m.group(1)
    return None


class _Draft:
    """The lines of the draft, and the keys still to write."""

    def __init__(self, source: str):
        self.top, self.table, self.reading, self.values, self.aliases = [], [], [], [], {}
        self.required, self.source = [], source

    def need(self, section: list, key: str, why: str, where: str) -> None:
        section.append(f"{key} = {_q(TODO)}  # REQUIRED: {why}")
        self.required.append(where)

    def alias(self, field: str, word: str, value: str | None, why: str = "") -> None:
        words = self.aliases.setdefault(field, [])
        if value is None:
            words.append(f"{_q(word)} = {_q(TODO)}  # REQUIRED: {why}")
            self.required.append(f"aliases.{field}.{word}")
        else:
            words.append(f"{_q(word)} = {_q(value)}")

    def text(self, header_comment: list[str]) -> str:
        out = [f"# {c}" if c else "#" for c in header_comment]
        out += self.top + ["", "[table]", *self.table, "", "[reading]", *self.reading]
        for spec in self.values:
            out += ["", "[[values]]", *spec]
        for field, words in self.aliases.items():
            out += ["", f"[aliases.{field}]", *words]
        return "\n".join(out) + "\n"


def _points_comment(points: dict | None) -> list[str]:
    if not points:
        return ["#   (the machine's control points: 'diffguide config', [points]; or pass "
                "--config/--preset to list them here)"]
    return ["#   the machine's control points (name = x, y mm from the table centre):"] + [
        f"#     {n} = {x:g}, {y:g}" for n, (x, y) in points.items()]


def _point_lines(d: _Draft, meta_roles: dict, columns: dict, points) -> None:
    """point, x_mm, y_mm (and z_mm) from a column, a metadata line, or REQUIRED."""
    for field, what in (("point", "the control point the readings are at (a name of the "
                                  "machine's [points])"),
                        ("x_mm", "x of that point on the table top (mm from its centre)"),
                        ("y_mm", "y of that point on the table top (mm from its centre)")):
        if field in columns:
            d.reading.append(f"{field}_column = {_q(columns[field])}")
        elif field in meta_roles:
            d.reading.append(f"{field}_meta = {_q(meta_roles[field])}")
        else:
            d.need(d.reading, field, what, f"reading.{field}")
    if "z_mm" in meta_roles:
        d.reading.append(f"z_mm_meta = {_q(meta_roles['z_mm'])}")
    if not ({"point", "x_mm", "y_mm"} <= (set(columns) | set(meta_roles))):
        d.reading += _points_comment(points)


def _x0_lines(d: _Draft, positions: list[float], meta_roles: dict, unit_in: bool) -> None:
    if "x0_mm" in meta_roles:
        d.top.append(f"x0_mm_meta = {_q(meta_roles['x0_mm'])}")
        return
    mm = [p * (25.4 if unit_in else 1.0) for p in positions]
    lo, hi = min(mm), max(mm)
    if lo < 0.0 < hi:  # mid-stroke x = 0 (targets from 0 are machine coordinates)
        d.top.append("x0_mm = 0.0  # CHECK: the machine coordinate (mm) of the table position "
                     f"x = 0 (mid-stroke); the targets run {lo:g} … {hi:g} mm")
    else:
        d.need(d.top, "x0_mm", f"the machine coordinate (mm) of the table position x = 0 "
               f"(mid-stroke): the targets run {lo:g} … {hi:g} mm; a number, or \"middle\" "
               f"(here {(lo + hi) / 2:g})", "x0_mm")


def _instrument_line(d: _Draft, meta_roles: dict, meta: dict, text: str, quantities) -> None:
    if "instrument" in meta_roles and meta[meta_roles["instrument"]].strip().lower() in (
            "level", "interferometer"):
        d.reading.append(f"instrument_meta = {_q(meta_roles['instrument'])}")
        return
    low = text.lower()
    for inst, words in INSTRUMENT_WORDS.items():
        hit = next((w for w in words if re.search(rf"\b{w}", low)), None)
        if hit:
            d.reading.append(f"instrument = {_q(inst)}  # CHECK: guessed from {hit!r} in the "
                             "file (level or interferometer)")
            return
    if quantities and all(q in ("EAX", "EBX") for q in quantities):
        d.reading.append('instrument = "level"  # CHECK: level or interferometer')
    elif quantities:
        d.reading.append('instrument = "interferometer"  # CHECK: level or interferometer')
    else:
        d.reading.append("# instrument = \"level\"  # or \"interferometer\" (default: level for "
                         "EAX, EBX, interferometer otherwise)")


def _direction_aliases(d, words) -> None:
    for word in sorted(words, key=str.lower):
        w = word.lower()
        if w in _FORWARD + _BACKWARD:
            continue
        if w in DIRECTION_WORDS:
            d.alias("direction", word, DIRECTION_WORDS[w])
        else:
            d.alias("direction", word, None, '"forward" or "backward"')
