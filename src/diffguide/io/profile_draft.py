r"""A *draft* profile written from a vendor file's own layout and metadata
(``diffguide import FILE --draft-profile OUT.toml``), for the user to complete.

What the file itself says is read: its encoding, separator and decimal mark, the header row of
its table (the line before the longest run of numeric rows), the position column and its unit
(mm or inch), the value columns with their quantities (ISO 230-1 names or the common words:
linear, straightness, roll, pitch, yaw) and units (µm, mm, in, µm/m, mm/m, µrad, arcsec, ...),
run and direction columns or a "Run 1 Fwd" naming of the columns, an ISO 230-2 summary's mean
and s per direction, and the ``key: value`` metadata lines above the table (point, x, y,
quantity, unit, instrument, runs; serials, dates, temperatures and operators are read by any
profile and kept in the report). A ``Targets:`` list with ``Data:`` records, and the
vendor-exchange grid of the built-in ``exx`` profile, are recognised too.

What the file does not say is left for the user, each on one line marked ``# REQUIRED``
whose value is ``"?"`` — the profile refuses to load while one is left
(:func:`~diffguide.io.profiles.check_profile`): typically the point's name and its x, y on the
table (the machine's control points listed as comments when a configuration is given), the
machine coordinate of x = 0, the quantity of a column named by a word diffguide does not know.
Guesses the user should confirm (an instrument, an x0 of 0) are marked ``# CHECK``.
"""

import os
import re

from .csvtable import decode, read_bytes
from .measurements import _BACKWARD, _FORWARD, LINEAR_UNITS, unit_key
from .profile_draft_lines import _BRACKET, _SEPARATORS, _Draft, _direction_aliases
from .profile_draft_lines import TODO as TODO  # the placeholder a user replaces
from .profile_draft_lines import _instrument_line, _lit, _num, _point_lines, _q, _split
from .profile_draft_lines import _unit_of, _x0_lines
from .profile_words import DIRECTION_WORDS, META_ROLES, quantity_of


class _Layout:
    """The table found in a file: separator, decimal comma, header (line index), data rows."""

    def __init__(self, lines):
        best = None
        for sep, name in _SEPARATORS:
            comma = sep in ("\t", ";")
            rows = [_split(s, sep) for _, s in lines]
            i = 0
            while i < len(rows):
                j = i
                n = len(rows[i])
                while (j < len(rows) and len(rows[j]) == n and n >= 2
                       and sum(_num(f, comma) for f in rows[j]) * 2 >= n):
                    j += 1
                if j - i >= 3 and (best is None or j - i > best[0]):
                    best = (j - i, sep, name, comma, i, j, rows)
                i = max(j, i + 1)
        if best is None:
            raise ValueError("no table found (at least three rows of numbers, two or more "
                             "fields each, separated by tab, ';', ',' or spaces)")
        _, self.sep, self.sep_name, self.comma, first, last, rows = best
        self.comma = self.comma and any(
            re.fullmatch(r"[+-]?\d*,\d+", f) for r in rows[first:last] for f in r)
        head = first - 1
        self.header = rows[head] if head >= 0 and len(rows[head]) == len(rows[first]) else None
        self.header_index = head if self.header is not None else None
        self.first = first
        self.data = rows[first:last]
        self.lines = lines


def _metadata(lines, upto: int, sep: str) -> list[tuple[str, str]]:
    """``(key, value)`` of the metadata lines before line index ``upto``."""
    out = []
    seps = ([sep] if sep != " " else []) + [":", "="]
    for _, s in lines[:upto]:
        found = [(s.index(c), c) for c in seps if c in s]
        if not found:
            continue
        c = min(found)[1]
        key, _, value = s.partition(c)
        value = value.strip().strip(c).strip().strip('"')
        if key.strip() and value:
            out.append((key.strip().strip('"'), value))
    return out


def _meta_role(key: str) -> str | None:
    k = " ".join(key.lower().split())
    return next((role for role, rx in META_ROLES.items() if re.fullmatch(rx, k)), None)


def _run_dir_template(header: str):
    """``(regex, run, direction word)`` of a column named like ``Run 1 Fwd`` / ``run2_bwd`` /
    ``Lauf 3 rück``; ``None`` otherwise."""
    m = re.fullmatch(r"(?P<pre>.*?\b(?:run|lauf|cycle|zyklus|messung)\s*[_#]?\s*)(?P<run>\d+)"
                     r"(?P<mid>[\s_]*)(?P<dir>[^\s_()\[\]]+)?(?P<post>.*)", header, re.I)
    if not m:
        return None
    word = m.group("dir")
    if word and word.lower() not in _FORWARD + _BACKWARD + tuple(DIRECTION_WORDS):
        return None
    return m, m.group("run"), word


