"""One file of a disk cache: a header that says what it holds, checked before the payload is used.

Every file of the caches of condensed tables (:mod:`diffguide.fe.cache`) and of stored programs
(:mod:`diffguide._core.aot`) is written as::

    DIFFGUIDE-CACHE\\n
    {"kind": ..., "key": ..., "format": ..., "bytes": ..., "sha256": ..., "diffguide": ...,
     "jax": ..., "jaxlib": ..., "inputs": {...}}\\n
    <payload>

:func:`read` returns the payload only when the header is whole JSON and names the expected kind,
key (the file's name), file format and the running diffguide, JAX and jaxlib versions, and the
payload has the stated length and SHA-256; anything else — a truncated, bit-flipped, foreign or
stale file, a directory or a dangling link in its place, a file that cannot be read — raises
:class:`Damaged` with the reason. The callers then :func:`heal`: one
:class:`~diffguide._core.caches.CacheWarning` (``cache entry X was damaged (why); rebuilt``),
the entry removed where possible, and the result computed again and rewritten — never reported
as a failure of the model or of the input. A folder that cannot be written to is reported once
(:func:`unwritable`) and the run goes on uncached.
"""

import hashlib
import os
import shutil
import warnings
from pathlib import Path

from .atomic import atomic_write
from .caches import Caches, CacheWarning
from .version import __version__

MAGIC = b"DIFFGUIDE-CACHE\n"
#: a header longer than this (bytes) is not one of ours
MAX_HEADER = 1 << 20


class Damaged(Exception):
    """A cache file that exists but cannot be trusted; ``str(exc)`` says why."""


def versions() -> dict[str, str]:
    """The versions a cache file is valid for: diffguide, JAX and jaxlib."""
    import jax

    try:
        import jaxlib

        jaxlib_version = str(jaxlib.__version__)
    except (ImportError, AttributeError):  # pragma: no cover
        jaxlib_version = "?"
    return {"diffguide": __version__, "jax": jax.__version__, "jaxlib": jaxlib_version}


def _line(value: object) -> str:
    return " ".join(str(value).split())  # one line


def encode(kind: str, key: str, fmt: int, payload: bytes, inputs: dict | None = None) -> bytes:
    """The bytes of a cache file holding ``payload`` (see the module docstring)."""
    header = {
        "kind": kind,
        "key": key,
        "format": fmt,
        "bytes": len(payload),
        "sha256": hashlib.sha256(payload).hexdigest(),
        **versions(),
        **{f"inputs.{name}": value for name, value in (inputs or {}).items()},
    }
    text = "".join(f"{name}: {_line(value)}\n" for name, value in sorted(header.items()))
    return MAGIC + text.encode() + b"\n" + payload


def decode(data: bytes, kind: str, key: str, fmt: int) -> tuple[dict[str, str], bytes]:
    """``(header, payload)`` of the bytes of a cache file; :class:`Damaged` unless every check
    of the module docstring passes."""
    if not data.startswith(MAGIC):
        raise Damaged("not a diffguide cache file" if data else "empty file")
    end = data.find(b"\n\n", len(MAGIC) - 1, len(MAGIC) + MAX_HEADER)
    if end < 0:
        raise Damaged("truncated header")
    header = {}
    try:
        for line in data[len(MAGIC):end].decode().splitlines():
            name, value = line.split(": ", 1)
            header[name] = value
    except ValueError:  # not text, or a line without "name: value"
        raise Damaged("unreadable header") from None
    expected = {"kind": kind, "key": key, "format": fmt, **versions()}
    for name, value in expected.items():
        if header.get(name) != _line(value):
            raise Damaged(f"{name} {header.get(name)!r}, expected {_line(value)!r}")
    payload = data[end + 2:]
    if header.get("bytes") != str(len(payload)):
        raise Damaged(f"{len(payload)} bytes of payload, the header says {header.get('bytes')}")
    if header.get("sha256") != hashlib.sha256(payload).hexdigest():
        raise Damaged("checksum mismatch")
    return header, payload


def read(path: Path, kind: str, key: str, fmt: int) -> tuple[dict, bytes] | None:
    """``(header, payload)`` of the cache file ``path``; ``None`` when there is none (a miss);
    :class:`Damaged` when something is there that fails a check or cannot be read."""
    if not os.path.lexists(path):
        return None
    try:
        data = Path(path).read_bytes()
    except OSError as exc:  # a directory, a dangling link, no permission
        raise Damaged(exc.strerror or type(exc).__name__) from None
    return decode(data, kind, key, fmt)


def discard(path: Path) -> bool:
    """Remove a damaged entry (a file, a link, or a folder in its place); ``False`` where that
    fails."""
    try:
        if os.path.isdir(path) and not os.path.islink(path):
            shutil.rmtree(path)
        else:
            os.unlink(path)
    except OSError:
        return False
    return True


def heal(stats: dict, path: Path, why: object) -> None:
    """Report the damaged entry ``path`` (one :class:`CacheWarning`; ``why``: a reason or the
    exception met), count it in ``stats`` (``"damaged"``) and remove it, so that the caller's
    rebuild can write it again."""
    if isinstance(why, BaseException) and not isinstance(why, Damaged):
        why = f"{type(why).__name__}: {why}".strip().rstrip(":")
    why = " ".join(str(why).split())
    why = why if len(why) <= 200 else why[:197] + "..."
    stats["damaged"] = stats.get("damaged", 0) + 1
    removed = discard(path)
    warnings.warn(
        f"cache entry {path} was damaged ({why}); "
        + ("rebuilt" if removed else "rebuilt in memory (it could not be removed)"),
        CacheWarning,
        stacklevel=3,
    )


def unwritable(caches: Caches, folder: Path, exc: OSError) -> None:
    """Say once per folder and :class:`~diffguide._core.caches.Caches` that ``folder`` cannot
    be written to: the run goes on without storing what it computes."""
    if folder in caches.unwritable:
        return
    caches.unwritable.add(folder)
    warnings.warn(
        f"cache folder {folder} cannot be written ({exc.strerror or exc}); running uncached",
        CacheWarning,
        stacklevel=3,
    )


def write(caches: Caches, path: Path, data: bytes) -> bool:
    """Write ``data`` to ``path`` atomically; ``False`` (and :func:`unwritable`) where the folder
    cannot be written."""
    try:
        atomic_write(path, lambda tmp: Path(tmp).write_bytes(data))
    except OSError as exc:
        unwritable(caches, path.parent, exc)
        return False
    return True
