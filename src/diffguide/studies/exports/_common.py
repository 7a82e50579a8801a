"""What every compensation writer shares: the options, the sign rule, the header lines.

**Sign rule.** diffguide's errors are the motion of a point of the *table*, which carries the
workpiece (ISO 230-1 names, relative to x = 0), so the X axis sits on the workpiece side of the
kinematic chain. A controller adds a compensation value ``C`` to the position of the compensated
axis: that axis moves its own part (the tool or the workpiece) by ``C`` along its positive
direction. For the tool to stay where it should be on the workpiece:

- compensated axis on the **workpiece** side: it must move the workpiece back, ``C = −E``
  (pitch on X itself, or a cross table's Y);
- compensated axis on the **tool** side: the tool must follow the workpiece, ``C = +E``
  (a spindle head's Z on a machine whose table carries the workpiece).

This assumes that each axis counts positive along diffguide's +X, +Y, +Z (as ``X = x + x0``
does for X); an axis counting the other way flips its sign.
"""

import re
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..._core.comments import CommentSyntax
from . import settings
from .settings import AXIS_NAME as AXIS_NAME

SIDES = ("tool", "workpiece")
#: The compensating axis of each cross-axis error of the X axis.
CROSS_AXES = {"EYX": "Y", "EZX": "Z"}


@dataclass(frozen=True)
class ExportSpec:
    """A compensation export format with its options (pass it where a format name goes).

    Attributes:
        format: one of :data:`~diffguide.studies.exports.FORMATS`.
        axis_side: which side of the kinematic chain the compensating axes Y and Z sit on,
            ``{"Y": "tool" | "workpiece", "Z": ...}`` (a bare ``"tool"``/``"workpiece"`` means
            both); it decides the sign of a cross-axis table. X carries the workpiece.
        axis_names: the controller's names of X, Y, Z (``siemens-cec``: ``AX1``..``AX3``).
        table_name: the name a table carries inside its file (``heidenhain``: ``NAME.COM``).
        file_name: the exported file's name, for the configuration lines (``isg``).
        reference_mm: ``fanuc``: machine coordinate (mm) of the reference position; default
            the machine coordinate of x = 0.
        first_number: ``fanuc``: number of the first compensation point (0 to 1023).
        detection_unit_mm: ``fanuc``: detection unit (mm; IS-B 0.001, IS-C 0.0001).
        isg_axis_numbers: ``isg``, ``isg-cross``: the ISG logical axis numbers of X, Y, Z
            (P-VOLC-00001..3, ``kopf.achs_nr``); no default (the files say what to set).
        max_records: ``isg``: start-up ``vol_comp[0].max_records``; default the table's
            number of records.
        heidenhain_values, isg_cross_values: what a value of that format is:
            ``"compensation"`` (the controller adds it to the axis) or ``"error"`` (the
            controller subtracts it); unconfirmed from the documentation, so stated.
    """

    format: str
    axis_side: Mapping[str, str] | str | None = None
    axis_names: Mapping[str, str] = field(
        default_factory=lambda: {"X": "AX1", "Y": "AX2", "Z": "AX3"})
    table_name: str = "DGX"
    file_name: str = ""
    reference_mm: float | None = None
    first_number: int = 0
    detection_unit_mm: float = 0.001
    isg_axis_numbers: Mapping[str, int] | None = None
    max_records: int | None = None
    heidenhain_values: str = "compensation"
    isg_cross_values: str = "compensation"

    def __post_init__(self):
        """The settings (:mod:`.settings`) and the names the format writes outside its
        comments, checked (:func:`check_name`)."""
        for axis, name in dict(self.axis_names).items():
            check_name(name, f"axis_names[{axis!r}]", AXIS_NAME)
        names = settings.check("cec_axis_names", dict(self.axis_names), "axis_names")
        if set(names) != set(settings.AXES):
            raise ValueError(f"axis_names: {dict(self.axis_names)!r}: X, Y and Z need three "
                             "distinct names")
        object.__setattr__(self, "axis_names", names)
        object.__setattr__(self, "detection_unit_mm", settings.check(
            "fanuc_detection_unit", self.detection_unit_mm, "detection_unit_mm"))
        if self.isg_axis_numbers is not None:
            object.__setattr__(self, "isg_axis_numbers", settings.check(
                "isg_axis_numbers", dict(self.isg_axis_numbers), "isg_axis_numbers"))
        if self.max_records is not None:
            settings.check("isg_max_records", self.max_records, "max_records")
        settings.check("heidenhain_values", self.heidenhain_values, "heidenhain_values")
        settings.check("isg_cross_values", self.isg_cross_values, "isg_cross_values")
        if self.format == "heidenhain":
            check_name(self.table_name, "table_name", TABLE_NAME)
        if self.format in ("isg", "isg-cross") and self.file_name:
            check_name(self.file_name, "file_name", FILE_NAME)


#: the comment syntax of each file that holds comments (the .note.txt is plain text)
CSV_COMMENT = CommentSyntax("#", ascii_only=False)  # diffguide's own CSV (UTF-8)
ISG_COMMENT = CommentSyntax("//", reserved="#")  # '#' is ISG CSV's file break
LIS_COMMENT = CommentSyntax("#")
CEC_COMMENT = CommentSyntax(";")
FANUC_COMMENT = CommentSyntax("#")
NOTE_TEXT = CommentSyntax("", ascii_only=False)

