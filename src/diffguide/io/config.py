"""Machine configuration files (TOML): read, validate, write; units in the key names.

A configuration is a nested mapping ``{section: {key: value}}``; what each key means, its unit,
range and default (the ``majda2012`` machine) is in :mod:`diffguide.io.config_spec`, re-exported
here. A file only needs the keys it changes. :func:`load_config` reads and validates a file —
every error names the file, the key and the allowed range, in one line — and
:func:`dump_config` writes one (``diffguide config --preset majda2012 > machine.toml``).
:func:`spec_from_config` turns a configuration into the typed, SI
:class:`~diffguide.machine.spec.MachineSpec` that :func:`diffguide.build_machine` builds from
(:func:`config_from_spec` goes back).
"""

import math
import os
import re
import tomllib
from pathlib import Path

from .carriage_block import CATALOGUE_KEYS, resolve_catalogue
from .config_spec import FIT_SCHEMA as FIT_SCHEMA
from .config_spec import KEYS as KEYS
from .config_spec import RIB_KEYS as RIB_KEYS
from .config_spec import RIB_SCHEMA as RIB_SCHEMA
from .config_spec import carriage_from_config as carriage_from_config
from .config_spec import config_from_spec as config_from_spec
from .config_spec import default_config as default_config
from .config_spec import schema as schema
from .config_spec import spec_from_config as spec_from_config
from .config_spec import table_from_config as table_from_config
from .table_source import PLATE_ONLY, describe_source, resolve_table_source, retained_points


def _number(value, where, what):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{where}: {what} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{where}: {what} must be finite, got {value!r}")
    return float(value)


def _check(value, spec, where):
    _, kind, lo, hi, help_ = spec
    if kind.startswith("str:"):
        allowed = kind[4:].split("|")
        if value not in allowed:
            raise ValueError(f"{where}: {value!r} is not allowed; allowed: {', '.join(allowed)}")
        return value
    if kind == "bool":
        if not isinstance(value, bool):
            raise ValueError(f"{where}: must be true or false, got {value!r}")
        return value
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"{where}: must be an integer in [{lo}, {hi}], got {value!r}")
        if not lo <= value <= hi:
            raise ValueError(f"{where}: {value} outside the allowed range [{lo}, {hi}] ({help_})")
        return value
    if kind == "float":
        v = _number(value, where, "value")
        if not lo <= v <= hi:
            raise ValueError(f"{where}: {v:g} outside the allowed range [{lo:g}, {hi:g}] ({help_})")
        return v
    if kind in ("pair", "list"):
        if kind == "pair" and (not isinstance(value, (list, tuple)) or len(value) != 2):
            raise ValueError(f"{where}: must be a list of two numbers [a, b], got {value!r}")
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"{where}: must be a list of numbers [a, b, ...] ({help_}), got "
                             f"{value!r}")
        out = tuple(_number(v, where, "each entry") for v in value)
        for v in out:
            if not lo <= v <= hi:
                raise ValueError(
                    f"{where}: {v:g} outside the allowed range [{lo:g}, {hi:g}] ({help_})"
                )
        return out
    if kind == "prior":
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            raise ValueError(
                f"{where}: must be a list of three numbers [value, lo, hi] ({help_}), "
                f"got {value!r}"
            )
        v, a, b = (_number(x, where, "each entry") for x in value)
        if not (lo <= a <= v <= b <= hi):
            raise ValueError(
                f"{where}: needs {lo:g} <= lo <= value <= hi <= {hi:g}, got "
                f"[{v:g}, {a:g}, {b:g}] ({help_})"
            )
        return (v, a, b)
    raise AssertionError(kind)


