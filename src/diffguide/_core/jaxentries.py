"""Damage to JAX's persistent compilation cache that JAX itself cannot see, found before JAX
reads the folder: entries swapped (each file holds another's compiled program — JAX loads it
and runs the wrong program: a wrong result, no error) and a directory in an entry's place
(JAX warns on every run and never writes the entry again).

JAX's entries (``<module>-<hash>-cache`` at the folder's top level, :mod:`.cachedir`) carry no
record of their key, so diffguide keeps one: a ledger beside them (:data:`LEDGER`, one line
``sha256 bytes mtime_ns name`` per entry) of what each entry held when it was first seen.
:func:`check` — at the start of every command-line run that uses the folder — then

- removes anything under an entry's name that is not a regular file (a directory, a link);
- for each entry the ledger knows whose size or modification time changed, hashes it: content
  that another entry of the ledger held (the two were swapped, or one copied over the other),
  or any other content (a rewrite JAX never does: it writes an entry once), is removed;
- for each entry it does not know (written by the previous run), checks that its decompressed
  program names the module of its file name (a swap between two runs' new entries) and adds it;
- and writes the ledger again (atomically) when it changed.

Not caught: two entries of one module (one function at two shapes) swapped before any run had
recorded them — their programs name the same module.

What was removed is one line (a :class:`~diffguide._core.caches.CacheWarning`, shown by the
command line as ``diffguide: ...``), naming each entry and why; JAX then compiles the program again and
writes the entry afresh. The cost when nothing changed is one ``stat`` per entry.
"""

import hashlib
import os
import re
import stat
import warnings
from pathlib import Path

from .cacheentry import discard
from .caches import CacheWarning
from .compat import jax_cache_decompress

#: the ledger's file name in the cache folder
LEDGER = "jax-entries.sha256"
_NAME = re.compile(r"(?P<module>.+)-[0-9a-f]{16,}-cache")


def _read_ledger(path: Path) -> dict[str, tuple[str, int, int]]:
    out = {}
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return out
    for line in text.splitlines():
        parts = line.split(" ", 3)
        if len(parts) == 4 and parts[1].isdigit() and parts[2].isdigit():
            out[parts[3]] = (parts[0], int(parts[1]), int(parts[2]))
    return out


def _write_ledger(path: Path, ledger: dict) -> None:
    from .atomic import atomic_write

    text = "".join(f"{sha} {size} {mtime} {name}\n"
                   for name, (sha, size, mtime) in sorted(ledger.items()))
    try:
        atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    except OSError:
        pass  # an unwritable folder is reported by the cache setup; the check is only lost


def _names_its_module(data: bytes, module: str) -> bool:
    """Whether a JAX entry's bytes decompress to a program that names ``module`` as a whole
    word (not as the start of a longer name: ``jit_f`` in ``jit_fit``)."""
    try:
        program = jax_cache_decompress(data)
    except Exception:  # noqa: BLE001 - JAX's own read will fail too: drop_jax_entries heals it
        return True
    return re.search(re.escape(module.encode()) + rb"(?![A-Za-z0-9_])", program) is not None


def _say(removed: list[tuple[Path, str]]) -> None:
    """One note for what was removed (a swap is two entries, one event)."""
    if len(removed) == 1:
        (path, why), = removed
        text = f"JAX compilation cache entry {path} was damaged ({why})"
    else:
        text = (f"{len(removed)} JAX compilation cache entries in {removed[0][0].parent} were "
                "damaged (" + "; ".join(f"{p.name}: {why}" for p, why in removed[:4])
                + ("; ..." if len(removed) > 4 else "") + ")")
    warnings.warn(text + "; removed, compiled again", CacheWarning, stacklevel=3)


def check(folder: str | os.PathLike) -> list[tuple[Path, str]]:
    """Find and remove the damaged JAX entries of ``folder`` (see the module docstring), say
    each in one :class:`~diffguide._core.caches.CacheWarning`, update the ledger; returns
    ``(path, why)`` of each removed."""
    folder = Path(folder)
    ledger_path = folder / LEDGER
    ledger = _read_ledger(ledger_path)
    try:
        scan = [item for item in os.scandir(folder) if _NAME.fullmatch(item.name)]
    except OSError:
        return []
    owner = {sha: name for name, (sha, _, _) in ledger.items()}
    seen, removed, changed = set(), [], False
    for item in sorted(scan, key=lambda i: i.name):
        path = Path(item.path)
        try:
            st = item.stat(follow_symlinks=False)
        except OSError:
            continue
        if not stat.S_ISREG(st.st_mode):
            why = "a directory in its place" if stat.S_ISDIR(st.st_mode) else "not a file"
            if discard(path):
                removed.append((path, why))
            changed |= item.name in ledger
            continue
        known = ledger.get(item.name)
        if known and (known[1], known[2]) == (st.st_size, st.st_mtime_ns):
            seen.add(item.name)
            continue
        try:
            data = path.read_bytes()
        except OSError:
            continue
        sha = hashlib.sha256(data).hexdigest()
        why = None
        if known and sha != known[0]:
            other = owner.get(sha)
            why = (f"it holds the program of {other} (entries swapped?)" if other else
                   "its content changed after JAX wrote it")
        elif not known and not _names_its_module(data, _NAME.fullmatch(item.name)["module"]):
            why = "it holds another module's program (entries swapped?)"
        if why is not None:
            if discard(path):
                removed.append((path, why))
            ledger.pop(item.name, None)
            changed = True
            continue
        ledger[item.name] = (sha, st.st_size, st.st_mtime_ns)
        seen.add(item.name)
        changed = True
    for name in set(ledger) - seen:  # pruned, removed or gone
        del ledger[name]
        changed = True
    if removed:
        _say(removed)
    if changed:
        _write_ledger(ledger_path, ledger)
    return removed
