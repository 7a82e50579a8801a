r"""Measurement *profiles*: a small TOML file that maps a vendor's table onto diffguide's readings,
so that any instrument's export is read as it is (``diffguide import --profile``, ``fit
--profile``). The reference of every key is docs/file-formats.md ("Profiles"); in short::

    name = "laser CSV"              # what the profile reads (for messages)
    encoding = "auto"               # or utf-8, utf-16, cp1252, latin-1, ...
    separator = "auto"              # ",", ";", "tab", "whitespace", "|" ...
    decimal = "auto"                # "." or ","
    comment = ["#"]                 # line prefixes skipped anywhere
    skip_lines = 0                  # lines skipped at the top
    x0_mm = 0.0                     # machine coordinate of x = 0, or "middle"

    [table]
    start = '^Target'               # the table's header line (regex); before it: key/value
    position = "Target (mm)"        # metadata. Columns by name (or names) or 1-based index
    position_unit = "mm"            # or "in"

    [reading]                       # every reading: field = value, field_column = column,
    point_meta = "Point"            # field_meta = metadata key
    quantity = "EBX"

    [[values]]                      # the columns holding readings
    match = 'Run (?P<run>\d+) (?P<direction>\w+) \((?P<unit>[^)]*)\)'

    [aliases.direction]             # words of the file -> forward / backward
    Rev = "backward"

Fields of a reading (:data:`FIELDS`): those of the long format (:mod:`.measurements`) and
``sign`` (±1, multiplies value and reference: a level mounted reversed) and ``runs`` (the
number of runs a value averages, a summary table's mean: its ``sigma`` is divided by √runs).

Built-in profiles (package data, :func:`builtin_profiles`) are named by their file stem:
``--profile exx``.
"""

import math
import re
import tomllib
from importlib import resources

from .csvtable import decode, read_bytes
from .measurements import _BACKWARD, _FORWARD, Reading, _parse_row, _RowError, note_repeats

#: The fields of a reading a profile gives (literal, ``_column`` or ``_meta``).
FIELDS = ("point", "x_mm", "y_mm", "quantity", "unit", "instrument", "sigma", "run",
          "direction", "z_mm", "resolution", "reference", "sign", "runs")
_NUMERIC = ("x_mm", "y_mm", "sigma", "z_mm", "resolution", "reference", "sign", "runs")
_TOP = {"name": str, "description": str, "encoding": str, "separator": str, "decimal": str,
        "comment": (str, list), "inline_comment": str, "skip_lines": int,
        "x0_mm": (int, float, str), "x0_mm_meta": str, "metadata_separator": str,
        "table": dict, "targets": dict, "blocks": dict, "reading": dict, "values": list,
        "aliases": dict}
_TABLE = {"start": str, "header": bool, "end": str, "position": (str, int, list),
          "position_unit": str, "position_index": (str, int, list)}
_SEPARATORS = {"auto": None, ",": ",", ";": ";", "tab": "\t", "\t": "\t", "|": "|",
               "whitespace": " ", " ": " "}
_NUMBER = re.compile(r"^[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?$")


class ProfileError(ValueError):
    """A profile that cannot be used (its file and key named)."""


def builtin_profiles() -> dict[str, str]:
    """``{name: TOML text}`` of the profiles shipped with diffguide."""
    root = resources.files("diffguide.io").joinpath("builtin_profiles")
    return {p.name[:-5]: p.read_text(encoding="utf-8") for p in root.iterdir()
            if p.name.endswith(".toml")}


def load_profile(spec: str) -> dict:
    """A profile from a TOML file's path or a built-in profile's name, checked
    (:func:`check_profile`); its ``"_source"`` key says which."""
    shipped = builtin_profiles()
    if spec in shipped:
        text, source = shipped[spec], f"built-in profile {spec!r}"
    else:
        try:
            with open(spec, "rb") as fh:
                text = fh.read().decode("utf-8-sig")
        except OSError as exc:
            raise ProfileError(f"{spec}: cannot read the profile ({exc.strerror or exc}; "
                               f"built-in profiles: {', '.join(sorted(shipped))})") from None
        source = spec
    try:
        prof = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProfileError(f"{source}: not a valid TOML profile ({exc})") from None
    check_profile(prof, source)
    prof["_source"] = source
    return prof