def validate_config(raw: dict, source: str = "<config>") -> dict:
    """Merge ``raw`` over the defaults and validate every key; returns the full configuration.

    Raises:
        ValueError: one line naming ``source``, the key and the allowed range or values.
    """
    if not isinstance(raw, dict):
        raise ValueError(f"{source}: the configuration must be a table of sections")
    # [carriage] block = ... / datasheet values -> the internal keys (io/carriage_block.py)
    raw, catalogue = resolve_catalogue(raw, source, _check, schema()["carriage"])
    # [table] source = "superelement", file = ...: the user's FE model (io/table_source.py)
    raw, table_source = resolve_table_source(raw, source)
    cfg = default_config()
    if catalogue is not None:
        cfg["catalogue"] = catalogue
    if table_source is not None:
        cfg["table_source"] = table_source
    for section, body in raw.items():
        where = f"{source}: [{section}]"
        if section == "ribs":
            if not isinstance(body, list):
                raise ValueError(f"{where}: ribs must be an array of tables, [[ribs]]")
            cfg["ribs"] = []
            for i, rib in enumerate(body):
                if not isinstance(rib, dict):
                    raise ValueError(f"{where}: rib {i + 1} must be a table")
                out = {k: spec[0] for k, spec in RIB_SCHEMA.items()}
                for key, value in rib.items():
                    if key not in RIB_SCHEMA:
                        raise ValueError(
                            f"{source}: key 'ribs[{i + 1}].{key}' is unknown; allowed: "
                            f"{', '.join(RIB_SCHEMA)}"
                        )
                    out[key] = _check(
                        value, RIB_SCHEMA[key], f"{source}: key 'ribs[{i + 1}].{key}'"
                    )
                cfg["ribs"].append(out)
            continue
        if section == "fit":
            if not isinstance(body, dict):
                raise ValueError(f"{where}: must be a table of keys")
            for key, value in body.items():
                if key not in FIT_SCHEMA:
                    raise ValueError(
                        f"{source}: key 'fit.{key}' is unknown; allowed: {', '.join(FIT_SCHEMA)}"
                    )
                cfg["fit"][key] = _check(value, FIT_SCHEMA[key], f"{source}: key 'fit.{key}'")
            continue
        if section == "export":  # the compensation exports' controller settings
            from ..studies.exports.settings import check_table

            cfg["export"] = check_table(body, source)
            continue
        if section == "points":
            if not isinstance(body, dict) or not body:
                raise ValueError(f"{where}: must be a table of name = [x_mm, y_mm] entries")
            cfg["points"] = {}
            for name, xy in body.items():
                spec = (None, "pair", -1e5, 1e5, "point on the table top")
                cfg["points"][str(name)] = _check(xy, spec, f"{source}: key 'points.{name}'")
            continue
        if section not in schema():
            raise ValueError(
                f"{where}: unknown section; allowed: "
                f"{', '.join([*schema(), 'points', 'ribs', 'fit', 'export'])}"
            )
        if not isinstance(body, dict):
            raise ValueError(f"{where}: must be a table of keys")
        for key, value in body.items():
            if key not in schema()[section]:
                extra = CATALOGUE_KEYS if section == "carriage" else {}
                raise ValueError(
                    f"{source}: key '{section}.{key}' is unknown; allowed: "
                    f"{', '.join([*schema()[section], *extra])}"
                )
            cfg[section][key] = _check(
                value, schema()[section][key], f"{source}: key '{section}.{key}'"
            )
    if table_source is not None and "points" not in raw:
        # an imported table knows only its retained points: they are the machine's points
        cfg["points"] = {name: tuple(round(v * 1e3, 9) for v in xy)
                         for name, xy in retained_points(cfg).items()}
    if table_source is None and cfg["fit"].get("stiffness_prior") is not None:
        raise ValueError(f"{source}: key 'fit.stiffness_prior': a stiffness scale is estimated "
                         'for a table imported from an FE model ([table] source = '
                         '"superelement") only; the plate has a thickness (thickness_prior_mm)')
    _check_consistency(cfg, source)
    return cfg


#: Two footprints closer than this (mm; the mesh's node tolerance, 1e-9 m) touch.
_TOUCH_MM = 1e-6


def _check_consistency(cfg: dict, source: str) -> None:
    t, g = cfg["table"], cfg["guideway"]
    half_l, half_w = t["length_mm"] / 2, t["width_mm"] / 2
    fx, fy = g["carriage_footprint_mm"]
    for y in g["rail_y_mm"]:
        if abs(y) + fy / 2 > half_w:
            raise ValueError(
                f"{source}: key 'guideway.rail_y_mm': {y:g} puts a carriage footprint off the "
                f"table; allowed |y| <= {half_w - fy / 2:g} mm"
            )
    if not g["rail_y_mm"][0] < g["rail_y_mm"][1]:
        raise ValueError(f"{source}: key 'guideway.rail_y_mm': rail 1 must be at the smaller Y")
    if not g["rail_y_mm"][1] - g["rail_y_mm"][0] > fy + _TOUCH_MM:
        raise ValueError(
            f"{source}: key 'guideway.rail_y_mm': the two rails' carriages overlap; the rails "
            f"must be more than one footprint ({fy:g} mm) apart (touching footprints share "
            "mesh nodes)"
        )
    xs = g["carriage_x_mm"]
    for x in xs:
        if abs(x) + fx / 2 > half_l:
            raise ValueError(
                f"{source}: key 'guideway.carriage_x_mm': {x:g} puts a carriage footprint off the "
                f"table; allowed |x| <= {half_l - fx / 2:g} mm"
            )
    if not xs[1] - xs[0] > fx + _TOUCH_MM:
        raise ValueError(
            f"{source}: key 'guideway.carriage_x_mm': the carriages overlap; they must be more "
            f"than one footprint ({fx:g} mm) apart, first the smaller X (touching footprints "
            "share mesh nodes)"
        )
    _check_nut(cfg, source)
    for i, rib in enumerate(cfg["ribs"]):
        limit = half_w if rib["axis"] == "x" else half_l
        if abs(rib["position_mm"]) > limit:
            raise ValueError(
                f"{source}: key 'ribs[{i + 1}].position_mm': {rib['position_mm']:g} is off the "
                f"table; allowed |position| <= {limit:g} mm"
            )
    for name, (x, y) in cfg["points"].items():
        if abs(x) > half_l or abs(y) > half_w:
            raise ValueError(
                f"{source}: key 'points.{name}': ({x:g}, {y:g}) mm is off the table "
                f"(|x| <= {half_l:g}, |y| <= {half_w:g} mm)"
            )
    if cfg["machine"]["stroke_mm"] / 2 >= cfg["screw"]["free_length_at_ref_mm"]:
        raise ValueError(
            f"{source}: key 'screw.free_length_at_ref_mm': must exceed half the stroke "
            f"({cfg['machine']['stroke_mm'] / 2:g} mm), or the nut would pass the fixed bearing"
        )


