"""A size limit for the command line's cache folder: the least recently used entries go first.

The folder holds JAX's persistent compilation cache (files ``*-cache`` at its top level), the
condensed tables (``tables/*.npz``) and the stored programs (``exports/*.jaxexport`` with their
``*.out``). Every new machine layout, measurement layout or package version adds entries and
nothing else removes them, so :func:`prune` keeps the total under a limit, removing the files
used longest ago (by modification time: the table and program caches :func:`touch` a file
when they read it; JAX's entries count from when they were written). Only files of those
kinds are ever removed — a cache folder named by the user may hold other files.
"""

import os
import re
import stat
import time
from pathlib import Path

from .cacheentry import discard
from .compat import jax_cache_decompress

#: What :func:`prune` may remove: (sub-folder, file-name pattern); a leading ``.`` is an atomic
#: write's temporary file (:mod:`diffguide._core.atomic`).
ENTRIES = (
    ("", re.compile(r"[^/]+-cache")),
    ("tables", re.compile(r"\.?[^/]+\.npz")),
    ("exports", re.compile(r"\.?[^/]+\.(jaxexport|out)")),
)
#: A temporary file younger than this (s) may be a write in progress: it is left alone.
IN_PROGRESS_S = 3600.0


def touch(path: str | os.PathLike) -> None:
    """Mark ``path`` as used now (its modification time), so that :func:`prune` keeps it
    longer; silently nothing where that fails."""
    try:
        os.utime(path)
    except OSError:
        pass


def entries(folder: str | os.PathLike) -> list[tuple[float, int, Path]]:
    """``(modification time, bytes, path)`` of every cache entry below ``folder``
    (:data:`ENTRIES`), oldest first; temporary files of writes in progress left out."""
    now = time.time()
    out = []
    for sub, pattern in ENTRIES:
        try:
            scan = list(os.scandir(Path(folder) / sub))
        except OSError:
            continue
        for item in scan:
            if not pattern.fullmatch(item.name):
                continue
            try:
                st = item.stat(follow_symlinks=False)
            except OSError:
                continue
            if not stat.S_ISREG(st.st_mode):
                continue
            if item.name.startswith(".") and now - st.st_mtime < IN_PROGRESS_S:
                continue
            out.append((st.st_mtime, st.st_size, Path(item.path)))
    out.sort()
    return out


def prune(folder: str | os.PathLike, max_bytes: int) -> tuple[int, int]:
    """Remove cache entries below ``folder``, least recently used first, until the rest take at
    most ``max_bytes``; returns ``(files removed, bytes freed)``. A file that cannot be removed
    (gone already, no permission) is passed over."""
    found = entries(folder)
    total = sum(size for _, size, _ in found)
    removed = freed = 0
    for _, size, path in found:
        if total <= max_bytes:
            break
        try:
            path.unlink()
        except OSError:
            continue
        total -= size
        removed += 1
        freed += size
    return removed, freed


def drop_jax_entries(folder: str | os.PathLike, module_name: str) -> list[tuple[Path, str]]:
    """Remove the damaged entries of JAX's persistent compilation cache in ``folder`` for the
    compiled function ``module_name`` (files ``<module_name>-<hash>-cache``); returns
    ``(path, why)`` of each removed.

    JAX (0.9) warns when it cannot read an entry (``Error reading persistent compilation cache
    entry for '<module_name>'``), compiles again, and then leaves the damaged file in place (it
    never overwrites an entry), so every later run would compile again and warn again. Called on
    that warning, this removes the entries of that name that do not decompress; where all of
    them do (the damage was found later, deserialising), all of that name are removed. JAX then
    writes the fresh compilation in their place.
    """
    found = sorted(Path(folder).glob(f"{glob_escape(module_name)}-*-cache"))
    bad = []
    for path in found:
        try:
            jax_cache_decompress(path.read_bytes())
        except Exception as exc:  # truncated, flipped, foreign: JAX could not read it either
            bad.append((path, f"{type(exc).__name__}: {exc}"))
    if not bad:
        bad = [(path, "JAX could not load it") for path in found]
    removed = []
    for path, why in bad:
        if os.path.isdir(path) and not os.path.islink(path):
            why = "a directory in its place"
        if discard(path):  # a file, a link, or a folder in its place
            removed.append((path, why))
    return removed


def glob_escape(text: str) -> str:
    """``text`` with the characters ``glob`` treats specially escaped."""
    return re.sub(r"([*?\[])", r"[\1]", text)