#: names written on live lines (outside comments), refused rather than escaped otherwise
TABLE_NAME = re.compile(r"[A-Za-z0-9_-]+")  # a TNC table name (NAME.COM)
FILE_NAME = re.compile(r"[A-Za-z0-9_.+-]+")  # a file name on an ISG configuration line


def check_name(value, what: str, pattern: re.Pattern) -> str:
    """``value`` where ``pattern`` matches all of it, else ``ValueError`` naming ``what``."""
    if not isinstance(value, str) or not pattern.fullmatch(value):
        raise ValueError(f"{what} must match {pattern.pattern} (it is written outside a "
                         f"comment in the controller's file), got {value!r}")
    return value


def sides(axis_side) -> dict[str, str]:
    """``axis_side`` as ``{axis: side}`` for Y and Z (missing: unknown); ``ValueError`` on a
    bad axis or side."""
    if axis_side is None:
        return {}
    if isinstance(axis_side, str):
        axis_side = {"Y": axis_side, "Z": axis_side}
    out = {}
    for axis, side in axis_side.items():
        axis = str(axis).upper()
        if axis == "X":
            raise ValueError("axis_side: X carries the table, so the workpiece, in diffguide's "
                             "model; only Y and Z can be chosen")
        if axis not in ("Y", "Z") or side not in SIDES:
            raise ValueError(f"axis_side: {axis}={side!r} is not allowed (Y or Z = tool or "
                             "workpiece)")
        out[axis] = side
    return out


def parse_axis_side(text: str) -> dict[str, str]:
    """The CLI's ``--axis-side``: ``tool``, ``workpiece`` (Y and Z alike) or
    ``Y=workpiece,Z=tool``."""
    text = text.strip()
    if "=" not in text:
        return sides(text.lower())
    pairs = {}
    for item in text.split(","):
        axis, _, side = item.partition("=")
        pairs[axis.strip().upper()] = side.strip().lower()
    return sides(pairs)


def sign(side: str) -> float:
    """Compensation = ``sign(side) × error`` on an axis on ``side`` (module docstring)."""
    return -1.0 if side == "workpiece" else 1.0


def lead_line(exx_includes_lead) -> str:
    """What EXX holds, for a header."""
    if exx_includes_lead is True:
        return "EXX includes the fitted lead error of the drive (screw)"
    if exx_includes_lead is False:
        return ("EXX has no lead error: the errors come from a simulation with an ideal drive; "
                "a pitch table from it holds only the guideway's part of the positioning error")
    return ("EXX left out: whether it includes the lead error of the drive is unknown, and "
            "without it a pitch (positioning) table would be wrong")


def header_lines(point, source, x0_mm, values, exx_includes_lead,
                 straightness_note=None) -> list[str]:
    """The lines every header starts with; ``straightness_note``: lines (a fit's statement of
    the common slope its straightness leaves undetermined) for a file that holds EYX or EZX."""
    return [
        f"diffguide compensation table, point {point}" + (f"; {source}" if source else ""),
        f"machine coordinates: X = x + x0, x0 = {x0_mm:g} mm (x = 0: the reference position)",
        values,
        lead_line(exx_includes_lead),
        *(straightness_note or ()),
    ]


def value_sign(values: str) -> float:
    """The factor from the compensation ``C`` to the value written: ``+1`` where the controller
    adds the value (``"compensation"``), ``−1`` where it subtracts it (``"error"``)."""
    return 1.0 if values == "compensation" else -1.0


def values_line(values: str, fmt: str, key: str) -> str:
    """The header's statement of an unconfirmed value convention (setting ``key``)."""
    what = ("the compensation C: the controller adds it to the axis" if values == "compensation"
            else "the error -C: the controller subtracts it from the axis")
    other = "error" if values == "compensation" else "compensation"
    option = "--" + key.replace("_", "-")
    return (f"values: {what} ({key} = {values}); UNCONFIRMED: the {fmt} documentation read "
            "does not state the sign: check one point on the machine, and if the error "
            f"doubles, export again with {option} {other} ([export] {key} = \"{other}\")")


def equidistant_step(x_mm, fmt: str) -> float:
    d = np.diff(x_mm)
    if len(x_mm) < 2 or not np.allclose(d, d[0], rtol=0, atol=1e-6) or d[0] <= 0:
        raise ValueError(f"a {fmt} table needs at least two equidistant, increasing positions")
    return float(d[0])


def cross_tables(err, axis_side, fmt: str) -> list[tuple[str, str, str, np.ndarray]]:
    """``[(error name, axis, side, compensation (m))]`` for EYX → Y and EZX → Z where the side
    is known; ``ValueError`` when neither is."""
    known = sides(axis_side)
    if not known:
        raise ValueError(
            f"{fmt}: the sign of a cross-axis table (EYX on Y, EZX on Z) depends on which side "
            "of the kinematic chain Y and Z sit; pass axis_side (CLI: --axis-side "
            "Y=tool|workpiece,Z=tool|workpiece)")
    out = []
    for k, (name, axis) in enumerate(CROSS_AXES.items(), start=1):
        if axis in known:
            out.append((name, axis, known[axis], sign(known[axis]) * err[:, k]))
    return out