def _check_nut(cfg: dict, source: str) -> None:
    """The screw nut's flange must lie on the table (its edges may reach the table's edges) and
    must not touch or overlap a carriage's footprint (touching patches share mesh nodes).

    The flange ``[screw] nut_footprint_mm`` (X, Y) is centred on ``nut_xy_mm``; both in mm,
    the table ``length_mm`` (X) × ``width_mm`` (Y) is centred on the origin.
    """
    t, s = cfg["table"], cfg["screw"]
    half_l, half_w = t["length_mm"] / 2, t["width_mm"] / 2
    (x, y), (fx, fy) = s["nut_xy_mm"], s["nut_footprint_mm"]
    if fx > t["length_mm"] or fy > t["width_mm"]:
        raise ValueError(
            f"{source}: key 'screw.nut_footprint_mm': ({fx:g}, {fy:g}) mm is larger than the "
            f"table; allowed at most ({t['length_mm']:g}, {t['width_mm']:g}) mm "
            "(table length_mm, width_mm)"
        )
    if abs(x) + fx / 2 > half_l or abs(y) + fy / 2 > half_w:
        raise ValueError(
            f"{source}: key 'screw.nut_xy_mm': ({x:g}, {y:g}) mm puts the nut footprint "
            f"({fx:g} × {fy:g} mm) off the table; allowed |x| <= {half_l - fx / 2:g} mm, "
            f"|y| <= {half_w - fy / 2:g} mm"
        )
    g = cfg["guideway"]
    cx, cy = g["carriage_footprint_mm"]
    for xc in g["carriage_x_mm"]:
        for yc in g["rail_y_mm"]:
            gap_x = abs(x - xc) - (fx + cx) / 2
            gap_y = abs(y - yc) - (fy + cy) / 2
            if gap_x <= _TOUCH_MM and gap_y <= _TOUCH_MM:
                raise ValueError(
                    f"{source}: key 'screw.nut_xy_mm': ({x:g}, {y:g}) mm puts the nut footprint "
                    f"({fx:g} × {fy:g} mm) on the carriage at ({xc:g}, {yc:g}) mm "
                    f"({cx:g} × {cy:g} mm); allowed: |x - {xc:g}| > {(fx + cx) / 2:g} mm or "
                    f"|y - {yc:g}| > {(fy + cy) / 2:g} mm (footprints must not touch)"
                )


def load_config(path: str | os.PathLike) -> dict:
    """Read and validate a machine TOML file (see :func:`validate_config`)."""
    return validate_config(_read_toml(path), str(path))


