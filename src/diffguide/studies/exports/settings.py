"""The controller settings of the compensation exports: one definition for the command line and
the machine file's ``[export]`` table, each with its default, its allowed values and the check
that refuses anything else, naming the option or key.

=========================  ===========================  ==========================================
``[export]`` key           command line                 meaning (default)
=========================  ===========================  ==========================================
``cec_axis_names``         ``--cec-axis-names``         SINUMERIK machine axis names of X, Y, Z
                                                        (``X=AX1,Y=AX2,Z=AX3``)
``fanuc_detection_unit``   ``--fanuc-detection-unit``   FANUC detection unit: ``IS-A`` .. ``IS-E``
                                                        or a length in mm (``IS-B``, 0.001 mm)
``isg_axis_numbers``       ``--isg-axis-numbers``       ISG logical axis numbers of X, Y, Z
                                                        (P-VOLC-00001..3; none: to be set)
``isg_max_records``        ``--isg-max-records``        ISG start-up ``vol_comp[0].max_records``
                                                        (P-STUP-00100; the table's record count)
``heidenhain_values``      ``--heidenhain-values``      what a TNC ``.COM`` value is: the
                                                        ``compensation`` the axis adds, or the
                                                        ``error`` (``compensation``; unconfirmed)
``isg_cross_values``       ``--isg-cross-values``       the same for the ISG cross compensation
                                                        list (``compensation``; unconfirmed)
=========================  ===========================  ==========================================

A name written outside a comment of a controller file must fit that controller's syntax: it is
refused otherwise, never escaped .
"""

import re
from collections.abc import Callable, Mapping

#: a SINUMERIK axis identifier (written outside a comment: refused otherwise)
AXIS_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")

#: FANUC increment systems and their least command increment on a millimetre machine (mm); the
#: detection unit equals it where the command multiplier (CMR) is 1.
INCREMENT_SYSTEMS = {"IS-A": 0.01, "IS-B": 0.001, "IS-C": 0.0001, "IS-D": 0.00001,
                     "IS-E": 0.000001}
#: the range (mm) of a detection unit given as a length
DETECTION_UNIT_MM = (1e-6, 0.01)
#: logical axis numbers of the ISG kernel: UNS16, 0 not allowed (P-COMP-00001)
AXIS_NUMBER = (1, 65535)
#: vol_comp[i].max_records: SGN32 (P-STUP-00100)
MAX_RECORDS = (1, 2**31 - 1)
VALUES = ("compensation", "error")
AXES = ("X", "Y", "Z")

#: ``{key: (CLI option, default, allowed form)}``
SETTINGS: dict[str, tuple[str, object, str]] = {
    "cec_axis_names": ("--cec-axis-names", {"X": "AX1", "Y": "AX2", "Z": "AX3"},
                       "X=NAME,Y=NAME,Z=NAME (any of them; the others keep theirs), each a "
                       "SINUMERIK identifier "
                       f"{AXIS_NAME.pattern}, the three distinct"),
    "fanuc_detection_unit": ("--fanuc-detection-unit", "IS-B",
                             f"{', '.join(INCREMENT_SYSTEMS)} or a length in mm in "
                             f"[{DETECTION_UNIT_MM[0]:g}, {DETECTION_UNIT_MM[1]:g}]"),
    "isg_axis_numbers": ("--isg-axis-numbers", None,
                         f"X=N,Y=N,Z=N, integers in [{AXIS_NUMBER[0]}, {AXIS_NUMBER[1]}], "
                         "distinct"),
    "isg_max_records": ("--isg-max-records", None,
                        f"an integer in [{MAX_RECORDS[0]}, {MAX_RECORDS[1]}], at least the "
                        "table's number of records"),
    "heidenhain_values": ("--heidenhain-values", "compensation", " or ".join(VALUES)),
    "isg_cross_values": ("--isg-cross-values", "compensation", " or ".join(VALUES)),
}


def _refuse(where, key, value):
    raise ValueError(f"{where}: {value!r} is not allowed; allowed: {SETTINGS[key][2]}")


def _per_axis(value, where, key, item: Callable):
    if not isinstance(value, Mapping) or not value:
        _refuse(where, key, value)
    out = {}
    for axis, v in value.items():
        if str(axis).upper() not in AXES:
            _refuse(where, key, value)
        out[str(axis).upper()] = item(v, f"{where}: {str(axis).upper()}")
    if len(set(out.values())) != len(out):
        raise ValueError(f"{where}: {value!r}: the axes must be distinct; allowed: "
                         f"{SETTINGS[key][2]}")
    return out


