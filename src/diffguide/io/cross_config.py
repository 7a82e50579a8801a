"""A cross table's machine file (TOML): the one-axis file for the table's joint, and sections
of its own for the saddle's joint. User units, as the key names say; the defaults are the
``majda2012-cross`` preset (:func:`~diffguide.machine.paper_cross.majda2012_cross_spec`).

- ``[table]``, ``[guideway]``, ``[carriage]``, ``[screw]``, ``[machine]``, ``[points]``,
  ``[[ribs]]``: the table on its X rails, as in a one-axis machine file
  (:mod:`diffguide.io.config_spec`; the X rails lie on the saddle's top).
- ``[saddle]``: the keys of ``[table]`` for the saddle plate, in the Y axis frame: ``length_mm``
  along Y (its travel), ``width_mm`` along X.
- ``[guideway.y]``: the keys of ``[guideway]`` in the Y axis frame (``x' = Y``, ``y' = −X``):
  ``rail_y_mm`` the Y rails' ``y'`` (rail 1 first: the smaller ``y'``, the larger machine X),
  ``carriage_x_mm`` the carriages' Y from the saddle centre, ``carriage_footprint_mm`` (along
  the Y rail, across).
- ``[carriage.y]``: the keys of ``[carriage]`` (or a catalogue ``block``) for the Y blocks.
- ``[screw.y]``: the keys of ``[screw]`` for the Y screw (``nut_xy_mm`` in the Y axis frame).
- ``[machine.y]``: ``stroke_mm``, the Y stroke (gravity is ``[machine]``'s).
- ``[cross]``: ``x_guideway_height_mm``, the X guideway's assembly height (saddle top to table
  underside).
"""

import math
import os

from ..machine.cross_spec import GUIDEWAY_HEIGHT_RANGE, CrossSpec
from ..machine.paper_cross import majda2012_cross_spec
from .config import _read_toml, validate_config
from .config_spec import config_from_spec, spec_from_config

#: The Y joint's sections of a cross machine file and the one-axis sections they stand for.
Y_SECTIONS = {"saddle": "table", "guideway.y": "guideway", "carriage.y": "carriage",
              "screw.y": "screw", "machine.y": "machine"}


def _defaults(spec) -> dict:
    """A one-axis specification as a file's sections, without ``[fit]`` (the fit's own
    defaults stand)."""
    cfg = config_from_spec(spec)
    del cfg["fit"]
    return cfg


def _over(defaults: dict, raw: dict) -> dict:
    """``raw``'s sections over ``defaults`` (key by key; ``[points]``, ``[[ribs]]`` and a
    ``[carriage]`` naming a catalogue ``block`` replace the default section whole)."""
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in defaults.items()}
    for section, body in raw.items():
        whole = section in ("points", "ribs") or (section == "carriage" and "block" in body)
        if isinstance(body, dict) and isinstance(out.get(section), dict) and not whole:
            out[section].update(body)
        else:
            out[section] = body
    return out


def _y_names(message: str) -> str:
    """A one-axis validation message with the Y joint's section names (its table: the
    saddle)."""
    for y, x in Y_SECTIONS.items():
        message = message.replace(f"'{x}.", f"'{y}.").replace(f"[{x}]", f"[{y}]")
    return message.replace(" the table", " the saddle")


def _split(raw: dict, source: str) -> tuple[dict, dict, dict]:
    """``(x_raw, y_raw, cross)``: the X joint's sections, the Y joint's (under their one-axis
    names), and ``[cross]``."""
    if not isinstance(raw, dict):
        raise ValueError(f"{source}: the configuration must be a table of sections")
    x_raw, y_raw = {}, {}
    for section, body in raw.items():
        if section in ("cross", "saddle"):
            continue
        if isinstance(body, dict) and isinstance(body.get("y"), dict):
            if f"{section}.y" not in Y_SECTIONS:
                raise ValueError(f"{source}: [{section}.y]: unknown section; allowed: "
                                 f"{', '.join(Y_SECTIONS)}")
            y_raw[Y_SECTIONS[f"{section}.y"]] = body["y"]
            body = {k: v for k, v in body.items() if k != "y"}
        x_raw[section] = body
    if "saddle" in raw:
        y_raw["table"] = raw["saddle"]
    extra = set(y_raw.get("machine", {})) - {"stroke_mm"}
    if extra:
        raise ValueError(f"{source}: key 'machine.y.{sorted(extra)[0]}' is unknown; allowed: "
                         "stroke_mm (gravity is [machine]'s)")
    cross = raw.get("cross", {})
    if not isinstance(cross, dict) or set(cross) - {"x_guideway_height_mm"}:
        raise ValueError(f"{source}: [cross]: allowed keys: x_guideway_height_mm")
    return x_raw, y_raw, cross


def cross_spec_from_raw(raw: dict, source: str = "<config>") -> CrossSpec:
    """The :class:`~diffguide.machine.cross_spec.CrossSpec` (SI) of a cross machine file's raw
    table (module docstring), the ``majda2012-cross`` preset's values where it says nothing.

    Raises:
        ValueError: one line naming ``source``, the section or key and the allowed range.
    """
    preset = majda2012_cross_spec()
    x_raw, y_raw, cross = _split(raw, source)
    x_cfg = validate_config(_over(_defaults(preset.x), x_raw), source)
    y_defaults = _defaults(preset.y)
    y_defaults["machine"]["gravity_m_s2"] = x_cfg["machine"]["gravity_m_s2"]
    try:
        y_cfg = validate_config(_over(y_defaults, y_raw), source)
    except ValueError as exc:
        raise ValueError(_y_names(str(exc))) from None
    h = cross.get("x_guideway_height_mm", preset.x_guideway_height * 1e3)
    lo, hi = (v * 1e3 for v in GUIDEWAY_HEIGHT_RANGE)
    if isinstance(h, bool) or not isinstance(h, (int, float)) or not (
            math.isfinite(h) and lo <= h <= hi):
        raise ValueError(f"{source}: key 'cross.x_guideway_height_mm' must be a number in "
                         f"[{lo:g}, {hi:g}] mm, got {h!r}")
    try:
        return CrossSpec(x=spec_from_config(x_cfg), y=spec_from_config(y_cfg),
                         x_guideway_height=float(h) / 1e3)
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from None


def load_cross_config(path: str | os.PathLike) -> CrossSpec:
    """Read a cross machine file (TOML; module docstring) into a
    :class:`~diffguide.machine.cross_spec.CrossSpec`."""
    return cross_spec_from_raw(_read_toml(path), str(path))


def is_cross_config(path: str | os.PathLike) -> bool:
    """Whether a machine file describes a cross table: it has a ``[saddle]`` or ``[cross]``
    section, or one of the Y joint's (``[guideway.y]``, ...)."""
    raw = _read_toml(path)
    return any(section in raw for section in ("saddle", "cross")) or any(
        isinstance(body, dict) and isinstance(body.get("y"), dict) for body in raw.values())


def cross_config_from_spec(spec: CrossSpec) -> dict:
    """A :class:`~diffguide.machine.cross_spec.CrossSpec` as a cross machine file's table (user
    units; the Y joint's sections nested as TOML reads ``[guideway.y]``)."""
    cfg = _defaults(spec.x)
    y = _defaults(spec.y)
    cfg["saddle"] = y["table"]
    for section in ("guideway", "carriage", "screw"):
        cfg[section]["y"] = y[section]
    cfg["machine"]["y"] = {"stroke_mm": y["machine"]["stroke_mm"]}
    cfg["cross"] = {"x_guideway_height_mm": spec.x_guideway_height * 1e3}
    return cfg
