"""The code a cached result depends on, as one hash (for the caches of condensed tables and of
stored programs: a changed source or version must miss)."""

import hashlib
from pathlib import Path

import jax

from .version import __version__


def code_fingerprint(fmt: int, root: Path, pattern: str) -> str:
    """SHA-256 (hex) of a cache's file-format number ``fmt``, the diffguide, JAX and jaxlib
    versions, and every source file below ``root`` matching ``pattern`` (its path relative to
    ``root`` and its bytes, in sorted order)."""
    h = hashlib.sha256(f"{fmt}|{__version__}|{jax.__version__}|".encode())
    try:
        import jaxlib

        h.update(jaxlib.__version__.encode())
    except (ImportError, AttributeError):  # pragma: no cover
        pass
    for path in sorted(root.glob(pattern)):
        h.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()
