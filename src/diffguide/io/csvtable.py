"""One set of rules for every CSV file diffguide reads (measurements, rails, truth profiles).

- UTF-8 text (a byte-order mark is allowed), no NUL bytes;
- blank lines and lines whose first non-blank character is ``#`` are skipped, anywhere;
- the first other line is the header; column names are matched without case or surrounding
  spaces;
- the separator is sniffed from the header line: tab, else ``;``, else ``,``; with tab or ``;``
  a decimal comma (``1,25``) is read as a decimal point;
- columns that the format does not know are ignored and named in ``notes``, unless the name is
  close to a known column (then it is taken for a typo: an error), or empty;
- every data line must have as many fields as the header;
- every error is one line ``FILE:LINE: what (what was expected)``.
"""

import csv
import difflib
import io
import os
import re
from collections.abc import Iterator

_MAX_BYTES = 200 * 1024 * 1024


def sniff_delimiter(header: str) -> str:
    """The field separator of a CSV whose header line is ``header``: tab or ``;`` when the
    header contains one (instrument software of decimal-comma locales), else ``,``."""
    for d in ("\t", ";"):
        if d in header:
            return d
    return ","


_DECIMAL_COMMA = re.compile(r"^[+-]?\d*,\d+(?:[eE][+-]?\d+)?$")


def decimal_point(field: str, delimiter: str) -> str:
    """``"1,25"`` → ``"1.25"`` in a file whose separator is not the comma (a decimal comma);
    anything else unchanged."""
    if delimiter != "," and _DECIMAL_COMMA.match(field):
        return field.replace(",", ".")
    return field


def read_text(path: str | os.PathLike) -> str:
    """The UTF-8 text of a CSV file (size and encoding checked; one-line errors)."""
    name = os.fspath(path)
    try:
        size = os.path.getsize(name)
        if size > _MAX_BYTES:
            raise ValueError(f"{name}: file too large ({size} bytes > {_MAX_BYTES})")
        with open(name, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise ValueError(f"{name}: cannot read the file: {exc.strerror or exc}") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise ValueError(f"{name}:{line}: not UTF-8 text (byte {exc.start})") from None
    if "\x00" in text:
        line = text[: text.index("\x00")].count("\n") + 1
        raise ValueError(f"{name}:{line}: the file contains a NUL byte (not a CSV text file)")
    return text


def split_line(line: str, delimiter: str, name: str, number: int) -> list[str]:
    """The stripped fields of one CSV line (quotes honoured; decimal commas made points)."""
    try:
        fields = next(csv.reader(io.StringIO(line), delimiter=delimiter, strict=True))
    except (csv.Error, StopIteration) as exc:
        raise ValueError(f"{name}:{number}: not a valid CSV line ({exc})") from None
    return [decimal_point(f.strip(), delimiter) for f in fields]


def iter_rows(
    text: str,
    name: str,
    required: tuple[str, ...],
    optional: tuple[str, ...] = (),
    notes: list | None = None,
) -> Iterator[tuple[int, dict[str, str]]]:
    """``(line number, {column: field})`` for every data line of ``text`` (module rules); only
    the format's columns are in the dicts."""
    if "\x00" in text:
        line = text[: text.index("\x00")].count("\n") + 1
        raise ValueError(f"{name}:{line}: the file contains a NUL byte (not a CSV text file)")
    allowed = tuple(required) + tuple(optional)
    header, header_line, delimiter, keep = None, 0, ",", []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        if header is None:
            delimiter = sniff_delimiter(line)
            written = split_line(line, delimiter, name, number)
            header = [f.lower() for f in written]
            header_line = number
            ignored = []
            for f, as_written in zip(header, written):
                if f in allowed:
                    continue
                close = difflib.get_close_matches(f, allowed, n=1, cutoff=0.75)
                if close or not f:
                    hint = f", did you mean {close[0]!r}?" if close else ""
                    raise ValueError(
                        f"{name}:{number}: unknown column {as_written!r}{hint} (allowed "
                        f"{', '.join(allowed)}; other columns are ignored)"
                    )
                ignored.append(as_written)  # named as the file writes it
            dup = sorted({f for f in header if header.count(f) > 1})
            if dup:
                raise ValueError(f"{name}:{number}: duplicate column(s) {', '.join(dup)}")
            missing = [f for f in required if f not in header]
            if missing:
                raise ValueError(
                    f"{name}:{number}: missing column(s) {', '.join(missing)} (required "
                    f"{', '.join(required)})"
                )
            if ignored and notes is not None:
                notes.append(
                    f"{name}:{number}: column(s) {', '.join(ignored)} ignored (not part of the "
                    "format)"
                )
            keep = [k for k, f in enumerate(header) if f in allowed]
            continue
        fields = split_line(line, delimiter, name, number)
        if len(fields) != len(header):
            raise ValueError(
                f"{name}:{number}: {len(fields)} fields, the header (line {header_line}) has "
                f"{len(header)} ({delimiter.join(header)})"
            )
        yield number, {header[k]: fields[k] for k in keep}
    if header is None:
        raise ValueError(f"{name}:1: no header line (expected {','.join(required)}[,...])")


def read_table(
    path: str | os.PathLike,
    required: tuple[str, ...],
    optional: tuple[str, ...] = (),
    notes: list | None = None,
) -> list[tuple[int, dict[str, str]]]:
    """All data lines of the CSV file ``path`` (module rules): ``[(line number, row), ...]``."""
    name = os.fspath(path)
    return list(iter_rows(read_text(path), name, required, optional, notes))


def number(row: dict, field: str, name: str, line: int, unit: str) -> float:
    """``row[field]`` as a finite float, or a one-line ``ValueError`` naming file, line, field."""
    raw = row[field].strip()
    try:
        v = float(raw)
    except ValueError:
        v = float("nan")
    if v != v or v in (float("inf"), float("-inf")):
        raise ValueError(
            f"{name}:{line}: field {field!r}: not a finite number, got {raw!r} (allowed a "
            f"finite number in {unit})"
        )
    return v