def _value_columns(d: _Draft, header, data, comma, meta, meta_roles, used, cols
                   ) -> tuple[set, set]:
    """The [[values]] of a header-row table: the columns' quantities and units. Returns the
    quantities found (``"?"`` for one still to write) and the direction words met."""
    low = [h.lower() for h in header]
    numeric = [all(_num(r[k], comma) or not r[k].strip() for r in data) for k in range(len(header))]
    quantities, words = set(), set()
    meta_unit = meta_roles.get("unit")
    meta_q = meta_roles.get("quantity")

    def unit_line(spec, h):
        u = _unit_of(h)
        if u is not None:
            spec.append(f"unit = {_q(u)}")
        elif meta_unit is not None:
            spec.append(f"unit_meta = {_q(meta_unit)}")
        elif "unit" not in cols:
            d.need(spec, "unit", f"the unit of column {h!r}: µm, mm, in (linear) or µm/m, "
                   "mm/m, µrad, arcsec (angular)", f"values.{h}.unit")

    def quantity_line(spec, h):
        q = quantity_of(h)
        if q is not None:
            spec.append(f"quantity = {_q(q)}")
            quantities.add(q)
        elif meta_q is not None:
            q = quantity_of(meta[meta_q])
            spec.append(f"quantity_meta = {_q(meta_q)}")
            if q is None:
                d.alias("quantity", meta[meta_q], None, "the ISO 230-1 name (EXX, EYX, EZX, "
                        "EAX, EBX, ECX) this file's quantity means")
                quantities.add(TODO)
            else:
                if meta[meta_q].strip().upper() != q:
                    d.alias("quantity", meta[meta_q], q)
                quantities.add(q)
        elif "quantity" not in cols:
            d.need(spec, "quantity", f"which error column {h!r} holds: EXX, EYX, EZX (µm) or "
                   "EAX, EBX, ECX (µm/m)", f"values.{h}.quantity")
            quantities.add(TODO)

    # an ISO 230-2 summary: a mean and an s per direction
    means = {k: h for k, h in enumerate(header) if re.match(r"(mean|x̄|avg|average)\b", low[k])
             or low[k].startswith("x̄")}
    if means:
        for k, h in means.items():
            tail = re.sub(r"^(mean|x̄|avg|average)", "", low[k]).strip()
            direction = ("backward" if re.search(r"bwd|back|rev|↓|-$|neg", tail) else "forward")
            s = next((header[j] for j in range(len(header)) if j not in means and re.fullmatch(
                r"(s|σ|sigma|std)\s*" + re.escape(tail), low[j])), None)
            spec = [f"column = {_q(h)}", f"direction = {_q(direction)}"]
            if s is not None:
                spec.append(f"sigma_column = {_q(s)}")
                used.add(s.lower())
            quantity_line(spec, h)
            unit_line(spec, h)
            d.values.append(spec)
            used.add(low[k])
        if "runs" in meta_roles:
            d.reading.append(f"runs_meta = {_q(meta_roles['runs'])}")
        else:
            d.need(d.reading, "runs", "how many runs each mean averages (its σ = s/√runs)",
                   "reading.runs")
        return quantities, words
    # columns named by run and direction: one [[values]] with a match
    runs = {k: t for k, h in enumerate(header) if low[k] not in used and numeric[k]
            and (t := _run_dir_template(h))}
    if runs:
        m, _, word = next(iter(runs.values()))
        dirs = sorted({t[2] for t in runs.values() if t[2]}, key=str.lower)
        rx = (re.escape(m.group("pre")).replace(r"\ ", r"\s*") + r"(?P<run>\d+)"
              + (re.escape(m.group("mid")).replace(r"\ ", r"\s*") + "(?P<direction>"
                 + "|".join(map(re.escape, dirs)) + ")" if dirs else "")
              + re.escape(m.group("post")).replace(r"\ ", r"\s*"))
        spec = [f"match = {_lit(rx)}"]
        words |= set(dirs)
        h = header[next(iter(runs))]
        quantity_line(spec, h)
        unit_line(spec, h)
        d.values.append(spec)
        used |= {low[k] for k in runs}
        return quantities, words
    # one column per error (a word or an ISO name with its unit), or one value column
    for k, h in enumerate(header):
        if low[k] in used or not numeric[k] or not h.strip():
            continue
        if re.search(r"temp|°c|°f|time|zeit|press|humid", low[k]):
            continue  # the environment's columns: read by no profile
        generic = re.search(r"\b(value|messwert|wert|deviation|abweichung|error|fehler|reading)"
                            r"\b", low[k])
        if quantity_of(h) is None and not generic and _unit_of(h) is None:
            continue
        spec = [f"column = {_q(h)}"]
        quantity_line(spec, h)
        unit_line(spec, h)
        d.values.append(spec)
        used.add(low[k])
    return quantities, words


