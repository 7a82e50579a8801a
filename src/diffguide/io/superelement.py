r"""Reduced (superelement) stiffness matrices of the table from FE codes, and their node files.

Formats read (each error names the file, the line and the field):

- **CalculiX / Abaqus user-element matrix** (``.mtx``; what ``*SUBSTRUCTURE GENERATE`` +
  ``*SUBSTRUCTURE MATRIX OUTPUT`` write): ``*USER ELEMENT, NODES=n, LINEAR``; comment lines
  ``** ELEMENT NODES`` followed by ``**`` lines listing the node of each of the n positions; the
  active-DOF data lines (first line: the DOF of position 1; then ``k, d1, d2, …``: from position
  k on, DOF d1, d2, …); ``*MATRIX, TYPE=STIFFNESS``; the lower triangle row by row, comma
  separated, any number of values per line. CalculiX lists one DOF per position (a node with
  three retained DOF appears three times); Abaqus lists each node once with its DOF.
- **Nastran DMIG** (punch ``.pch`` or bulk data): the header ``DMIG NAME 0 IFO TIN TOUT POLAR
  NCOL`` with ``IFO = 6`` (symmetric) or 1 (square), real ``TIN`` 1 or 2; column entries
  ``DMIG NAME GJ CJ (blank) G1 C1 A1 (B1)`` with continuations ``G2 C2 A2 (B2) G3 C3 A3 (B3)``;
  small field (8 characters), large field (``DMIG*``, 16 characters, continuation lines
  starting with ``*``) or free field (commas); numbers as Nastran writes them (``1.5+3``,
  ``1.5D+03``). A symmetric matrix may give either triangle (or both, equal).
- **CalculiX reactions** (the ``.dat`` file's ``forces (fx,fy,fz) for set … and time …`` blocks
  of ``*NODE PRINT`` RF): the reduced matrix by unit displacements, one step per retained DOF
  (the deck of :mod:`docs/superelement`), and the reduced self-weight loads from a last step
  with every retained DOF held (``f_r = -RF``).
- **Node coordinates**: ``*NODE`` blocks of a CalculiX / Abaqus input file (``id, x, y, z``).

Units: the file's consistent units; ``length_unit`` (m per file unit: 1 for m, 1e-3 for mm)
converts to SI with forces in N (:meth:`~diffguide.fe.superelement.ReducedMatrix.scaled`).
"""

import os
import re
from pathlib import Path

import numpy as np

from .._core.limits import MAX_REDUCED_DOFS
from ..fe.superelement import ReducedMatrix


class SuperelementFileError(ValueError):
    """A malformed reduced-matrix or node file (names the file, line and field)."""


def _fail(path, line, message):
    where = f"{path}:{line}" if line else f"{path}"
    raise SuperelementFileError(f"{where}: {message}")


def _read_lines(path) -> list[str]:
    try:
        return Path(path).read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as exc:
        raise OSError(f"cannot read {path}: {exc.strerror}") from None


def _number(text: str, path, line, field: str) -> float:
    """A real as FE codes write it: ``1.5E3``, ``1.5D+03``, Nastran's ``1.5+3`` / ``-2.-4``."""
    s = text.strip().upper().replace("D", "E")
    if s and "E" not in s:
        s = re.sub(r"(?<=[0-9.])([+-])", r"E\1", s)
    try:
        value = float(s)
    except ValueError:
        _fail(path, line, f"field {field}: {text.strip()!r} is not a number")
    if not np.isfinite(value):
        _fail(path, line, f"field {field}: {text.strip()!r} is not finite")
    return value


_WHY_DOFS = ("a dense matrix of n x n values; a table reduced to its carriages, nut and "
             "control points retains a few hundred")


def _check_size(n: int, path, line) -> int:
    """``n`` retained DOF, refused beyond :data:`MAX_REDUCED_DOFS` before the matrix exists."""
    if n > MAX_REDUCED_DOFS:
        _fail(path, line, f"{n} retained DOF: allowed 1..{MAX_REDUCED_DOFS} ({_WHY_DOFS})")
    return n


def _int(text: str, path, line, field: str, lo: int = 1, hi: int | None = None) -> int:
    try:
        value = int(text.strip())
    except ValueError:
        _fail(path, line, f"field {field}: {text.strip()!r} is not an integer")
    if value < lo or (hi is not None and value > hi):
        rng = f"{lo}..{hi}" if hi is not None else f">= {lo}"
        _fail(path, line, f"field {field}: {value} is outside the allowed range {rng}")
    return value


# ---------------------------------------------------------------- CalculiX / Abaqus .mtx