def _check_keys(table: dict, allowed: dict, where: str, source: str) -> None:
    for k, v in table.items():
        if k not in allowed:
            raise ProfileError(f"{source}: unknown key {where}{k!r} (allowed "
                               f"{', '.join(allowed)})")
        if not isinstance(v, allowed[k]) or (isinstance(v, bool) and allowed[k] is not bool):
            raise ProfileError(f"{source}: key {where}{k!r} has the wrong type "
                               f"({type(v).__name__}, {v!r})")


def _field_keys() -> dict:
    keys = {}
    for f in FIELDS:
        keys[f] = (str, int, float, dict)
        keys[f + "_column"] = (str, int, list)
        keys[f + "_meta"] = str
    return keys


def check_profile(prof: dict, source: str = "<profile>") -> None:
    """``ProfileError`` naming the key for an unknown key, a wrong type, a bad regular
    expression or value; a value still ``"?"`` (a draft's line to complete, :mod:`.profile_draft`)
    named with its key."""
    _check_placeholders(prof, "", source)
    _check_keys({k: v for k, v in prof.items() if k != "_source"}, _TOP, "", source)
    _check_keys(prof.get("table", {}), _TABLE, "table.", source)
    _check_keys(prof.get("targets", {}), {"start": str}, "targets.", source)
    _check_keys(prof.get("blocks", {}), {"start": str, "skip": str}, "blocks.", source)
    _check_keys(prof.get("reading", {}), _field_keys(), "reading.", source)
    spec_keys = {"column": (str, int, list), "match": str, **_field_keys()}
    values = prof.get("values", [])
    if not values:
        raise ProfileError(f"{source}: no [[values]] (the columns that hold the readings)")
    for k, v in enumerate(values):
        if not isinstance(v, dict) or ("column" in v) == ("match" in v):
            raise ProfileError(f"{source}: [[values]] number {k + 1} needs 'column' or 'match' "
                               "(one of them)")
        _check_keys(v, spec_keys, f"values[{k + 1}].", source)
    for f, words in prof.get("aliases", {}).items():
        if f not in FIELDS or not isinstance(words, dict):
            raise ProfileError(f"{source}: [aliases.{f}] is not a table of a field (fields "
                               f"{', '.join(FIELDS)})")
    for where, key in (("table", "start"), ("table", "end"), ("targets", "start"),
                       ("blocks", "start"), ("blocks", "skip")):
        if key in prof.get(where, {}):
            _regex(prof[where][key], f"{where}.{key}", source)
    for k, v in enumerate(values):
        if "match" in v:
            _regex(v["match"], f"values[{k + 1}].match", source)
    checks = (("separator", _SEPARATORS), ("decimal", ("auto", ".", ",")),
              ("metadata_separator", ("auto", ":", "=", ",", ";", "tab", "\t")))
    for key, allowed in checks:
        if key in prof and prof[key] not in allowed:
            raise ProfileError(f"{source}: key {key!r} is {prof[key]!r} (allowed "
                               f"{', '.join(map(repr, allowed))})")
    unit = prof.get("table", {}).get("position_unit", "mm")
    if unit not in ("mm", "in"):
        raise ProfileError(f"{source}: key 'table.position_unit' is {unit!r} (allowed 'mm', "
                           "'in')")
    x0 = prof.get("x0_mm", 0.0)
    if isinstance(x0, str) and x0 != "middle":
        raise ProfileError(f"{source}: key 'x0_mm' is {x0!r} (allowed a number in mm or "
                           "'middle')")
    table = prof.get("table", {})
    if ("position" in table) == ("position_index" in table):
        raise ProfileError(f"{source}: [table] needs 'position' (the targets' column) or "
                           "'position_index' (a column of 1-based indices into [targets])")
    if "position_index" in table and "start" not in prof.get("targets", {}):
        raise ProfileError(f"{source}: 'table.position_index' needs [targets] start")
    if not table.get("header", True):
        refs = [table.get("position", table.get("position_index"))]
        refs += [v.get("column") for v in values] + [
            s[k] for s in (prof.get("reading", {}), *values) for k in s if k.endswith("_column")]
        if any("match" in v for v in values) or any(
                r is not None and not isinstance(r, int) for r in refs):
            raise ProfileError(f"{source}: with table.header = false every column is a 1-based "
                               "index (and [[values]] use 'column', not 'match')")