def _text_columns(d: _Draft, header, data, comma) -> tuple[dict, set]:
    """The [reading] columns of a header-row table: point, x, y, z, quantity, unit, run,
    direction, sigma, reference (by name, or by what the cells hold); the lower-case names
    used."""
    cols, used, found = {}, set(), {}
    rules = (("point", r"(point|messpunkt|punkt|location|station)( name)?"),
             ("x_mm", r"x( position| pos)?"),
             ("y_mm", r"y( position| pos)?"),
             ("z_mm", r"z( position| pos)?|height"),
             ("quantity", r"quantity|größe|grösse|measurement|error type|parameter|test"),
             ("unit", r"units?|einheit"),
             ("run", r"run( no\.?| number| #)?|lauf|cycle|zyklus|messung"),
             ("direction", r"direction|dir|richtung|sens"),
             ("sigma", r"sigma|σ|u|std|uncertainty|unsicherheit"),
             ("reference", r"(reference|referenz|ref)\b.*"))
    for k, h in enumerate(header):
        name = " ".join(_BRACKET.sub("", h.lower()).split()).rstrip(".:# ")
        for field, rx in rules:
            if field not in found and re.fullmatch(rx, name):
                found[field] = h
                used.add(h.lower())
                break
    for field, h in found.items():
        if field not in ("point", "x_mm", "y_mm"):  # those: _point_lines
            d.reading.append(f"{field}_column = {_q(h)}")
        cols[field] = h
    return cols, used


def _column_aliases(d, header, data, cols) -> set:
    """Aliases for the words of a quantity or direction column; the quantities found."""
    quantities = set()
    if "quantity" in cols:
        k = header.index(cols["quantity"])
        for word in sorted({r[k].strip() for r in data if k < len(r) and r[k].strip()}):
            q = quantity_of(word)
            if q is None:
                d.alias("quantity", word, None, "the ISO 230-1 name (EXX, EYX, EZX, EAX, EBX, "
                        "ECX) of this word")
                quantities.add(TODO)
            else:
                quantities.add(q)
                if word.upper() != q:
                    d.alias("quantity", word, q)
    if "direction" in cols:
        k = header.index(cols["direction"])
        _direction_aliases(d, {r[k].strip() for r in data if k < len(r) and r[k].strip()})
    return quantities


