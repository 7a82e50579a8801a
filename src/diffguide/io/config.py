"""Machine configuration files (TOML): every parameter of a machine, units in the key names.

A configuration is a nested mapping ``{section: {key: value}}``. :func:`schema` lists every key
with its default (the ``majda2012`` preset), its kind and its allowed range; a file only needs the
keys it changes. :func:`load_config` reads and validates a file — every error names the file, the
key and the allowed range, in one line — and :func:`dump_config` writes one (``diffguide config
--preset majda2012 > machine.toml``). :func:`spec_from_config` turns a configuration into
the typed, SI :class:`~diffguide.machine.spec.MachineSpec` that :func:`diffguide.build_machine`
builds from (:func:`config_from_spec` goes back); the defaults are
:func:`diffguide.presets.majda2012`, the one definition of the preset.

Units: mm, µm, GPa, N, kg/m³, degrees, as the key names say; :data:`KEYS` converts them to SI.
"""

import functools
import math
import os
import tomllib
from pathlib import Path

from .. import presets

#: ``{section: {key: (spec path, SI -> user scale, kind, low, high, help)}}``: every key of a
#: machine file, the field of :class:`~diffguide.machine.spec.MachineSpec` it sets (``None``:
#: a key of the file only) and the factor from SI to the key's unit (``None``: not a number).
#: kind: "float", "int", "bool", "str:a|b", "pair" (two floats). Ranges are inclusive.
KEYS: dict[str, dict[str, tuple]] = {
    "table": {
        "length_mm": ("table.length", 1e3, "float", 50.0, 20000.0, "table length along X"),
        "width_mm": ("table.width", 1e3, "float", 50.0, 10000.0, "table width along Y"),
        "thickness_mm": (
            "table.thickness",
            1e3,
            "float",
            1.0,
            2000.0,
            "equivalent plate thickness",
        ),
        "E_GPa": ("table.material.E", 1e-9, "float", 1.0, 1000.0, "Young's modulus"),
        "nu": ("table.material.nu", 1.0, "float", 0.0, 0.49, "Poisson ratio"),
        "density_kg_m3": ("table.material.rho", 1.0, "float", 0.0, 30000.0, "density"),
        "mesh_nx": ("table.nx", None, "int", 1, 200, "elements along X"),
        "mesh_ny": ("table.ny", None, "int", 1, 200, "elements along Y"),
    },
    "guideway": {
        "rail_y_mm": (
            "guideway.rail_y",
            1e3,
            "pair",
            -5000.0,
            5000.0,
            "Y of rail 1 and rail 2 (rail 1 first)",
        ),
        "carriage_x_mm": (
            "guideway.carriage_x",
            1e3,
            "pair",
            -10000.0,
            10000.0,
            "X of the two carriages on each rail, from the table centre",
        ),
        "carriage_footprint_mm": (
            "guideway.footprint",
            1e3,
            "pair",
            5.0,
            1000.0,
            "footprint bolted to the table (X, Y)",
        ),
    },
    "carriage": {
        "law": (
            "carriage.law",
            None,
            "str:hertz|rivin|roller",
            None,
            None,
            "contact law: hertz (balls, exact), rivin (the paper's eq. 1), roller (Palmgren)",
        ),
        "ball_diameter_mm": ("carriage.ball_diameter", 1e3, "float", 0.5, 50.0, "ball diameter d"),
        "groove_conformity": (
            "carriage.groove_conformity",
            1.0,
            "float",
            1.0001,
            1.5,
            "groove diameter / ball diameter, D/d",
        ),
        "roller_length_mm": (
            "carriage.roller_length",
            1e3,
            "float",
            0.5,
            100.0,
            "effective roller length (law = roller)",
        ),
        "E_GPa": (
            "carriage.E",
            1e-9,
            "float",
            1.0,
            1000.0,
            "Young's modulus of elements and grooves",
        ),
        "nu": ("carriage.nu", 1.0, "float", 0.0, 0.49, "Poisson ratio of elements and grooves"),
        "elements_per_row": (
            "carriage.elements_per_row",
            None,
            "int",
            1,
            200,
            "rolling elements per row",
        ),
        "pitch_mm": ("carriage.pitch", 1e3, "float", 0.5, 100.0, "element pitch along the row"),
        "contact_angle_deg": (
            "carriage.contact_angle_deg",
            1.0,
            "float",
            1.0,
            89.0,
            "load line angle from the vertical",
        ),
        "arrangement": (
            "carriage.arrangement",
            None,
            "str:O|X",
            None,
            None,
            "O (load lines away from the rail) or X",
        ),
        "upper_row_yz_mm": (
            "carriage.upper_row_yz",
            1e3,
            "pair",
            -500.0,
            500.0,
            "|y| and z of the upper rows below the carriage top face",
        ),
        "lower_row_yz_mm": (
            "carriage.lower_row_yz",
            1e3,
            "pair",
            -500.0,
            500.0,
            "|y| and z of the lower rows below the carriage top face",
        ),
        "capacity_N": ("carriage.capacity", 1.0, "float", 100.0, 1e7, "dynamic load capacity C"),
        "preload_fraction": (
            "carriage.preload_fraction",
            1.0,
            "float",
            1e-4,
            0.5,
            "preload as a fraction of C",
        ),
        "smoothing_fraction": (
            "carriage.smoothing_fraction",
            1.0,
            "float",
            1e-4,
            0.5,
            "smoothing length ε / preload approach",
        ),
    },
    "screw": {
        "core_diameter_mm": (
            "screw.core_diameter",
            1e3,
            "float",
            1.0,
            500.0,
            "screw core diameter",
        ),
        "E_GPa": ("screw.E", 1e-9, "float", 1.0, 1000.0, "screw Young's modulus"),
        "free_length_at_ref_mm": (
            "screw.free_length_at_ref",
            1e3,
            "float",
            1.0,
            50000.0,
            "fixed bearing to nut at x = 0; grows with x",
        ),
        "nut_xy_mm": (
            "screw.nut_xy",
            1e3,
            "pair",
            -10000.0,
            10000.0,
            "nut position under the table",
        ),
        "nut_footprint_mm": (
            "screw.nut_footprint",
            1e3,
            "pair",
            1.0,
            1000.0,
            "nut flange bolted to the table",
        ),
    },
    "machine": {
        "gravity_m_s2": ("gravity", 1.0, "float", 0.0, 100.0, "gravity"),
        "stroke_mm": ("stroke", 1e3, "float", 1.0, 50000.0, "X stroke, symmetric about x = 0"),
    },
}