def _check_placeholders(node, where: str, source: str) -> None:
    """``ProfileError`` for the first value ``"?"`` below ``node``, naming its key."""
    items = (node.items() if isinstance(node, dict) else
             ((f"[{k + 1}]", v) for k, v in enumerate(node)) if isinstance(node, list) else ())
    for k, v in items:
        key = f"{where}{k}" if str(k).startswith("[") or not where else f"{where}.{k}"
        if v == "?":
            raise ProfileError(f"{source}: key {key!r} is still \"?\" (a draft profile: write "
                               "its value; the comment beside it says what)")
        _check_placeholders(v, key, source)


def _regex(text, key, source):
    try:
        return re.compile(text, re.IGNORECASE)
    except re.error as exc:
        raise ProfileError(f"{source}: key {key!r} is not a valid regular expression "
                           f"({exc})") from None


class _Ctx:
    """What one file's parse carries along: the profile, the file's name and separators."""

    def __init__(self, prof, name, info):
        self.prof, self.name, self.info = prof, name, info
        self.sep = _SEPARATORS[prof.get("separator", "auto")]
        self.decimal = prof.get("decimal", "auto")
        comment = prof.get("comment", ["#"])
        self.comment = tuple([comment] if isinstance(comment, str) else comment)
        self.inline = prof.get("inline_comment", "")
        self.table = None
        self.aliases = {f: {str(k).strip().lower(): str(v) for k, v in words.items()}
                        for f, words in prof.get("aliases", {}).items()}

    def fail(self, line, text):
        raise ValueError(f"{self.name}:{line}: {text} (profile {self.prof['_source']})")

    def split(self, line: str) -> list[str]:
        import csv
        import io

        if self.sep is None:  # sniffed from the first table line
            self.sep = next((d for d in ("\t", ";", ",") if d in line), " ")
            self.info["separator"] = {"\t": "tab", " ": "whitespace"}.get(self.sep, self.sep)
        if self.sep == " ":
            return line.split()
        try:
            return [f.strip() for f in next(csv.reader(io.StringIO(line), delimiter=self.sep))]
        except (csv.Error, StopIteration) as exc:
            raise ValueError(f"{self.name}: not a valid line {line[:40]!r} ({exc})") from None

    def number_text(self, text: str) -> str:
        """``text`` with its decimal mark made a point."""
        t = text.strip().replace("\u2212", "-")
        comma = self.decimal == "," or (self.decimal == "auto" and self.sep not in (",", None))
        if comma and re.fullmatch(r"[+-]?\d*,\d+(?:[eE][+-]?\d+)?", t):
            t = t.replace(",", ".")
        return t


def _key_value(ctx: _Ctx, line: str):
    """``(key, value)`` of a metadata line (split at the earliest of the separators:
    ``metadata_separator``, or the file's separator, ``:`` and ``=``), or ``None``."""
    wanted = ctx.prof.get("metadata_separator", "auto")
    if wanted != "auto":
        seps = [{"tab": "\t"}.get(wanted, wanted)]
    else:
        seps = ([ctx.sep] if ctx.sep not in (None, " ") else [";", "\t", ","]) + [":", "="]
    found = [(line.index(s), s) for s in seps if s in line]
    if not found:
        return None
    s = min(found)[1]
    key, _, value = line.partition(s)
    value = value.strip().strip(s).strip().strip('"')
    if key.strip() and value and (s in ":=" or s not in value):
        return key.strip().strip('"'), value
    return None