def read_user_element_matrix(path: str | os.PathLike, *, length_unit: float = 1.0
                             ) -> ReducedMatrix:
    """The stiffness of a CalculiX / Abaqus ``*USER ELEMENT`` matrix file (module docstring),
    SI (``length_unit``: m per file unit), with zero loads. Only the symmetric
    (``*MATRIX, TYPE=STIFFNESS``, lower triangle) form."""
    lines = _read_lines(path)
    n_pos = header = None
    nodes: list[int] = []
    dof_lines: list[tuple[int, list[str]]] = []
    in_nodes = False
    k = 0
    for k, raw in enumerate(lines, start=1):
        s = raw.strip()
        up = s.upper().replace(" ", "")
        if up.startswith("*USERELEMENT"):
            m = re.search(r"NODES=(\d+)", up)
            if not m:
                _fail(path, k, "*USER ELEMENT needs NODES=<number of positions>")
            n_pos, header = int(m.group(1)), k
            if n_pos > MAX_REDUCED_DOFS:
                _fail(path, k, f"NODES={n_pos}: at most {MAX_REDUCED_DOFS} retained DOF "
                               f"({_WHY_DOFS})")
        elif up.startswith("**ELEMENTNODES"):
            in_nodes = True
        elif s.startswith("**"):
            if in_nodes:
                body = s[2:].strip().rstrip(",")
                if body:
                    nodes += [_int(t, path, k, "node") for t in body.split(",") if t.strip()]
        elif up.startswith("*MATRIX"):
            if "TYPE=STIFFNESS" not in up:
                _fail(path, k, "only *MATRIX, TYPE=STIFFNESS is read")
            if "UNSYMMETRIC" in up:
                _fail(path, k, "an unsymmetric matrix is not a stiffness diffguide can use")
            break
        elif s.startswith("*"):
            in_nodes = False
        elif s and header is not None:
            in_nodes = False
            dof_lines.append((k, [t for t in s.rstrip(",").split(",") if t.strip()]))
    else:
        _fail(path, None, "no *MATRIX, TYPE=STIFFNESS block")
    if n_pos is None:
        _fail(path, None, "no *USER ELEMENT line")
    if len(nodes) != n_pos:
        _fail(path, header, f"NODES={n_pos} but the '** ELEMENT NODES' comment lists "
                            f"{len(nodes)} nodes")
    dofs_at = [None] * n_pos
    for j, (ln, fields) in enumerate(dof_lines):
        if j == 0:
            start, ds = 1, fields
        else:
            start, ds = _int(fields[0], path, ln, "position", 1, n_pos), fields[1:]
        dl = [_int(t, path, ln, "dof", 1, 6) for t in ds]
        for pos in range(start - 1, n_pos):
            dofs_at[pos] = dl
    if dofs_at and dofs_at[0] is None:
        _fail(path, header, "no active-DOF data lines after *USER ELEMENT")
    dofs = tuple((nodes[p], d) for p in range(n_pos) for d in dofs_at[p])
    n = _check_size(len(dofs), path, header)
    values: list[float] = []
    for ln in range(k + 1, len(lines) + 1):
        s = lines[ln - 1].strip()
        if not s or s.startswith("**"):
            continue
        if s.startswith("*"):
            break
        values += [_number(t, path, ln, "matrix value") for t in s.rstrip(",").split(",")
                   if t.strip()]
    if len(values) != n * (n + 1) // 2:
        _fail(path, k, f"the lower triangle of a {n} x {n} matrix has {n * (n + 1) // 2} "
                       f"values, found {len(values)}")
    K = np.zeros((n, n))
    K[np.tril_indices(n)] = values
    K = K + np.tril(K, -1).T
    rm = ReducedMatrix(K=K, dofs=dofs, f=np.zeros(n), source=str(path))
    return rm if length_unit == 1.0 else rm.scaled(length_unit)


# ---------------------------------------------------------------- Nastran DMIG


def _bulk_cards(path, lines):
    """Bulk data cards as ``(line, [name, field2, field3, …])``, continuations joined."""
    cards = []
    for k, raw in enumerate(lines, start=1):
        text = raw.rstrip("\n")
        if not text.strip() or text.lstrip().startswith("$"):
            continue
        text = text.split("$", 1)[0].expandtabs(8)
        if "," in text:
            fields = [f.strip() for f in text.split(",")]
            first, data = fields[0], fields[1:9]
        elif text[:8].strip().endswith("*") or text.startswith("*"):
            first = text[:8].strip()
            data = [text[8 + 16 * i: 24 + 16 * i].strip() for i in range(4)]
        else:
            first = text[:8].strip()
            data = [text[8 + 8 * i: 16 + 8 * i].strip() for i in range(8)]
        is_cont = first == "" or first.startswith("+") or first.startswith("*")
        if is_cont:
            if not cards:
                _fail(path, k, "a continuation line before any card")
            cards[-1][1].extend(data)
        else:
            cards.append((k, [first.rstrip("*").upper()] + data))
    return cards


