"""Output folders diffguide owns: a command replaces a folder only where it wrote it itself.

Each output folder diffguide writes holds a marker, :data:`MARKER`, naming the command and
listing the files it wrote. :func:`check_output_dir` refuses (``ValueError`` naming the option
and the folder), before any work, every folder it may not replace: the working folder or one of
its parents (``--out .``), a file, a non-empty folder without the marker (whatever else it
holds), another command's output, or an output to which files were added since. On replacement
(:class:`OutputFolder`) the folder is checked again, the new one swapped in with no gap
(:func:`diffguide._core.atomic.replace_dir`), and of the previous one only the files its marker
lists are removed.
"""

import contextlib
import json
import os
import shutil
import warnings
from collections.abc import Callable
from pathlib import Path

from .._core.atomic import interrupts_deferred, replace_dir, staging_dir
from .._core.version import __version__

#: the marker file in every output folder diffguide writes
MARKER = ".diffguide-output.json"
#: a marker larger than this is not diffguide's (one name per file written: well under 64 kB)
_MARKER_MAX_BYTES = 1 << 20


def _entries(folder: Path) -> list[os.DirEntry]:
    with os.scandir(folder) as it:
        return list(it)


def read_marker(folder: str | os.PathLike) -> dict | None:
    """The marker of ``folder`` (``{"command", "files", ...}``), or ``None`` where it has none
    or one that diffguide did not write (unreadable, not JSON, wrong fields)."""
    path = Path(folder) / MARKER
    try:
        if not path.is_file() or path.is_symlink() or path.stat().st_size > _MARKER_MAX_BYTES:
            return None
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if (not isinstance(data, dict) or not isinstance(data.get("command"), str)
            or not data["command"].isascii() or not data["command"].isalpha()
            or not isinstance(data.get("files"), list)
            or not all(isinstance(f, str) and f and "/" not in f and f not in (".", "..")
                       for f in data["files"])):
        return None
    return data


def marker_text(command: str, files: list[str]) -> str:
    """The marker's content: the command, the files it wrote (names in the folder), the
    version."""
    return json.dumps({"diffguide_output": 1, "command": command, "files": sorted(files),
                       "version": __version__}, indent=1) + "\n"


def _refusal(flag: str, out: Path, why: str,
             hint: str = "choose a new or empty folder, or remove this one yourself") -> ValueError:
    return ValueError(f"{flag} {out}: {why}; refusing to replace it (nothing done): {hint}")


def check_output_dir(path: str | os.PathLike, command: str, flag: str = "--out") -> Path:
    """``path`` resolved, where ``command`` may write its output folder there: the folder does
    not exist, is empty, or is an earlier output of ``command`` (its marker) holding nothing
    but the files the marker lists. Raises ``ValueError`` (naming ``flag`` and the folder)
    otherwise, and for the working folder or any of its parents, whatever they hold."""
    out = Path(os.path.abspath(path))
    resolved = out.resolve()
    cwd = Path.cwd().resolve()
    if resolved == cwd or resolved in cwd.parents:
        where = "the working folder" if resolved == cwd else "a parent of the working folder"
        raise _refusal(flag, out, f"is {where}", f"choose a new folder, e.g. {flag} results")
    if not os.path.lexists(out):
        return resolved
    if out.is_symlink() or not out.is_dir():
        raise _refusal(flag, out, "exists and is not a folder" if not out.is_symlink()
                       else "is a symbolic link")
    try:
        entries = _entries(out)
    except OSError as exc:
        raise _refusal(flag, out, f"cannot be read ({exc.strerror or exc})") from None
    if not entries:
        return resolved
    marker = read_marker(out)
    if marker is None:
        raise _refusal(flag, out, f"is not empty and diffguide did not write it (no {MARKER})")
    if marker["command"] != command:
        raise _refusal(flag, out, f"holds the output of 'diffguide {marker['command']}', not "
                       f"of 'diffguide {command}'")
    listed = set(marker["files"]) | {MARKER}
    foreign = sorted(e.name for e in entries
                     if e.name not in listed or e.is_dir(follow_symlinks=False))
    if foreign:
        shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3
                                          else "")
        raise _refusal(flag, out, f"holds files diffguide did not write ({shown})")
    return resolved


def _discard(old: Path, files: list[str], out: Path) -> None:
    """Remove, from the previous output folder ``out`` swapped out to ``old``, the marker and
    the files it lists, then the folder; anything else (added in the moment between the last
    check and the swap) is kept, in a visible folder beside ``out``, with a warning."""
    for name in [*files, MARKER]:
        with contextlib.suppress(FileNotFoundError, IsADirectoryError):
            (old / name).unlink()
    try:
        old.rmdir()
    except OSError:
        kept = out.with_name(f"{out.name}.kept-{os.getpid()}")
        with contextlib.suppress(OSError):
            os.rename(old, kept)
            old = kept
        warnings.warn(f"files added to the output folder while diffguide wrote it were kept in "
                      f"{old}", stacklevel=2)


class OutputFolder:
    """A command's output folder, written into a temporary folder next to ``out`` and swapped
    into place by :meth:`commit`, with its marker; ``out`` checked when made and again just
    before the swap (:func:`check_output_dir`). On an exception inside the ``with`` block the
    temporary folder is removed. ``checkpoint`` (called before staging and before the swap)
    may raise to stop (the command line's Ctrl-C record)."""

    def __init__(self, out: str | os.PathLike, command: str, flag: str = "--out",
                 checkpoint: Callable[[], None] = lambda: None):
        self.command, self.flag, self.checkpoint = command, flag, checkpoint
        self.out = check_output_dir(out, command, flag)
        checkpoint()
        self.tmp = staging_dir(self.out)

    def __enter__(self) -> "OutputFolder":
        return self

    def __exit__(self, kind, *exc) -> None:
        if kind is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)

    def write(self, files: dict[str, object], dpi: int = 110) -> None:
        """``files``: {name: text, bytes or matplotlib figure}."""
        for name, content in files.items():
            if isinstance(content, str):
                (self.tmp / name).write_text(content, encoding="utf-8")
            elif isinstance(content, bytes):
                (self.tmp / name).write_bytes(content)
            else:
                content.savefig(self.tmp / name, dpi=dpi)

    def commit(self) -> None:
        """Write the marker, check ``out`` again, and swap the staged folder in (``checkpoint``
        first; an interrupt during the swap is held until it is done)."""
        written = [e.name for e in _entries(self.tmp) if e.name != MARKER]
        (self.tmp / MARKER).write_text(marker_text(self.command, written), encoding="utf-8")
        with interrupts_deferred():
            self.checkpoint()
            check_output_dir(self.out, self.command, self.flag)
            previous = read_marker(self.out) if self.out.is_dir() else None
            files = previous["files"] if previous else []
            replace_dir(self.tmp, self.out, discard=lambda old: _discard(old, files, self.out))
