"""Atomic file writes: a temporary file in the destination folder, renamed into place, so an
interrupted write never leaves a half-written file that looks valid (outputs at the edge, and
the caches of condensed tables and stored programs)."""

import os
import tempfile
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