def _header_table(d, layout, meta, meta_roles, points, text) -> None:
    header, data, comma = layout.header, layout.data, layout.comma
    low = [h.lower() for h in header]
    numeric = [all(_num(r[k], comma) for r in data) for k in range(len(header))]
    cols, used = _text_columns(d, header, data, comma)
    for f in [f for f in ("x_mm", "y_mm", "z_mm") if f in cols]:
        k = header.index(cols[f])
        distinct = {r[k] for r in data if k < len(r)}
        if not numeric[k] or len(distinct) > min(10, max(1, len(data) // 4)):  # a position
            if f == "z_mm":
                d.reading.remove(f"{f}_column = {_q(cols[f])}")
            used.discard(cols[f].lower())
            del cols[f]
    # the position column: target > position > nominal ... > the first numeric column
    order = (r"target", r"position|pos\b", r"nominal|soll|p[ij]\b", r"x\b")
    pos = next((k for rx in order for k, h in enumerate(low)
                if numeric[k] and h not in used and re.match(rx, h)),
               next((k for k in range(len(header)) if numeric[k] and low[k] not in used), 0))
    used.add(low[pos])
    unit = _unit_of(header[pos]) or ""
    unit_in = unit_key(unit, LINEAR_UNITS) == "in" or meta_roles.get("position_unit") and \
        unit_key(meta[meta_roles["position_unit"]], LINEAR_UNITS) == "in"
    first = re.escape(header[0].strip()).replace("\\ ", " ")  # spaces need no escape
    start = '^"?' + first  # the name, quoted or not
    d.table.append(f"start = {_lit(start)}"
                   f"  # the header line (line {layout.lines[layout.header_index][0]})")
    d.table.append(f"position = {_q(header[pos])}")
    if unit_in:
        d.table.append('position_unit = "in"')
    elif unit and unit_key(unit, LINEAR_UNITS) != "mm":
        d.need(d.table, "position_unit", f"the unit of the positions ({unit!r}): \"mm\" or "
               "\"in\"", "table.position_unit")
    positions = [float(r[pos].replace(",", ".") if comma else r[pos]) for r in data]
    _x0_lines(d, positions, meta_roles, bool(unit_in))
    _point_lines(d, meta_roles, cols, points)
    quantities = _column_aliases(d, header, data, cols)
    q2, words = _value_columns(d, header, data, comma, meta, meta_roles, used, cols)
    quantities |= q2
    _direction_aliases(d, words)
    _instrument_line(d, meta_roles, meta, text, quantities - {TODO})
    d.reading.append("# sign = -1  # a sensor mounted reversed (per quantity: sign = { ECX = -1 })")


def _records_table(d, lines, meta, meta_roles, points, text) -> bool:
    """A ``Targets:`` list and ``Data:`` records (run, direction, target index, value)."""
    heads = [i for i, (_, s) in enumerate(lines) if re.fullmatch(r"[A-Za-z][\w ]*:", s)]
    if len(heads) < 2:
        return False
    t, r = heads[0], heads[1]
    targets = [tok for _, s in lines[t + 1:r] for tok in s.replace(";", " ").split()]
    if not targets or not all(_num(x, False) for x in targets):
        return False
    records = [s.split() for _, s in lines[r + 1:]]
    if not records or len({len(x) for x in records}) != 1:
        return False
    n = len(records[0])
    kinds = {}
    for k in range(n):
        cells = [x[k] for x in records]
        if all(c.lower() in _FORWARD + _BACKWARD + tuple(DIRECTION_WORDS) for c in cells):
            kinds.setdefault("direction", k)
        elif all(re.fullmatch(r"\d+", c) for c in cells):
            if max(map(int, cells)) <= len(targets) and "index" in kinds:
                kinds.setdefault("run", kinds["index"])
                kinds["index"] = k
            else:
                kinds.setdefault("run" if "index" in kinds else "index", k)
        elif all(_num(c, False) for c in cells):
            kinds.setdefault("value", k)
    if "index" not in kinds or "value" not in kinds:
        return False
    d.top += ['separator = "whitespace"', 'metadata_separator = ":"']
    d.table += [f"start = {_lit('^' + re.escape(lines[r][1]))}"
                f"  # the records follow (line {lines[r][0]})", "header = false",
                f"position_index = {kinds['index'] + 1}  # into the [targets] list"]
    d.top.insert(0, f"__TARGETS__{lines[t][1]}")
    positions = [float(x) for x in targets]
    _x0_lines(d, positions, meta_roles, False)
    _point_lines(d, meta_roles, {}, points)
    for f in ("run", "direction"):
        if f in kinds:
            d.reading.append(f"{f}_column = {kinds[f] + 1}")
    if "direction" in kinds:
        _direction_aliases(d, {x[kinds["direction"]] for x in records})
    spec = [f"column = {kinds['value'] + 1}"]
    quantities = set()
    if "quantity" in meta_roles:
        q = quantity_of(meta[meta_roles["quantity"]])
        d.reading.append(f"quantity_meta = {_q(meta_roles['quantity'])}")
        if q is None:
            d.alias("quantity", meta[meta_roles["quantity"]], None, "its ISO 230-1 name")
        else:
            quantities.add(q)
            if meta[meta_roles["quantity"]].strip().upper() != q:
                d.alias("quantity", meta[meta_roles["quantity"]], q)
    else:
        d.need(d.reading, "quantity", "EXX, EYX, EZX (µm) or EAX, EBX, ECX (µm/m)",
               "reading.quantity")
    if "unit" in meta_roles:
        d.reading.append(f"unit_meta = {_q(meta_roles['unit'])}")
    else:
        d.need(d.reading, "unit", "the values' unit", "reading.unit")
    d.values.append(spec)
    _instrument_line(d, meta_roles, meta, text, quantities)
    d.reading.append("# sign = -1  # a sensor mounted reversed")
    return True


def _exx_draft(d, lines, points) -> str:
    """The vendor-exchange grid: the built-in ``exx`` profile with its point left to write."""
    from .profiles import builtin_profiles

    positions, on = [], False
    for _, s in lines:
        if s.startswith("["):
            on = bool(re.match(r"\[\s*E[XYZABC]X\s*\]", s))
        elif on and re.fullmatch(r"[+-]?[\d.]+\s+[+-]?[\d.eE+-]+", s):
            positions.append(float(s.split()[0]))
    _x0_lines(d, positions or [0.0], {}, False)
    out = []
    for ln in builtin_profiles()["exx"].splitlines():
        if ln.startswith("#") or re.match(r"(point|x_mm|y_mm)\s*=", ln):
            continue
        if ln.startswith("name ="):
            out += d.top
            continue
        out.append(ln)
        if ln.strip() == "[reading]":
            sub = _Draft(d.source)
            _point_lines(sub, {}, {}, points)
            out += sub.reading
            d.required += sub.required
    return "\n".join(out) + "\n"


def draft_profile(path, encoding: str | None = None, points: dict | None = None
                  ) -> tuple[str, list[str]]:
    """``(TOML text, keys still to write)`` of a draft profile for the file ``path``
    (``points``: the machine's control points ``{name: (x, y)}`` in mm, listed as comments).
    ``ValueError`` naming the file where no table is found."""
    name = os.fspath(path)
    text, used = decode(read_bytes(path), name, encoding or "auto")
    lines = [(n, s.strip()) for n, s in enumerate(text.splitlines(), start=1)
             if s.strip() and not s.strip().startswith("#")]
    d = _Draft(name)
    comment = [f"draft profile for {os.path.basename(name)}, written by diffguide import "
               "--draft-profile", "Complete every line marked REQUIRED (its value is \"?\"; "
               "the profile is refused while one is left),", "confirm the lines marked CHECK, "
               "then: diffguide import FILE --profile THIS.toml --explain",
               "(every key: docs/file-formats.md, \"Profiles\")"]
    d.top += [f"name = {_q('draft: ' + os.path.basename(name))}",
              f"encoding = {_q(used)}"]
    if any(re.match(r"Gridpoints\s*=\s*\{", s) for _, s in lines):
        body = _exx_draft(d, lines, points)
        return "\n".join(f"# {c}" for c in comment) + "\n" + body, d.required
    try:
        layout = _Layout(lines)
        upto = layout.header_index if layout.header is not None else layout.first
    except ValueError:
        layout, upto = None, len(lines)
    meta_pairs = _metadata(lines, upto if layout else len(lines),
                           layout.sep if layout else ":")
    meta = {k: v for k, v in meta_pairs}
    meta_roles = {}
    for k, _ in meta_pairs:
        role = _meta_role(k)
        if role and role not in meta_roles:
            meta_roles[role] = k
    if layout is None or layout.header is None:
        if _records_table(d, lines, meta, meta_roles, points, text):
            return _finish(d, comment, lines), d.required
        where = "no table found" if layout is None else "the table has no header row"
        raise ValueError(f"{name}: cannot draft a profile: {where} (write one from "
                         "docs/file-formats.md, \"Profiles\")")
    d.top.append(f"separator = {_q(layout.sep_name)}")
    d.top.append(f"decimal = {_q(',' if layout.comma else '.')}")
    _header_table(d, layout, meta, meta_roles, points, text)
    if meta_pairs:
        d.top.append("# metadata lines read (each is kept in the report): "
                     + "; ".join(f"{k} = {v}" for k, v in meta_pairs[:12]))
    return _finish(d, comment, lines), d.required


def _finish(d, comment, lines) -> str:
    top = []
    for ln in d.top:
        if ln.startswith("__TARGETS__"):
            continue
        top.append(ln)
    targets = [ln[len("__TARGETS__"):] for ln in d.top if ln.startswith("__TARGETS__")]
    d.top = top
    text = d.text(comment)
    if targets:
        text = text.replace("\n[table]\n", "\n[targets]\nstart = "
                            + _lit("^" + re.escape(targets[0])) + "\n\n[table]\n", 1)
    return text


def write_draft(path, text: str, overwrite: bool = False) -> None:
    """Write ``text`` to ``path`` atomically; an existing file is refused (``ValueError``
    naming it) unless ``overwrite``."""
    from .atomic import atomic_write_text

    if not overwrite and os.path.lexists(path):
        raise ValueError(f"--draft-profile {os.fspath(path)}: the file exists (a profile you "
                         "may have completed); choose another name, or --overwrite-draft")
    if overwrite:
        atomic_write_text(path, text)
        return
    folder = os.path.dirname(os.path.abspath(path))
    tmp = os.path.join(folder, f".{os.path.basename(path)}.{os.getpid()}.tmp")
    with open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    try:
        os.link(tmp, path)  # atomic, and never over a file that appeared meanwhile
    except FileExistsError:
        raise ValueError(f"--draft-profile {os.fspath(path)}: the file exists; choose another "
                         "name, or --overwrite-draft") from None
    finally:
        os.unlink(tmp)

