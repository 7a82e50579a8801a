"""Where a machine file's table comes from: diffguide's plate (the default) or the user's FE
model, a statically reduced (superelement) matrix.

::

    [table]
    source = "superelement"          # "plate" (default) or "superelement"
    file = "superelement/plate.toml" # the superelement description file, relative to this TOML
    length_mm = 1000.0               # still the table's extent: footprints and points on it
    width_mm = 500.0

The description file (format, matrix, nodes, interfaces, points:
:mod:`diffguide.io.superelement_file`, ``docs/superelement.md``) says which file holds the
matrix and which retained node is which carriage, the nut and each control point; without a
``[points]`` section the machine's control points are the description's (at their nodes). With
``source = "superelement"`` the plate's keys — ``[table] thickness_mm``, ``E_GPa``, ``nu``,
``density_kg_m3``, ``mesh_nx``, ``mesh_ny``, ``[[ribs]]`` and ``[fit] thickness_prior_mm`` —
have no meaning (the matrix is the table's stiffness and the file its weight): a file that gives
them is refused, naming the key, rather than silently ignoring them. :func:`resolve_table_source`
takes the two keys out of the raw file before it is validated (as
:func:`~diffguide.io.carriage_block.resolve_catalogue` does for a catalogue block) and
:func:`config_machine` builds the machine of a configuration from either source.
"""

import os
import re
from pathlib import Path

SOURCES = ("plate", "superelement")
#: Keys of a machine file that describe the plate only (refused with an imported table).
PLATE_ONLY = ("table.thickness_mm", "table.E_GPa", "table.nu", "table.density_kg_m3",
              "table.mesh_nx", "table.mesh_ny", "ribs", "fit.thickness_prior_mm")


def key_line(path, section: str, key: str) -> int | None:
    """The line number (1-based) of ``key = …`` in ``[section]`` of the TOML file ``path``, or
    ``None`` (not found, not readable): for messages only."""
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return None
    current = None
    for i, line in enumerate(lines, 1):
        s = line.strip()
        head = re.match(r"^\[\s*([^\[\]]+?)\s*\]", s)
        if head:
            current = head.group(1)
        elif current == section and re.match(rf"^{re.escape(key)}\s*=", s):
            return i
    return None


def _where(source: str, key: str) -> str:
    line = key_line(source, "table", key) if os.path.isfile(source) else None
    return f"{source}" + (f", line {line}" if line else "") + f": key 'table.{key}'"


def resolve_table_source(raw: dict, source: str) -> tuple[dict, dict | None]:
    """``raw`` without ``[table] source`` and ``file``, and the table's source.

    Arguments:
        raw: the machine file's mapping. source: its path (the description file is relative to
            its folder; a name that is not a file: relative to the working folder).

    Returns:
        ``(raw, info)``: ``info`` is ``None`` for the plate, else ``{"source": "superelement",
        "file": the description file's path, "given": the path as written}``.

    Raises:
        ValueError: an unknown source, a missing or unreadable ``file`` (naming the line and
            key), or a plate-only key next to ``source = "superelement"``.
    """
    table = raw.get("table") if isinstance(raw, dict) else None
    if not isinstance(table, dict) or not {"source", "file"} & table.keys():
        return raw, None
    table = dict(table)
    kind = table.pop("source", "plate")
    given = table.pop("file", None)
    out = dict(raw, table=table)
    if kind not in SOURCES:
        raise ValueError(f"{_where(source, 'source')}: {kind!r} is not allowed; allowed: "
                         f"{', '.join(SOURCES)}")
    if kind == "plate":
        if given is not None:
            raise ValueError(f"{_where(source, 'file')}: a file is only read with source = "
                             '"superelement" (the plate is built from the [table] keys)')
        return out, None
    if not isinstance(given, str) or not given.strip():
        raise ValueError(f"{_where(source, 'file' if given is not None else 'source')}: "
                         'source = "superelement" needs file = "DESCRIPTION.toml" (the '
                         "superelement description file, relative to this file)")
    base = Path(source).parent if os.path.isfile(source) else Path(".")
    path = base / given
    if not path.is_file():
        raise ValueError(f"{_where(source, 'file')}: the superelement description file "
                         f"{str(path)!r} does not exist")
    for key in PLATE_ONLY:
        section, _, name = key.partition(".")
        body = raw.get(section)
        if (name and isinstance(body, dict) and name in body) or (not name and body):
            line = key_line(source, section, name) if name else None
            at = f"{source}" + (f", line {line}" if line else "")
            raise ValueError(
                f"{at}: key '{key}' describes diffguide's plate, which an imported table "
                f'(source = "superelement") does not use: its stiffness and weight come from '
                f"{given}; remove the key (the fit estimates a stiffness scale instead of a "
                "thickness: [fit] stiffness_prior)")
    return out, {"source": "superelement", "file": str(path), "given": given}


def imported_source(cfg: dict) -> dict | None:
    """The configuration's table source when it is imported (:func:`resolve_table_source`),
    else ``None`` (diffguide's plate)."""
    return cfg.get("table_source")


_TABLES: dict = {}


def _description(path: str):
    """The imported table of a description file, read once per file version."""
    from .superelement_file import load_imported_table

    st = os.stat(path)
    key = (os.path.abspath(path), st.st_mtime_ns, st.st_size)
    if key not in _TABLES:
        if len(_TABLES) >= 4:
            _TABLES.pop(next(iter(_TABLES)))
        _TABLES[key] = load_imported_table(path)
    return _TABLES[key]