def read_dmig(path: str | os.PathLike, name: str | None = None, *,
              length_unit: float = 1.0) -> ReducedMatrix:
    """The symmetric stiffness matrix ``name`` (default: the file's only DMIG matrix) of a
    Nastran DMIG file (module docstring), SI (``length_unit``: m per file unit), zero loads."""
    cards = [c for c in _bulk_cards(path, _read_lines(path)) if c[1][0] == "DMIG"]
    if not cards:
        _fail(path, None, "no DMIG card")
    headers = {c[1][1].upper(): c for c in cards if c[1][2:3] == ["0"]}
    if name is None:
        if len(headers) != 1:
            _fail(path, None, f"the file holds the DMIG matrices {sorted(headers)}: name one")
        name = next(iter(headers))
    name = name.upper()
    if name not in headers:
        _fail(path, None, f"no DMIG header for matrix {name!r} (found {sorted(headers)})")
    ln, h = headers[name]
    ifo = _int(h[3], path, ln, "IFO (4)", 1, 9)
    if ifo not in (1, 6):
        _fail(path, ln, f"field IFO (4): form {ifo}; a stiffness matrix is form 6 (symmetric) "
                        "or 1 (square)")
    tin = _int(h[4], path, ln, "TIN (5)", 1, 4)
    if tin not in (1, 2):
        _fail(path, ln, f"field TIN (5): type {tin} is complex; a real matrix (1 or 2) is needed")
    entries: dict[tuple, float] = {}
    for ln, c in cards:
        if c[1].upper() != name or c[2:3] == ["0"]:
            continue
        col = (_int(c[2], path, ln, "GJ (3)"), _int(c[3] or "1", path, ln, "CJ (4)", 0, 6))
        data = c[5:]
        for i in range(0, len(data) - 2, 4):
            g, comp, a = data[i: i + 3]
            if not g:
                continue
            row = (_int(g, path, ln, f"G (field {i + 6})"),
                   _int(comp or "1", path, ln, f"C (field {i + 7})", 0, 6))
            value = _number(a, path, ln, f"A (field {i + 8})")
            key = (row, col)
            if ifo == 6 and (col, row) in entries and row != col:
                if not np.isclose(entries[(col, row)], value, rtol=1e-9, atol=0):
                    _fail(path, ln, f"symmetric matrix {name}: entry {row}-{col} is {value} but "
                                    f"{col}-{row} is {entries[(col, row)]}")
                continue
            entries[key] = entries.get(key, 0.0) + value
    keys = sorted({k for rc in entries for k in rc})
    for node, d in keys:
        if d == 0:
            _fail(path, None, f"node {node} component 0 (a scalar point) is not a table DOF")
    index = {k: i for i, k in enumerate(keys)}
    n = _check_size(len(keys), path, ln)
    K = np.zeros((n, n))
    for (row, col), v in entries.items():
        K[index[row], index[col]] = v
        if ifo == 6 and row != col:
            K[index[col], index[row]] = v
    rm = ReducedMatrix(K=K, dofs=tuple(keys), f=np.zeros(n), source=str(path))
    return rm if length_unit == 1.0 else rm.scaled(length_unit)


# ---------------------------------------------------------------- CalculiX .dat reactions


_BLOCK = re.compile(r"forces \(fx,fy,fz\) for set (\S+) and time\s+(\S+)", re.IGNORECASE)


def read_ccx_reactions(path: str | os.PathLike) -> list[dict[int, np.ndarray]]:
    """The ``*NODE PRINT`` RF blocks of a CalculiX ``.dat`` file, in file order: one
    ``{node: (fx, fy, fz)}`` per step (the blocks of one time merged: several node sets)."""
    lines = _read_lines(path)
    steps: list[dict[int, np.ndarray]] = []
    times: list[str] = []
    current = None
    for k, raw in enumerate(lines, start=1):
        m = _BLOCK.search(raw)
        if m:
            if not times or times[-1] != m.group(2):
                steps.append({})
                times.append(m.group(2))
            current = steps[-1]
            continue
        parts = raw.split()
        if current is None or not parts:
            continue
        if len(parts) != 4 or not parts[0].isdigit():
            current = None  # another kind of block
            continue
        current[int(parts[0])] = np.array([_number(t, path, k, name) for t, name in
                                           zip(parts[1:], ("fx", "fy", "fz"))])
    if not steps:
        _fail(path, None, "no 'forces (fx,fy,fz) for set …' block (*NODE PRINT … RF)")
    return steps