#: Ribs under the plate: an array of tables ``[[ribs]]`` with these keys (default: none); same
#: layout as :data:`KEYS`, paths into :class:`~diffguide.fe.mesh.Rib`.
RIB_KEYS: dict[str, tuple] = {
    "axis": ("axis", None, "str:x|y", None, None, "x: along the rails, y: across"),
    "position_mm": ("position", 1e3, "float", -1e5, 1e5, "y of an x-rib, x of a y-rib"),
    "width_mm": ("width", 1e3, "float", 1.0, 1000.0, "rib width"),
    "depth_mm": ("depth", 1e3, "float", 1.0, 2000.0, "rib depth below the plate"),
}
#: The default rib of a ``[[ribs]]`` table, user units.
_RIB_DEFAULTS = {"axis": "x", "position_mm": 0.0, "width_mm": 20.0, "depth_mm": 60.0}

#: The ``[fit]`` section: how ``diffguide fit`` treats what nobody knows about the machine. Not
#: part of the machine (no spec path); ``{key: (default, kind, low, high, help)}`` as
#: :func:`schema`. A ``"prior"`` is ``[value, lo, hi]`` with ``0 < lo <= value <= hi``, read as
#: a value and ±2σ of a log-normal prior; ``None`` (the default) means the machine's own value
#: with the range ``[value/2, 2·value]`` (thickness) or ``[value/4, 2·value]`` (preload).
FIT_SCHEMA: dict[str, tuple] = {
    "structure": (
        "estimate",
        "str:estimate|fixed",
        None,
        None,
        "estimate the table thickness and the preload with the rails, or hold them fixed",
    ),
    "thickness_prior_mm": (
        None,
        "prior",
        0.1,
        5000.0,
        "equivalent plate thickness prior [value, lo, hi] (mm)",
    ),
    "preload_prior": (
        None,
        "prior",
        1e-5,
        0.9,
        "preload prior [value, lo, hi] as fractions of C",
    ),
    "criterion": (
        "ml",
        "str:ml|gcv",
        None,
        None,
        "regularisation weight: marginal likelihood (ml) or generalised cross-validation (gcv)",
    ),
    "rail_waviness_um": (
        0.0,
        "float",
        0.0,
        100.0,
        "RMS of the rails' short-wave content the knots do not resolve (µm), added to every σ",
    ),
    "rigid": (
        False,
        "bool",
        None,
        None,
        "also run the classical rigid-table inversion (rails_rigid.csv; a compilation of its own)",
    ),
}


def _get(obj, path: str):
    for name in path.split("."):
        obj = getattr(obj, name)
    return obj


def _user(value, scale):
    """SI -> the key's unit, rounded to 12 significant digits (170.0 mm, not 170.00000000000003)."""
    if scale is None:
        return value
    if isinstance(value, tuple):
        return tuple(_user(v, scale) for v in value)
    return float(f"{float(value) * scale:.12g}")


def _si(value, scale):
    if scale is None:
        return value
    if isinstance(value, (tuple, list)):
        return tuple(_si(v, scale) for v in value)
    return value / scale


def config_from_spec(spec) -> dict:
    """A :class:`~diffguide.machine.spec.MachineSpec` as a configuration (user units)."""
    cfg = {
        sec: {key: _user(_get(spec, k[0]), k[1]) for key, k in keys.items()}
        for sec, keys in KEYS.items()
    }
    cfg["points"] = {name: _user(xy, 1e3) for name, xy in spec.points}
    cfg["ribs"] = [
        {key: _user(_get(rib, k[0]), k[1]) for key, k in RIB_KEYS.items()} for rib in spec.ribs
    ]
    cfg["fit"] = {key: v[0] for key, v in FIT_SCHEMA.items()}
    return cfg