def _read_toml(path: str | os.PathLike) -> dict:
    """The raw TOML table of a machine file (clear errors for unreadable or malformed files)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise OSError(f"cannot read config file {path}: {exc.strerror}") from None
    try:
        raw = tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a UTF-8 text file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: malformed TOML: {exc}") from None
    return raw


def explain_config(path: str | os.PathLike) -> str:
    """The resolved machine of a TOML file, every value with where it came from: ``file`` (the
    file gives it), ``catalogue`` (published, chosen or calibrated for a catalogue or datasheet
    block, with its source) or ``default`` (the ``majda2012`` preset's value); user units."""
    raw = _read_toml(path)
    cfg = validate_config(raw, str(path))
    prov = (cfg.get("catalogue") or {}).get("provenance", {})
    lines = [f"# {path}: the resolved machine; each value's source after '#'"]
    if cfg.get("catalogue"):
        lines.append(f"# carriage: {cfg['catalogue']['block']}, preload class "
                     f"{cfg['catalogue']['preload_class']}")

    lines += describe_source(cfg)
    unused = "not used: the table is imported" if cfg.get("table_source") else None

    def source(section, key):
        if unused and f"{section}.{key}" in PLATE_ONLY:
            return unused
        if key in raw.get(section, {}):
            return "file"
        where = prov.get(key if section == "carriage" else f"{section}.{key}")
        return f"catalogue, {where}" if where else "default"

    for section, keys in schema().items():
        lines.append(f"[{section}]")
        lines += [f"{k} = {_toml_value(cfg[section][k])}  # {source(section, k)}" for k in keys]
        lines.append("")
    points = ("file" if "points" in raw else
              "the imported table's retained points" if unused else "default")
    lines.append(f"[points]  # {points}")
    lines += [f"{_toml_key(n)} = {_toml_value(xy)}" for n, xy in cfg["points"].items()]
    lines.append("")
    ribs = unused or ("file" if "ribs" in raw else "default")
    lines.append(f"# ribs: {len(cfg['ribs'])} ({ribs})")
    fit = cfg.get("fit", {})
    lines.append("[fit]")
    for k, spec in FIT_SCHEMA.items():
        v = fit.get(k, spec[0])
        src = "file" if k in raw.get("fit", {}) else "default"
        if unused and f"fit.{k}" in PLATE_ONLY:
            src = unused
        lines.append(f"# {k}: the machine's value  # {src}" if v is None
                     else f"{k} = {_toml_value(v)}  # {src}")
    lines += ["", *_export_lines(cfg.get("export"), mark=True)]
    return "\n".join(lines) + "\n"


def _toml_string(s: str) -> str:
    """A TOML basic string: backslash, quote and control characters escaped."""
    out = []
    for ch in s:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append({"\n": "\\n", "\t": "\\t", "\r": "\\r"}.get(ch, f"\\u{ord(ch):04X}"))
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_key(name: str) -> str:
    """A TOML key: bare where it may be (ASCII letters, digits, ``_``, ``-``), else quoted (a
    dot in a bare key would make a nested table, a quote or a space is invalid)."""
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else _toml_string(name)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return _toml_string(v)
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, float):
        return repr(float(f"{v:.12g}"))
    return str(v)


def dump_config(cfg: dict, title: str = "") -> str:
    """TOML text of a configuration, each key with its unit and meaning as a comment."""
    lines = [
        f"# diffguide machine configuration{': ' + title if title else ''}",
        "# units are in the key names; every key is optional (defaults: majda2012)",
        "",
    ]
    if cfg.get("catalogue"):  # a catalogue block, written as its resolved internal keys
        lines[-1:-1] = [
            f"# carriage: {cfg['catalogue']['block']}, preload class "
            f"{cfg['catalogue']['preload_class']}; its calibrated internal values below"
        ]
    for section, keys in schema().items():
        lines.append(f"[{section}]")
        for key, spec in keys.items():
            lines.append(f"{key} = {_toml_value(cfg[section][key])}  # {spec[4]}")
        lines.append("")
    lines.append("[points]  # control points on the table top: name = [x_mm, y_mm] from its centre")
    for name, xy in cfg["points"].items():
        lines.append(f"{_toml_key(name)} = {_toml_value(xy)}")
    lines.append("")
    if not cfg["ribs"]:
        lines.append("# ribs under the plate (none); add one table per rib:")
        lines.append("# [[ribs]]")
        lines += [f"# {k} = {_toml_value(spec[0])}  # {spec[4]}" for k, spec in RIB_SCHEMA.items()]
    for rib in cfg["ribs"]:
        lines.append("[[ribs]]")
        lines += [f"{k} = {_toml_value(rib[k])}  # {spec[4]}" for k, spec in RIB_SCHEMA.items()]
    lines.append("")
    lines.append("[fit]  # what 'diffguide fit' estimates; a prior is [value, lo, hi]")
    fit = cfg.get("fit", {})
    for k, spec in FIT_SCHEMA.items():
        v = fit.get(k, spec[0])
        if v is None:  # a prior left to the machine's value: shown commented out
            lines.append(f"# {k} = [value, lo, hi]  # {spec[4]}; default: the machine's value")
        else:
            lines.append(f"{k} = {_toml_value(v)}  # {spec[4]}")
    lines += ["", *_export_lines(cfg.get("export"))]
    return "\n".join(lines) + "\n"


def _export_lines(given, mark: bool = False) -> list[str]:
    """The ``[export]`` table (:mod:`diffguide.studies.exports.settings`)."""
    from ..studies.exports.settings import toml_lines

    return toml_lines(given, mark)