def _column(ctx, ref, header, what, line) -> int | None:
    """0-based index of the column ``ref`` (a name, names, or a 1-based index; a name that
    starts with ``?`` is optional: ``None`` when absent)."""
    if isinstance(ref, str) and ref.startswith("?"):
        low = [h.strip().lower() for h in header or []]
        return low.index(ref[1:].strip().lower()) if ref[1:].strip().lower() in low else None
    if isinstance(ref, int):
        if ref < 1 or (header is not None and ref > len(header)):
            ctx.fail(line, f"{what}: column {ref} does not exist"
                     + (f" (the header has {len(header)} columns)" if header else ""))
        return ref - 1
    names = [ref] if isinstance(ref, str) else ref
    low = [h.strip().lower() for h in header]
    for n in names:
        if str(n).strip().lower() in low:
            return low.index(str(n).strip().lower())
    ctx.fail(line, f"{what}: no column named {' or '.join(map(repr, names))} in the header "
             f"({', '.join(header)})")


class _Table:
    """One table's columns resolved against its header line (``header`` None: by index)."""

    def __init__(self, ctx, header, line):
        prof, t = ctx.prof, ctx.prof.get("table", {})
        self.header, self.line = header, line
        self.index_mode = "position_index" in t
        ref = t.get("position_index") if self.index_mode else t["position"]
        self.position = _column(ctx, ref, header, "table.position", line)
        self.fields = {}  # field -> column, from [reading]
        for k, v in prof.get("reading", {}).items():
            if k.endswith("_column"):
                c = _column(ctx, v, header, f"reading.{k}", line)
                if c is not None:
                    self.fields[k[:-7]] = c
        used = {self.position, *self.fields.values()}
        self.values = []  # (column, spec, groups, {field: column})
        for n, spec in enumerate(prof["values"], start=1):
            cols = {}
            for k, v in spec.items():
                if k.endswith("_column") and not (k == "reference_column" and "{column}" in v):
                    c = _column(ctx, v, header, f"values[{n}].{k}", line)
                    if c is not None:
                        cols[k[:-7]] = c
            used |= set(cols.values())
            if "column" in spec:
                k = _column(ctx, spec["column"], header, f"values[{n}].column", line)
                self.values.append((k, spec, {}, cols))
                continue
            rx = re.compile(spec["match"], re.IGNORECASE)
            found = [(k, m) for k, h in enumerate(header)
                     if k not in used and (m := rx.fullmatch(h.strip()))]
            if not found:
                ctx.fail(line, f"values[{n}].match: no column of the header matches "
                         f"{spec['match']!r} (columns: {', '.join(header)})")
            for k, m in found:
                c = dict(cols)
                tpl = spec.get("reference_column")
                if isinstance(tpl, str) and "{column}" in tpl:
                    ref_name = tpl.replace("{column}", header[k].strip()).lower()
                    low = [h.strip().lower() for h in header]
                    if ref_name in low:
                        c["reference"] = low.index(ref_name)
                self.values.append((k, spec, {g: v for g, v in m.groupdict().items() if v}, c))
        self.value_cols = {k for k, *_ in self.values}
        ctx.info["position_column"] = (header[self.position] if header else
                                       f"column {self.position + 1}")
        used |= self.value_cols | {c for *_, cols in self.values for c in cols.values()}
        self.ignored = [h for k, h in enumerate(header or []) if k not in used and h.strip()]


def _given(ctx, level, field, meta, line):
    """A literal ``field`` or a ``field_meta`` of one profile level (``None``: neither)."""
    if field + "_meta" in level:
        key = _meta_key(level[field + "_meta"])
        if key.startswith("?"):  # optional
            return meta[key[1:]][0] if key[1:] in meta else level.get(field)
        if key not in meta:
            ctx.fail(line, f"{field}_meta: metadata key {level[field + '_meta']!r} not found "
                     f"(keys read: {', '.join(v[2] for v in meta.values()) or 'none'})")
        return meta[key][0]
    return level.get(field)


