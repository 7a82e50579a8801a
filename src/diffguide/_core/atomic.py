"""Atomic outputs: a temporary file in the destination folder, renamed into place, so an
interrupted write never leaves a half-written file that looks valid (outputs at the edge, and
the caches of condensed tables and stored programs); a folder staged beside its destination and
swapped in with no gap (:func:`replace_dir`); the leftovers of killed runs removed
(:func:`remove_leftovers`); an output's place checked before the work (:func:`check_output_place`).
"""

import contextlib
import ctypes
import errno
import os
import re
import shutil
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path


def usual_mode(base: int) -> int:
    """``base`` (``0o666`` for a file, ``0o777`` for a folder) less the process's umask: the
    permissions ``open`` or ``mkdir`` would give (``mkstemp``/``mkdtemp`` give 0600/0700)."""
    umask = os.umask(0)
    os.umask(umask)
    return base & ~umask


def atomic_write(path: str | os.PathLike, write: Callable[[str], None]) -> Path:
    """Call ``write(tmp_path)`` and rename the result to ``path`` atomically.

    The temporary file lives in the same folder (same file system), and keeps the destination's
    suffix so that writers choosing a format by extension (``savefig``, ``np.savez``) behave the
    same. On any error the temporary file is removed and the error raised.
    """
    path = Path(path)
    if path.is_dir() or not path.name:  # else a temporary file left in its parent (even /)
        raise IsADirectoryError(errno.EISDIR, "is a folder; a file name is needed", str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent or ".")
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, usual_mode(0o666))
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


# --- folders: staged next to their destination, swapped in with no gap --------------------------

#: free space (bytes) an output's folder must have before a command starts its work: a generous
#: bound on any one command's outputs (a fit's folder is under 1 MB, its figures included)
MIN_FREE_BYTES = 50 * 2**20
#: a leftover whose owner cannot be told (no pid in its name) is removed after this age (s)
LEFTOVER_AGE_S = 86400.0

_RENAME_EXCHANGE = 2  # <linux/fs.h>
_AT_FDCWD = -100
_STAGING_KINDS = ("tmp", "old")


def exchange(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Swap the names ``a`` and ``b`` (both existing, same file system) in one step:
    ``renameat2(a, b, RENAME_EXCHANGE)`` (Linux ≥ 3.15). Returns ``False``, having changed
    nothing, where the system or the file system does not offer it; raises ``OSError`` for
    any other failure."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):  # a C library without it (old glibc, musl < 1.2.?)
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                          ctypes.c_uint]
    renameat2.restype = ctypes.c_int
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False  # no such system call, or a file system without the flag
    raise OSError(err, os.strerror(err), os.fspath(a), None, os.fspath(b))


