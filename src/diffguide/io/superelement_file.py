"""The description file of an imported table (TOML): which matrix file, which nodes are what.

::

    format = "ccx-mtx"            # "ccx-mtx" / "abaqus-mtx" (*USER ELEMENT), "dmig",
                                  # "ccx-reactions" (a .dat of unit-displacement steps)
    matrix = "table.mtx"          # relative to this file
    nodes = "table_nodes.inp"     # *NODE lines: the retained nodes' coordinates
    length_unit = 0.001           # m per file unit (1e-3: mm, N, N·mm); default 1
    dmig_name = "KAAX"            # "dmig": the matrix's name (default: the only one)
    dofs = [[900001, 1], …]       # "ccx-reactions": the retained DOF in step order
    held_loads = "loads.inp"      # "ccx-reactions": *CLOAD of the held nodes' self-weight
    mass = 180.0                  # kg, with cog: the self-weight when the file has none
    cog = [0.0, 0.0, -0.01]       # m
    [rotation_nodes]              # CalculiX *RIGID BODY: "ROT NODE" = REF NODE
    "900101" = 900001
    [interfaces]                  # the machine's carriages C{rail}{carriage}, then nut
    C11 = 900001
    …
    nut = 900005
    [points.P1]                   # every control point of the machine
    node = 24269
    neighbours = [24267, 24271, 24083, 24455]   # or: rigid_to = "nut"; or neither (DOF 4-6)
    below = 20123                 # optional: the node under it on the underside (roll, pitch
                                  # of the fibre through the point, as a shell's rotation)
    neighbours_below = [20121, 20125, 19935, 20307]   # optional, with below: the nodes under
                                  # the neighbours (yaw of the mid-surface, as a shell's)

Every error names the file and the key.
"""

import os
import tomllib
from pathlib import Path

from ..fe.superelement import RetainedPoint, with_rotation_nodes
from ..machine.imported import ImportedTable
from . import superelement as se

FORMATS = ("ccx-mtx", "abaqus-mtx", "dmig", "ccx-reactions")


def _bad(path, key, message):
    raise se.SuperelementFileError(f"{path}: key {key!r}: {message}")


def _node(path, key, value):
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        _bad(path, key, f"a node number (an integer >= 1) is needed, got {value!r}")
    return value


def load_imported_table(path: str | os.PathLike) -> ImportedTable:
    """Read a description file (module docstring) and the files it names."""
    path = Path(path)
    try:
        cfg = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise OSError(f"cannot read {path}: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise se.SuperelementFileError(f"{path}: not valid TOML: {exc}") from None
    known = {"format", "matrix", "nodes", "length_unit", "dmig_name", "dofs", "held_loads",
             "mass", "cog", "rotation_nodes", "interfaces", "points"}
    for key in cfg:
        if key not in known:
            _bad(path, key, f"unknown key; allowed: {', '.join(sorted(known))}")
    fmt = cfg.get("format")
    if fmt not in FORMATS:
        _bad(path, "format", f"{fmt!r}; allowed: {', '.join(FORMATS)}")
    for key in ("matrix", "nodes", "interfaces", "points"):
        if key not in cfg:
            _bad(path, key, "missing")
    unit = cfg.get("length_unit", 1.0)
    if isinstance(unit, bool) or not isinstance(unit, (int, float)) or not 1e-6 <= unit <= 1:
        _bad(path, "length_unit", f"m per file unit, within 1e-6 .. 1; got {unit!r}")
    base = path.parent
    matrix = base / cfg["matrix"]
    if fmt in ("ccx-mtx", "abaqus-mtx"):
        rm = se.read_user_element_matrix(matrix)
    elif fmt == "dmig":
        rm = se.read_dmig(matrix, cfg.get("dmig_name"))
    else:
        dofs = cfg.get("dofs")
        if not isinstance(dofs, list) or not all(
                isinstance(d, list) and len(d) == 2 for d in dofs):
            _bad(path, "dofs", "a list of [node, dof] pairs in the order of the steps")
        held = se.read_cload(base / cfg["held_loads"]) if "held_loads" in cfg else None
        rm = se.reduced_from_reactions(matrix, dofs, held_loads=held)
    rot = {}
    for k, v in cfg.get("rotation_nodes", {}).items():
        if not k.isdigit():
            _bad(path, f"rotation_nodes.{k}", "the key is a node number")
        rot[int(k)] = _node(path, f"rotation_nodes.{k}", v)
    if rot:
        rm = with_rotation_nodes(rm, rot)
    if unit != 1.0:  # after the rotation nodes are known: their DOF 1-3 are rotations
        rm = rm.scaled(unit)
    coords = se.read_inp_nodes(base / cfg["nodes"], length_unit=unit)
    interfaces = {str(k): _node(path, f"interfaces.{k}", v) for k, v in cfg["interfaces"].items()}
    points = {}
    for name, p in cfg["points"].items():
        key = f"points.{name}"
        if not isinstance(p, dict):
            _bad(path, key, "a table with node (and neighbours or rigid_to)")
        allowed = ("node", "neighbours", "rigid_to", "below", "neighbours_below")
        extra = set(p) - set(allowed)
        if extra:
            _bad(path, key, f"unknown keys {sorted(extra)}; allowed: {', '.join(allowed)}")
        rigid_to = p.get("rigid_to")
        if rigid_to is not None:
            order = list(interfaces)
            if rigid_to not in order:
                _bad(path, f"{key}.rigid_to", f"{rigid_to!r} is not one of {order}")
        nb = [_node(path, f"{key}.neighbours", n) for n in p.get("neighbours", [])]
        below = _node(path, f"{key}.below", p["below"]) if "below" in p else None
        if below is not None and not nb:
            _bad(path, f"{key}.below", "needs neighbours too (they give the yaw)")
        nbb = [_node(path, f"{key}.neighbours_below", n) for n in p.get("neighbours_below", [])]
        if nbb and (below is None or len(nbb) != len(nb)):
            _bad(path, f"{key}.neighbours_below", f"needs below, and one node per neighbour "
                 f"({len(nb)})")
        points[name] = (RetainedPoint(name=name, node=_node(path, f"{key}.node", p.get("node")),
                                      neighbours=tuple(nb), below=below,
                                      neighbours_below=tuple(nbb)), rigid_to)
    weight = None
    if "mass" in cfg or "cog" in cfg:
        cog = cfg.get("cog")
        if not (isinstance(cog, list) and len(cog) == 3):
            _bad(path, "cog", "the centre of gravity [x, y, z] (m) is needed with mass")
        weight = (float(cfg.get("mass", 0.0)), tuple(float(c) * unit for c in cog))
    return ImportedTable(matrix=rm, coords=coords, interfaces=interfaces, points=points,
                         weight=weight, format=fmt)
