"""What a machine file (TOML) may say and what it means: every key with its unit, kind, range
and default, and the conversion between a configuration and a machine specification.

A configuration is a nested mapping ``{section: {key: value}}`` in user units (mm, µm, GPa, N,
kg/m³, degrees, as the key names say). :data:`KEYS` maps each key to the field of the typed, SI
:class:`~diffguide.machine.spec.MachineSpec` it sets and the factor between the two;
:func:`spec_from_config` and :func:`config_from_spec` convert. The defaults are the
``majda2012`` machine (:func:`~diffguide.machine.majda2012.majda2012_spec`, the one definition
of its values). Reading, validating and writing files: :mod:`diffguide.io.config`.
"""

import functools

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
            2,
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
#: with the range ``[value/2, 2·value]`` (thickness) or ``[value/4, 2·value]`` (preload); the
#: stiffness scale of an imported table defaults to ``[1, 0.5, 2]``.
FIT_SCHEMA: dict[str, tuple] = {
    "structure": (
        "estimate",
        "str:estimate|fixed",
        None,
        None,
        "estimate the table thickness (an imported table: its stiffness scale) and the preload "
        "with the rails, or hold them fixed",
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
    "stiffness_prior": (
        None,
        "prior",
        0.01,
        100.0,
        "stiffness scale prior [value, lo, hi] of an imported table (source = "
        "\"superelement\"); its own stiffness is 1, the range [0.5, 2]",
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
    "rail_joints_mm": (
        (),
        "list",
        -1e5,
        1e5,
        "rail joints (mm along the rail, as rails.csv's s_mm): each profile gains a step "
        "there, its height fitted",
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
    cfg["export"] = {}  # the compensation exports' settings given (studies.exports.settings)
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
    from ..machine.majda2012 import majda2012_spec

    return config_from_spec(majda2012_spec())


@functools.cache
def schema() -> dict[str, dict[str, tuple]]:
    """``{section: {key: (default, kind, low, high, help)}}``: every key with its default (the
    ``majda2012`` machine, :func:`~diffguide.machine.majda2012.majda2012_spec`), kind and allowed
    range. Built on
    first use (the preset's types import JAX; ``--help`` should not)."""
    defaults = _defaults()
    return {
        sec: {key: (defaults[sec][key], *k[2:]) for key, k in keys.items()}
        for sec, keys in KEYS.items()
    }


RIB_SCHEMA: dict[str, tuple] = {key: (_RIB_DEFAULTS[key], *k[2:]) for key, k in RIB_KEYS.items()}


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