def read_cload(path: str | os.PathLike) -> dict[tuple[int, int], float]:
    """``{(node, dof): value}`` from the ``*CLOAD`` blocks of a CalculiX / Abaqus input file
    (``node, dof, magnitude`` per line; repeated entries add up)."""
    out: dict[tuple[int, int], float] = {}
    inside = False
    for k, raw in enumerate(_read_lines(path), start=1):
        s = raw.strip()
        if not s or s.startswith("**"):
            continue
        if s.startswith("*"):
            inside = s.upper().replace(" ", "").split(",")[0] == "*CLOAD"
            continue
        if inside:
            t = s.rstrip(",").split(",")
            if len(t) != 3:
                _fail(path, k, f"a *CLOAD line is 'node, dof, magnitude', got {s!r}")
            key = (_int(t[0], path, k, "node"), _int(t[1], path, k, "dof", 1, 6))
            out[key] = out.get(key, 0.0) + _number(t[2], path, k, "magnitude")
    return out


def reduced_from_reactions(path: str | os.PathLike, dofs, *, gravity_step: bool = True,
                           held_loads: dict[tuple[int, int], float] | None = None,
                           length_unit: float = 1.0) -> ReducedMatrix:
    """The reduced matrix from a CalculiX ``.dat`` of unit-displacement steps: step ``j`` moves
    retained DOF ``dofs[j]`` (``(node, dof)``, dof 1-3; a rotation node's 1-3 are rotations) by
    1 with every other retained DOF held; column ``j`` of ``K`` is the reactions RF at the
    retained DOF. With ``gravity_step``, one more step holds every retained DOF under the
    self-weight: ``f = -RF + held_loads``; CalculiX's RF of a held node is the elements' force on
    it and leaves out the load applied at the node itself, so ``held_loads`` (``{(node, dof):
    value}``, :func:`read_cload`) gives those, a rigid footprint's as the wrench at its REF /
    ROT node. SI with ``length_unit`` (m per file unit)."""
    dofs = tuple((int(a), int(b)) for a, b in dofs)
    _check_size(len(dofs), path, None)
    steps = read_ccx_reactions(path)
    need = len(dofs) + (1 if gravity_step else 0)
    if len(steps) != need:
        _fail(path, None, f"{len(steps)} RF steps, expected {need} ({len(dofs)} unit "
                          f"displacements{' + the gravity step' if gravity_step else ''})")

    def column(j):
        out = np.empty(len(dofs))
        for i, (node, d) in enumerate(dofs):
            if node not in steps[j]:
                _fail(path, None, f"step {j + 1}: no RF of node {node} (print RF at every "
                                  "retained node)")
            out[i] = steps[j][node][d - 1]
        return out

    K = np.stack([column(j) for j in range(len(dofs))], axis=1)
    K = 0.5 * (K + K.T)
    f = -column(len(dofs)) if gravity_step else np.zeros(len(dofs))
    for key, value in (held_loads or {}).items():
        if tuple(key) not in dofs:
            _fail(path, None, f"a held load at node {key[0]} DOF {key[1]}, not a retained DOF")
        f[dofs.index(tuple(key))] += value
    rm = ReducedMatrix(K=K, dofs=dofs, f=f, source=str(path))
    return rm if length_unit == 1.0 else rm.scaled(length_unit)


# ---------------------------------------------------------------- nodes


def read_inp_nodes(path: str | os.PathLike, *, length_unit: float = 1.0
                   ) -> dict[int, np.ndarray]:
    """``{node: (x, y, z)}`` (m) from the ``*NODE`` blocks of a CalculiX / Abaqus input file
    (``length_unit``: m per file unit)."""
    out: dict[int, np.ndarray] = {}
    inside = False
    for k, raw in enumerate(_read_lines(path), start=1):
        s = raw.strip()
        if not s or s.startswith("**"):
            continue
        if s.startswith("*"):
            key = s.upper().replace(" ", "").split(",")[0]
            inside = key == "*NODE"
            continue
        if inside:
            t = [x for x in s.rstrip(",").split(",")]
            if len(t) < 2 or len(t) > 4:
                _fail(path, k, f"a *NODE line is 'id, x, y, z', got {s!r}")
            node = _int(t[0], path, k, "node id")
            xyz = [_number(v, path, k, c) for v, c in zip(t[1:], "xyz")]
            out[node] = length_unit * np.array(xyz + [0.0] * (3 - len(xyz)))
    if not out:
        _fail(path, None, "no *NODE block")
    return out