def describe_source(cfg: dict) -> list[str]:
    """Lines (TOML comments) stating the table's source for ``config --explain``: the plate,
    or the description file, its format, matrix, and the retained node of each interface and
    control point."""
    src = imported_source(cfg)
    if src is None:
        return ["# table: diffguide's plate (source = \"plate\")  # default"]
    data = _description(src["file"])
    lines = ['# table: imported, source = "superelement"  # file',
             f"# file = \"{src['given']}\" ({src['file']})  # file",
             f"# format {data.format}: {data.matrix.source}, {len(data.matrix.dofs)} retained "
             f"DOF, {len(data.coords)} nodes  # {src['given']}"]
    inter = ", ".join(f"{k} = node {v}" for k, v in data.interfaces.items())
    lines.append(f"# interfaces: {inter}  # {src['given']}")
    pts = []
    for name, (pt, rigid_to) in data.points.items():
        how = (f"rigid to {rigid_to}" if rigid_to else
               f"{len(pt.neighbours)} neighbours" if pt.neighbours else "own rotations")
        if pt.below is not None:
            how += (", fibre below" + (", mid-surface yaw" if pt.neighbours_below else ""))
        pts.append(f"{name} = node {pt.node} ({how})")
    lines.append(f"# points: {', '.join(pts)}  # {src['given']}")
    w = data.weight
    lines.append("# self-weight: " + (f"mass {w[0]:g} kg at {list(w[1])} m" if w else
                                      "the matrix file's reduced loads")
                 + f"  # {src['given']}")
    return lines


def config_machine(cfg: dict, *, nx: int | None = None, ny: int | None = None,
                   points: dict | None = None, stiffness_scale=None, **overrides):
    """The :class:`~diffguide.machine.Machine` of a validated configuration, whichever the
    table's source.

    Arguments:
        cfg: the configuration (:func:`diffguide.io.config.load_config`).
        nx, ny: the plate's mesh (``None``: the file's); refused for an imported table.
        points: control points ``{name: (x, y)}`` (m) in place of the file's; for an imported
            table each must be a retained node of the description file.
        stiffness_scale: a factor on an imported table's stiffness (may be traced;
            :func:`~diffguide.fe.superelement.scaled_table`); refused for the plate.
        overrides: :func:`~diffguide.machine.build.build_machine`'s (``thickness``,
            ``preload_fraction``, …; SI); an imported table takes ``preload_fraction`` only.
    """
    import equinox as eqx

    from ..fe.superelement import scaled_table
    from ..machine.build import build_machine, with_overrides
    from ..machine.imported import build_imported_machine, interface_names
    from .config_spec import spec_from_config
    from .superelement_file import resolve_points

    spec = spec_from_config(cfg)
    src = imported_source(cfg)
    if src is None:
        if stiffness_scale is not None:
            raise ValueError("a stiffness scale applies to an imported table only (source = "
                             '"superelement"); the plate has a thickness')
        return build_machine(spec, nx=nx, ny=ny, points=points, **overrides)
    if nx is not None or ny is not None:
        raise ValueError(f"--mesh: the table is imported from {src['given']} (source = "
                         '"superelement"): it has no mesh to set')
    plate = sorted(k for k, v in overrides.items() if v is not None and k != "preload_fraction")
    if plate:
        raise ValueError(f"{', '.join(plate)}: not a parameter of the imported table "
                         f"{src['given']} (only preload_fraction and stiffness_scale are)")
    spec = with_overrides(spec, points=points, preload_fraction=overrides.get("preload_fraction"))
    data = _description(src["file"])
    pts = resolve_points(src["file"], data, interface_names(spec))
    try:
        machine = build_imported_machine(spec, data.matrix, data.coords, data.interfaces, pts,
                                         weight=data.weight)
    except KeyError as exc:  # a point or interface without its node: bad input, named
        raise ValueError(f"{exc.args[0]} (the table of {src['given']}: measure or predict at "
                         f"its retained points, {', '.join(data.points)})") from None
    if stiffness_scale is not None:
        machine = eqx.tree_at(lambda m: m.table, machine,
                              scaled_table(machine.table, stiffness_scale))
    return machine


def machine_builder(cfg: dict, nx: int | None = None, ny: int | None = None):
    """``make_machine(points, **kw)`` for :func:`diffguide.inverse.predict.predict`: the
    configuration's machine with ``points`` and the fitted structure (:func:`config_machine`);
    ``None`` for the plate (predict's own builder)."""
    if imported_source(cfg) is None:
        return None
    return lambda points, **kw: config_machine(cfg, nx=nx, ny=ny, points=points, **kw)


def retained_points(cfg: dict) -> dict:
    """``{name: (x, y)}`` (m) of the control points an imported table retains (its
    description file's points, at their nodes' coordinates): the only places it can be
    measured or predicted (``plan``'s candidate sites)."""
    src = imported_source(cfg)
    if src is None:
        raise ValueError("retained points: the table is diffguide's plate, not imported")
    data = _description(src["file"])
    return {name: tuple(float(v) for v in data.coords[pt.node][:2])
            for name, (pt, _) in data.points.items()}