def spec_from_config(cfg: dict):
    """The :class:`~diffguide.machine.spec.MachineSpec` (SI) of a validated configuration."""
    from ..fe.materials import Material
    from ..fe.mesh import Rib
    from ..fe.table import TableSpec
    from ..guideway.carriage import CarriageSpec
    from ..machine.spec import GuidewaySpec, MachineSpec, ScrewSpec

    si = {k[0]: _si(cfg[sec][key], k[1]) for sec, keys in KEYS.items() for key, k in keys.items()}

    def fields(prefix):
        n = len(prefix) + 1
        return {p[n:]: v for p, v in si.items() if p.startswith(prefix + ".") and "." not in p[n:]}

    table = TableSpec(
        **fields("table"), material=Material(**fields("table.material"), name="table")
    )
    ribs = [
        Rib(**{RIB_KEYS[key][0]: _si(v, RIB_KEYS[key][1]) for key, v in rib.items()})
        for rib in cfg.get("ribs", [])
    ]
    return MachineSpec(
        table=table,
        guideway=GuidewaySpec(**fields("guideway")),
        carriage=CarriageSpec(**fields("carriage")),
        screw=ScrewSpec(**fields("screw")),
        points={name: _si(xy, 1e3) for name, xy in cfg["points"].items()},
        ribs=ribs,
        gravity=si["gravity"],
        stroke=si["stroke"],
    )


def _defaults() -> dict:
    return config_from_spec(presets.majda2012())


@functools.cache
def schema() -> dict[str, dict[str, tuple]]:
    """``{section: {key: (default, kind, low, high, help)}}``: every key with its default (the
    ``majda2012`` preset, :func:`diffguide.presets.majda2012`), kind and allowed range. Built on
    first use (the preset's types import JAX; ``--help`` should not)."""
    defaults = _defaults()
    return {
        sec: {key: (defaults[sec][key], *k[2:]) for key, k in keys.items()}
        for sec, keys in KEYS.items()
    }


RIB_SCHEMA: dict[str, tuple] = {key: (_RIB_DEFAULTS[key], *k[2:]) for key, k in RIB_KEYS.items()}


def __getattr__(name: str):
    """``SCHEMA``: :func:`schema` (a module constant in diffguide 0.1)."""
    if name == "SCHEMA":
        return schema()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def default_config() -> dict:
    """The ``majda2012`` preset as a configuration (user units)."""
    return _defaults()


def carriage_from_config(cfg: dict, preload_fraction=None):
    """The runner block of a configuration (:func:`~diffguide.guideway.carriage_from_spec`)."""
    from ..guideway.carriage import carriage_from_spec
    from ..machine.build import with_overrides

    spec = with_overrides(spec_from_config(cfg), preload_fraction=preload_fraction)
    return carriage_from_spec(spec.carriage)


def table_from_config(cfg: dict, *, thickness=None, E=None, nx=None, ny=None, nut=True):
    """The :class:`~diffguide.fe.table.TableModel` of a configuration (SI overrides allowed)."""
    from ..machine.build import table_from_spec, with_overrides

    spec = with_overrides(spec_from_config(cfg), thickness=thickness, E=E, nx=nx, ny=ny)
    return table_from_spec(spec, nut=nut)


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
            raise ValueError(f"{where}: {value} outside the allowed range [{lo}, {hi}]")
        return value
    if kind == "float":
        v = _number(value, where, "value")
        if not lo <= v <= hi:
            raise ValueError(f"{where}: {v:g} outside the allowed range [{lo:g}, {hi:g}] ({help_})")
        return v
    if kind == "pair":
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise ValueError(f"{where}: must be a list of two numbers [a, b], got {value!r}")
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
    cfg = default_config()
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
                f"{', '.join([*schema(), 'points', 'ribs', 'fit'])}"
            )
        if not isinstance(body, dict):
            raise ValueError(f"{where}: must be a table of keys")
        for key, value in body.items():
            if key not in schema()[section]:
                raise ValueError(
                    f"{source}: key '{section}.{key}' is unknown; allowed: "
                    f"{', '.join(schema()[section])}"
                )
            cfg[section][key] = _check(
                value, schema()[section][key], f"{source}: key '{section}.{key}'"
            )
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
    return validate_config(raw, str(path))


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
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
    for section, keys in schema().items():
        lines.append(f"[{section}]")
        for key, spec in keys.items():
            lines.append(f"{key} = {_toml_value(cfg[section][key])}  # {spec[4]}")
        lines.append("")
    lines.append("[points]  # control points on the table top: name = [x_mm, y_mm] from its centre")
    for name, xy in cfg["points"].items():
        lines.append(f"{name} = {_toml_value(xy)}")
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
    return "\n".join(lines) + "\n"
