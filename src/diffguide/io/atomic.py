"""Atomic file writes at the edge of the library.

Outputs are written to a temporary file in the destination folder and renamed into place, so an
interrupted run never leaves a half-written file that looks valid.
"""

import os
from pathlib import Path

from .._core.atomic import atomic_write as atomic_write  # the one implementation


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (UTF-8)."""

    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)

    return atomic_write(path, write)


def atomic_savefig(fig, path: str | os.PathLike, **kwargs) -> Path:
    """Save a matplotlib figure to ``path`` atomically."""
    return atomic_write(path, lambda tmp: fig.savefig(tmp, **kwargs))