def check(key: str, value, where: str):
    """``value`` of setting ``key`` in its normal form (names upper-cased axes, the detection
    unit in mm), else ``ValueError`` that begins with ``where`` (the option or key) and says
    what is allowed."""

    def name(v, at):
        if not isinstance(v, str) or not AXIS_NAME.fullmatch(v):
            _refuse(at, key, v)
        return v

    def number(v, at):
        lo, hi = AXIS_NUMBER
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            _refuse(at, key, v)
        return v

    if key == "cec_axis_names":
        return _per_axis(value, where, key, name)
    if key == "isg_axis_numbers":
        return _per_axis(value, where, key, number)
    if key == "fanuc_detection_unit":
        if isinstance(value, str) and value.upper() in INCREMENT_SYSTEMS:
            return INCREMENT_SYSTEMS[value.upper()]
        lo, hi = DETECTION_UNIT_MM
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not lo <= value <= hi:
            _refuse(where, key, value)
        return float(value)
    if key == "isg_max_records":
        lo, hi = MAX_RECORDS
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            _refuse(where, key, value)
        return value
    if key in ("heidenhain_values", "isg_cross_values"):
        if value not in VALUES:
            _refuse(where, key, value)
        return value
    raise ValueError(f"{where}: unknown export setting; allowed: {', '.join(SETTINGS)}")


def parse_option(key: str, text: str):
    """The command line's text of setting ``key`` (``X=AX1,Y=AX2``, ``IS-C``, ``0.0005``,
    ``1000``), checked (:func:`check`; the message names the option)."""
    option = SETTINGS[key][0]
    text = text.strip()
    if key in ("cec_axis_names", "isg_axis_numbers"):
        pairs = {}
        for item in text.split(","):
            axis, eq, v = item.partition("=")
            if not eq or not axis.strip():
                _refuse(option, key, text)
            v = v.strip()
            pairs[axis.strip()] = (int(v) if re.fullmatch(r"[0-9]+", v) else v) \
                if key == "isg_axis_numbers" else v
        return check(key, pairs, option)
    if key == "fanuc_detection_unit" and text.upper() not in INCREMENT_SYSTEMS:
        try:
            return check(key, float(text), option)
        except ValueError:
            _refuse(option, key, text)
    if key == "isg_max_records":
        if not re.fullmatch(r"[0-9]+", text):
            _refuse(option, key, text)
        return check(key, int(text), option)
    return check(key, text, option)


def merged(file_settings: Mapping | None = None, options: Mapping | None = None) -> dict:
    """Every setting: the command line's (already checked, ``None`` where not given) over the
    machine file's ``[export]`` (already checked) over the defaults."""
    out = {k: (check(k, v[1], k) if k == "fanuc_detection_unit" else v[1])
           for k, v in SETTINGS.items()}
    for given in (file_settings or {}, options or {}):
        for k, v in given.items():
            if v is not None:  # the axis names of X, Y, Z one by one
                out[k] = {**out[k], **v} if k == "cec_axis_names" else v
    return out


def spec_options(settings: Mapping) -> dict:
    """The :class:`~._common.ExportSpec` keywords of the merged settings."""
    return dict(axis_names=settings["cec_axis_names"],
                detection_unit_mm=settings["fanuc_detection_unit"],
                isg_axis_numbers=settings["isg_axis_numbers"],
                max_records=settings["isg_max_records"],
                heidenhain_values=settings["heidenhain_values"],
                isg_cross_values=settings["isg_cross_values"])


def check_table(body, source: str) -> dict:
    """A machine file's ``[export]`` table, every key checked (message: the file and the key,
    the allowed form)."""
    if not isinstance(body, Mapping):
        raise ValueError(f"{source}: [export]: must be a table of keys")
    out = {}
    for key, value in body.items():
        if key not in SETTINGS:
            raise ValueError(f"{source}: key 'export.{key}' is unknown; allowed: "
                             f"{', '.join(SETTINGS)}")
        out[key] = check(key, value, f"{source}: key 'export.{key}'")
    return out


def toml_lines(given: Mapping | None = None, mark: bool = False) -> list[str]:
    """The ``[export]`` table as TOML lines: each given setting (``mark``: with ``# file``),
    the others commented out at their default (or an example where there is none) with their
    option and allowed form."""
    given = given or {}
    examples = {"isg_axis_numbers": ({"X": 1, "Y": 2, "Z": 3}, "none: the files say what to set"),
                "isg_max_records": (2000, "the table's number of records")}
    lines = ["[export]  # compensation export settings (docs: compensation-exports)"]
    for key, (option, default, allowed) in SETTINGS.items():
        if key in given:
            lines.append(f"{key} = {_toml(given[key])}" + ("  # file" if mark else ""))
        elif default is None:
            example, means = examples[key]
            lines.append(f"# {key} = {_toml(example)}  # e.g.; default: {means}; {option}; "
                         f"allowed: {allowed}")
        else:
            lines.append(f"# {key} = {_toml(default)}  # default; {option}; allowed: "
                         f"{allowed}")
    return lines


def _toml(value) -> str:
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"
    if isinstance(value, str):
        return '"' + value + '"'  # checked values: identifiers and words, nothing to escape
    return repr(value)
