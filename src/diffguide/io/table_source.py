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
:func:`~diffguide.io.carriage_block.resolve_catalogue` does for a catalogue block) and reads
the description once, into the configuration (``cfg["table_source"]["table"]``); the machine
of a configuration from either source: :func:`diffguide.jobs.machine.config_machine`.
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
        "file": the description file's path, "given": the path as written, "table": its
        :class:`~diffguide.machine.imported.ImportedTable`}``.

    Raises:
        ValueError: an unknown source, a missing or unreadable ``file`` (naming the line and
            key), a plate-only key next to ``source = "superelement"``, or a malformed
            description (:class:`~diffguide.io.superelement.SuperelementFileError`).
        OSError: a file the description names cannot be read.
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
    from .superelement_file import load_imported_table

    return out, {"source": "superelement", "file": str(path), "given": given,
                 "table": load_imported_table(path)}


def imported_source(cfg: dict) -> dict | None:
    """The configuration's table source when it is imported (:func:`resolve_table_source`),
    else ``None`` (diffguide's plate)."""
    return cfg.get("table_source")


def describe_source(cfg: dict) -> list[str]:
    """Lines (TOML comments) stating the table's source for ``config --explain``: the plate,
    or the description file, its format, matrix, and the retained node of each interface and
    control point."""
    src = imported_source(cfg)
    if src is None:
        return ["# table: diffguide's plate (source = \"plate\")  # default"]
    data = src["table"]
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


def retained_points(cfg: dict) -> dict:
    """``{name: (x, y)}`` (m) of the control points an imported table retains (its
    description file's points, at their nodes' coordinates): the only places it can be
    measured or predicted (``plan``'s candidate sites)."""
    src = imported_source(cfg)
    if src is None:
        raise ValueError("retained points: the table is diffguide's plate, not imported")
    data = src["table"]
    return {name: tuple(float(v) for v in data.coords[pt.node][:2])
            for name, (pt, _) in data.points.items()}
