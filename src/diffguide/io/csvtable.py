"""One set of rules for every CSV file diffguide reads (measurements, rails, truth profiles).

- text in UTF-8 (a byte-order mark is allowed), UTF-16 (with a byte-order mark, or told by the
  NUL bytes of ASCII text) or cp1252/Latin-1 (what is not valid UTF-8), or in a stated
  ``encoding`` (:func:`decode`); no NUL bytes in the decoded text;
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


#: Encodings :func:`decode` accepts by name besides ``"auto"`` (any Python codec name works).
ENCODINGS = ("auto", "utf-8", "utf-8-sig", "utf-16", "utf-16-le", "utf-16-be", "cp1252",
             "latin-1")


def decode(data: bytes, name: str = "<bytes>", encoding: str = "auto") -> tuple[str, str]:
    """``(text, encoding used)`` of a file's bytes.

    ``"auto"``: a byte-order mark decides (UTF-8, UTF-16 LE/BE); without one, NUL bytes in
    every second place of the first bytes mean UTF-16 (ASCII text written as UTF-16, LE or BE);
    else UTF-8, and text that is not valid UTF-8 is read as cp1252 (Windows Western, a superset
    of Latin-1's printable characters; its five undefined bytes as Latin-1). Any other value is
    a Python codec name, used as stated (a UTF-8 byte-order mark is dropped)."""
    if encoding != "auto":
        try:
            text = data.decode(encoding)
        except LookupError:
            raise ValueError(f"{name}: unknown encoding {encoding!r} (allowed "
                             f"{', '.join(ENCODINGS)} or another Python codec name)") from None
        except UnicodeDecodeError as exc:
            line = data[: exc.start].count(b"\n") + 1
            raise ValueError(f"{name}:{line}: not {encoding} text (byte {exc.start}; "
                             "--encoding auto detects UTF-8, UTF-16 and cp1252)") from None
        return text.removeprefix("\ufeff"), encoding
    if data.startswith(b"\xef\xbb\xbf"):
        used = "utf-8-sig"
    elif data.startswith((b"\xff\xfe", b"\xfe\xff")):
        used = "utf-16"
    elif len(data) >= 4 and data[1:64:2].count(0) > 0.9 * len(data[1:64:2]):
        used = "utf-16-le"
    elif len(data) >= 4 and data[0:64:2].count(0) > 0.9 * len(data[0:64:2]):
        used = "utf-16-be"
    else:
        used = "utf-8"
    try:
        text = data.decode(used)
    except UnicodeDecodeError as exc:
        if used != "utf-8":
            line = data[: exc.start].count(b"\n") + 1
            raise ValueError(f"{name}:{line}: not {used} text (byte {exc.start})") from None
        try:
            used, text = "cp1252", data.decode("cp1252")
        except UnicodeDecodeError:  # one of cp1252's five undefined bytes: Latin-1 has them all
            used, text = "latin-1", data.decode("latin-1")
    return text.removeprefix("\ufeff"), used


def read_bytes(path: str | os.PathLike) -> bytes:
    """The bytes of a file (size checked; one-line errors)."""
    name = os.fspath(path)
    try:
        size = os.path.getsize(name)
        if size > _MAX_BYTES:
            raise ValueError(f"{name}: file too large ({size} bytes > {_MAX_BYTES})")
        with open(name, "rb") as fh:
            return fh.read()
    except OSError as exc:
        raise ValueError(f"{name}: cannot read the file: {exc.strerror or exc}") from None


def read_text(path: str | os.PathLike, encoding: str = "auto", info: dict | None = None) -> str:
    """The text of a CSV file (size checked; encoding as :func:`decode`; one-line errors).
    ``info`` (a dict) receives ``encoding``, the encoding used."""
    name = os.fspath(path)
    text, used = decode(read_bytes(path), name, encoding)
    if info is not None:
        info["encoding"] = used
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