def _field(ctx, field, spec, groups, cols, row, meta, line):
    """The text of ``field`` for one reading (``None``: not given): the value column's own
    ``field_column``, ``field`` or ``field_meta``, then its ``match`` groups, then
    [reading]'s."""
    if field in cols:
        return row[cols[field]] if cols[field] < len(row) else ""
    v = _given(ctx, spec, field, meta, line)
    if v is None and field in groups:
        v = groups[field]
    if v is None and field in ctx.table.fields:
        k = ctx.table.fields[field]
        v = row[k] if k < len(row) else ""
    if v is None:
        v = _given(ctx, ctx.prof.get("reading", {}), field, meta, line)
    return v


def _meta_key(key: str) -> str:
    return " ".join(str(key).lower().split())


def _alias(ctx, field, text):
    words = ctx.aliases.get(field, {})
    return words.get(str(text).strip().lower(), text)


def _negate(text: str) -> str:
    t = text.strip()
    return t[1:] if t.startswith("-") else "-" + t.lstrip("+")


def _readings_of_row(ctx, row, line, meta, targets) -> list:
    table = ctx.table
    raw = ctx.number_text(row[table.position]) if table.position < len(row) else ""
    if not _NUMBER.match(raw):
        return None  # not a data line: the table ended
    if table.header is not None and len(row) < len(table.header):
        ctx.fail(line, f"{len(row)} fields, the table header (line {table.line}) has "
                 f"{len(table.header)}")
    pos = float(raw)
    if table.index_mode:
        if not (pos == int(pos) and 1 <= pos <= len(targets)):
            ctx.fail(line, f"target index {raw!r} is not one of 1 .. {len(targets)} (the "
                     "[targets] list)")
        pos = targets[int(pos) - 1]
    elif ctx.prof.get("table", {}).get("position_unit", "mm") == "in":
        pos *= 25.4
    out = []
    for k, spec, groups, cols in table.values:
        if k >= len(row) or not row[k].strip():
            ctx.info["missing_cells"] = ctx.info.get("missing_cells", 0) + 1
            continue
        f = {name: _field(ctx, name, spec, groups, cols, row, meta, line) for name in FIELDS}
        f = {n: (str(v) if not isinstance(v, dict) else v) for n, v in f.items()
             if v is not None and v != ""}
        if isinstance(f.get("quantity"), dict):
            ctx.fail(line, "quantity: a table of values per quantity is not allowed here")
        quantity = str(_alias(ctx, "quantity", f.get("quantity", ""))).strip().upper()
        kind = "LINEAR" if quantity in ("EXX", "EYX", "EZX") else "ANGULAR"
        point = str(_alias(ctx, "point", f.get("point", ""))).strip().upper()
        for n, v in list(f.items()):  # a table by channel, quantity, kind or default
            if isinstance(v, dict):
                by = {str(k).upper().replace(" ", ""): x for k, x in v.items()}
                v = next((by[k] for k in (f"{point}:{quantity}", quantity, kind, "DEFAULT")
                          if k in by), None)
                f[n] = "" if v is None else str(v)
        f = {n: v for n, v in f.items() if v != ""}
        for name in ("point", "instrument", "direction", "run"):
            if name in f:
                f[name] = str(_alias(ctx, name, f[name])).strip()
        unit = str(_alias(ctx, "unit", f.get("unit", "")))
        d = f.get("direction", "forward").lower()
        if d not in _FORWARD + _BACKWARD:
            ctx.fail(line, f"direction {f['direction']!r} is not a known word (forward: "
                     f"{', '.join(_FORWARD)}; backward: {', '.join(_BACKWARD)}; others: "
                     "[aliases.direction] word = \"forward\" or \"backward\")")
        value = ctx.number_text(row[k])
        ref = ctx.number_text(f["reference"]) if f.get("reference", "").strip() else ""
        sign = ctx.number_text(f.get("sign", "1"))
        if sign not in ("1", "-1", "+1", "1.0", "-1.0"):
            ctx.fail(line, f"sign {sign!r}: allowed 1 or -1")
        if float(sign) < 0:
            value, ref = _negate(value), (_negate(ref) if ref else "")
        sigma = ctx.number_text(f.get("sigma", ""))
        if sigma and "runs" in f:
            runs = ctx.number_text(f["runs"])
            if not _NUMBER.match(runs) or float(runs) < 1:
                ctx.fail(line, f"runs {f['runs']!r}: allowed a number ≥ 1 (how many runs a "
                         "value averages)")
            if _NUMBER.match(sigma):
                sigma = repr(float(sigma) / math.sqrt(float(runs)))
        parsed = {"position_mm": repr(pos), "point": f.get("point", ""), "quantity": quantity,
                  "x_mm": ctx.number_text(f.get("x_mm", "")),
                  "y_mm": ctx.number_text(f.get("y_mm", "")), "value": value, "unit": unit,
                  "reference": ref, "sigma": sigma, "run": f.get("run", ""), "direction": d,
                  "instrument": f.get("instrument", ""),
                  "z_mm": ctx.number_text(f.get("z_mm", "")),
                  "resolution": ctx.number_text(f.get("resolution", ""))}
        try:
            out.append(_parse_row(parsed, line))
        except _RowError as exc:
            col = table.header[k] if table.header else f"column {k + 1}"
            ctx.fail(line, str(exc).replace("field 'value'", f"column {col!r}"))
        seen = ctx.info.setdefault("columns", {}).setdefault(
            table.header[k] if table.header else f"column {k + 1}", [])
        what = f"{out[-1].quantity} [{unit}] at {out[-1].point}" + (
            f", sign {sign}" if float(sign) < 0 else "")
        if what not in seen:
            seen.append(what)
    return out