@contextlib.contextmanager
def interrupts_deferred():
    """A ``with`` block that SIGINT does not cut short: an interrupt arriving inside it is held
    and delivered (the previous handler called, or ``KeyboardInterrupt`` raised) as the block
    ends. Outside the main thread (where Python runs no signal handler) it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: held.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if held:
            if callable(previous):
                previous(signal.SIGINT, None)
            elif previous != signal.SIG_IGN:
                raise KeyboardInterrupt


def staging_dir(out: str | os.PathLike, kind: str = "tmp") -> Path:
    """A new empty folder ``.<out's name>.<pid>.<random>.<kind>`` next to ``out`` (created with
    its parents), owned by this process: :func:`remove_leftovers` keeps it while the process
    lives."""
    out = Path(out)
    if kind not in _STAGING_KINDS:
        raise ValueError(f"kind must be one of {_STAGING_KINDS}, got {kind!r}")
    out.parent.mkdir(parents=True, exist_ok=True)
    return Path(tempfile.mkdtemp(prefix=f".{out.name}.{os.getpid()}.", suffix=f".{kind}",
                                 dir=out.parent))


def replace_dir(new: str | os.PathLike, out: str | os.PathLike,
                discard: Callable[[Path], None] | None = None) -> None:
    """Put the complete folder ``new`` in place of ``out`` (``new`` is consumed), so that
    ``out`` names the previous folder or the new one at every instant, never neither.

    Where ``out`` exists the two are swapped by :func:`exchange`, one atomic step, and the
    previous folder (now under ``new``'s name) is removed. Where the system lacks that call the
    swap takes two renames (``out`` aside, ``new`` into place): a process killed between them
    (SIGKILL, power loss) leaves no ``out``, its previous content under a hidden
    ``.<name>.<pid>.<random>.old`` beside it (which :func:`remove_leftovers` removes later). A
    Ctrl-C (SIGINT) never splits the swap: it is held until the swap is done
    (:func:`interrupts_deferred`). The folder gets the usual permissions (``mkdtemp``'s are 0700).
    ``discard(previous)`` disposes of the previous folder, swapped out (default: removed whole).
    """
    new, out = Path(new), Path(out)
    os.chmod(new, usual_mode(0o777))
    old = wrapper = None
    with interrupts_deferred():
        try:
            os.rename(new, out)  # no earlier folder (an empty one is replaced here too)
        except OSError as exc:
            if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                raise
            if exchange(new, out):
                old = new
            else:
                wrapper = staging_dir(out, "old")
                old = wrapper / out.name
                os.rename(out, old)
                os.rename(new, out)
    if old is None:
        return
    if discard is None:
        shutil.rmtree(wrapper or old, ignore_errors=True)
        return
    discard(old)
    if wrapper is not None:
        with contextlib.suppress(OSError):
            wrapper.rmdir()


def _owner_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # EPERM: another user's live process
        return True
    return True


def remove_leftovers(out: str | os.PathLike, max_age_s: float = LEFTOVER_AGE_S) -> list[Path]:
    """Remove what killed runs left beside ``out``: the entries named
    ``.<out's name>.<pid>.<random>.tmp|old`` (:func:`staging_dir`) whose process is gone, and the
    ``.<out's name>.<random>.tmp|old`` of earlier versions (no pid) older than ``max_age_s``.
    Nothing else is touched. Returns the paths removed."""
    out = Path(out)
    name = re.escape(out.name)
    with_pid = re.compile(rf"\.{name}\.(\d+)\.[a-z0-9_]{{8}}\.(tmp|old)")
    without = re.compile(rf"\.{name}\.[a-z0-9_]{{8}}\.(tmp|old)")
    removed = []
    try:
        entries = list(os.scandir(out.parent))
    except OSError:
        return removed
    now = time.time()
    for e in entries:
        m = with_pid.fullmatch(e.name)
        if m:
            stale = not _owner_alive(int(m.group(1)))
        elif without.fullmatch(e.name):
            try:
                stale = now - e.stat(follow_symlinks=False).st_mtime > max_age_s
            except OSError:
                continue
        else:
            continue
        if not stale:
            continue
        path = Path(e.path)
        if e.is_dir(follow_symlinks=False):
            shutil.rmtree(path, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                path.unlink()
        if not os.path.lexists(path):
            removed.append(path)
    return removed


def check_output_file(path: str | os.PathLike) -> Path:
    """``path`` as an output file: refused (``ValueError``) where it names a folder (an existing
    one, ``.``, ``..``, or a path ending in a separator)."""
    text = os.fspath(path)
    if (not text or text.endswith(os.sep) or Path(text).name in ("", ".", "..")
            or os.path.isdir(text)):
        raise ValueError("is a folder; a file name is needed")
    return Path(text)


def check_output_place(path: str | os.PathLike, need_bytes: int = MIN_FREE_BYTES) -> Path:
    """Check, before any work, that ``path`` can be written: the nearest existing folder on its
    way is a folder, accepts a new file (one is created and removed: permissions, read-only
    file systems, quotas, whoever runs) and has ``need_bytes`` free. Returns that folder;
    raises ``ValueError`` naming it otherwise."""
    folder = Path(os.path.abspath(path)).parent
    while not os.path.lexists(folder) and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise ValueError(f"{folder} is not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{Path(path).name}.{os.getpid()}.", suffix=".tmp",
                                     dir=folder)
    except OSError as exc:
        raise ValueError(f"cannot write in {folder}: {exc.strerror or exc}") from None
    os.close(fd)
    os.unlink(probe)
    free = shutil.disk_usage(folder).free
    if free < need_bytes:
        raise ValueError(f"{folder} has {free / 2**20:.1f} MB free; the outputs need up to "
                         f"{need_bytes / 2**20:.0f} MB")
    return folder