def _targets(ctx, lines) -> tuple[list, set]:
    """The [targets] list (mm) and the line numbers it took."""
    rx = _regex(ctx.prof["targets"]["start"], "targets.start", ctx.prof["_source"])
    values, taken, on = [], set(), False
    for number, line in lines:
        if not on:
            if rx.search(line):
                on = True
                taken.add(number)
            continue
        tokens = line.replace(";", " ").replace("\t", " ").split()
        nums = [ctx.number_text(t) for t in tokens]
        if not tokens or not all(_NUMBER.match(t) for t in nums):
            break
        values += [float(t) for t in nums]
        taken.add(number)
    if not values:
        ctx.fail(1, f"no target positions after a line matching targets.start "
                 f"{ctx.prof['targets']['start']!r}")
    scale = 25.4 if ctx.prof.get("table", {}).get("position_unit", "mm") == "in" else 1.0
    return [v * scale for v in values], taken


def parse_profile(text: str, prof: dict, name: str = "<text>", notes: list | None = None,
                  info: dict | None = None) -> tuple[Reading, ...]:
    """The readings of ``text`` read through the profile ``prof`` (:func:`load_profile`);
    positions as in the file (x0 not subtracted: the caller does). ``info`` receives what was
    used (separator, decimal mark, metadata, columns, lines read and skipped)."""
    info = {} if info is None else info
    ctx = _Ctx(prof, name, info)
    t = prof.get("table", {})
    start = _regex(t["start"], "table.start", "") if "start" in t else None
    end = _regex(t["end"], "table.end", "") if "end" in t else None
    bstart = _regex(prof["blocks"]["start"], "", "") if "start" in prof.get("blocks", {}) else None
    bskip = _regex(prof["blocks"]["skip"], "", "") if "skip" in prof.get("blocks", {}) else None
    has_header = t.get("header", True)
    lines = []
    for number, line in enumerate(text.splitlines(), start=1):
        if number <= prof.get("skip_lines", 0):
            continue
        if ctx.inline and ctx.inline in line:
            line = line[: line.index(ctx.inline)]
        s = line.strip()
        if s and not s.startswith(ctx.comment):
            lines.append((number, s))
    targets, taken = _targets(ctx, lines) if "targets" in prof else ([], set())
    file_meta, meta, skipped = {}, {}, []
    state, readings, in_block, skipping, tables = "pre", [], False, False, 0
    for number, line in lines:
        if number in taken:
            continue
        if bstart and (m := bstart.search(line)):
            meta = dict(file_meta)
            meta.update({_meta_key(k): (v, number, k) for k, v in m.groupdict().items() if v})
            state, in_block, skipping = "pre", True, False
            kv = _key_value(ctx, line)
            if kv is not None:  # a block's first metadata line
                meta[_meta_key(kv[0])] = (kv[1], number, kv[0])
            continue
        if bskip and bskip.search(line):
            skipping, state = True, "pre"
            info.setdefault("blocks_skipped", []).append(line[:40])
            continue
        if skipping:
            continue
        if state == "table":
            if end and end.search(line):
                state = "post"
                continue
            got = _readings_of_row(ctx, ctx.split(line), number, meta, targets)
            if got is not None:
                readings += got
                info["rows"] = info.get("rows", 0) + 1
                continue
            state, meta = "post", dict(file_meta)  # the table ended: a new block may begin
        if (start.search(line) if start else (state == "pre" and not tables)):
            tables += 1
            ctx.table = _Table(ctx, ctx.split(line), number) if has_header else None
            if not has_header:
                ctx.table = _Table(ctx, None, number)
                if start is None:  # the first content line is data
                    state = "table"
                    readings += _readings_of_row(ctx, ctx.split(line), number, meta,
                                                 targets) or []
                    continue
            elif ctx.table.ignored and notes is not None:
                text = f"column(s) {', '.join(ctx.table.ignored)} ignored (not in the profile)"
                if not any(n.endswith(text) for n in notes):  # once per file, not per block
                    notes.append(f"{name}:{number}: {text}")
            state = "table"
            continue
        kv = _key_value(ctx, line)
        if kv is not None:
            entry = (kv[1], number, kv[0])
            meta[_meta_key(kv[0])] = entry
            if not in_block and not tables:
                file_meta[_meta_key(kv[0])] = entry
                info.setdefault("metadata", {})[kv[0]] = kv[1]
            continue
        if tables:
            ctx.fail(number, f"not a data line ({line[:40]!r}: the position is not a number) "
                     "and not a metadata line after the table")
        skipped.append(number)
    if info.get("blocks_skipped") and notes is not None:
        shown = info["blocks_skipped"]
        notes.append(f"{name}: {len(shown)} section(s) skipped by blocks.skip: "
                     f"{', '.join(shown[:6])}{' ...' if len(shown) > 6 else ''}")
    if skipped:
        info["lines_skipped"] = skipped
        if notes is not None:
            notes.append(f"{name}: line(s) {', '.join(map(str, skipped[:10]))}"
                         f"{' ...' if len(skipped) > 10 else ''} before the table skipped "
                         "(neither metadata 'key: value' nor the table)")
    if not readings:
        where = (f"a line matching table.start {t['start']!r}" if start else "the first line")
        raise ValueError(f"{name}:1: no readings read through profile {prof['_source']} "
                         f"(the table is expected at {where})")
    if "x0_mm_meta" in prof:
        key = _meta_key(prof["x0_mm_meta"]).lstrip("?")
        if key in file_meta:
            raw = ctx.number_text(file_meta[key][0])
            if not _NUMBER.match(raw):
                ctx.fail(file_meta[key][1], f"x0_mm_meta: {file_meta[key][0]!r} is not a number "
                         "(allowed the machine coordinate of x = 0 in mm)")
            info["x0_stated"] = (float(raw), file_meta[key][1])
        elif not prof["x0_mm_meta"].startswith("?"):
            ctx.fail(1, f"x0_mm_meta: metadata key {prof['x0_mm_meta']!r} not found")
    info["readings"] = len(readings)
    info["decimal"] = ctx.decimal if ctx.decimal != "auto" else (
        "," if ctx.sep not in (",", None) else ".")
    info.setdefault("separator", {"\t": "tab", " ": "whitespace"}.get(ctx.sep, ctx.sep))
    note_repeats(readings, name, notes)
    return tuple(readings)


def read_profile(path, prof: dict, encoding: str | None = None, notes: list | None = None,
                 info: dict | None = None) -> tuple[Reading, ...]:
    """:func:`parse_profile` of the file ``path`` (``encoding`` overrides the profile's)."""
    import os

    name = os.fspath(path)
    text, used = decode(read_bytes(path), name, encoding or prof.get("encoding", "auto"))
    if info is not None:
        info["encoding"] = used
    return parse_profile(text, prof, name, notes, info)
