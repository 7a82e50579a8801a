"""A disk cache of condensed tables: a table condensed once is read back, not recomputed.

The condensation (:func:`diffguide.fe.condense`) is a one-time computation per table, but the
command line repeats it on every run (``diffguide fit`` condenses the table at nine thicknesses
and the prior value, ``simulate`` once): ~0.05-0.1 s each with concrete inputs (NumPy), seconds
for the first compiled call with traced ones. With a cache
folder set (:func:`set_table_cache_dir`; the command line sets ``<cache dir>/tables`` — its
``--cache-dir``, ``$DIFFGUIDE_CACHE_DIR``, default ``~/.cache/diffguide/jax`` — and
``--no-cache`` switches it off), every condensation with concrete inputs is looked up first:

- **key**: SHA-256 of everything the result depends on — every array and static field of the
  mesh, the plate section (thickness, material), the patches, the control points, the node and
  reference-point overrides, gravity, surface load and method — plus the code that computes it:
  the source of :mod:`diffguide.fe` (every module), the diffguide, JAX and jaxlib versions, the
  float width and :data:`FORMAT`. A changed input or a changed code misses.
- **files**: one ``<key>.npz`` per table holding the :class:`~diffguide.fe.condense.CondensedTable`
  arrays and the key itself; written to a temporary file in the same folder and renamed into
  place (atomic: a reader sees a whole file or none; concurrent writers of one key write the
  same bytes).
- **robust**: a file that cannot be read, lacks a field, or holds another key is ignored and
  rewritten; a folder that cannot be written to only disables writing.

A traced input (inside ``jit``/``grad``: differentiating w.r.t. the thickness or the node
coordinates) bypasses the cache. The arrays read back are bit-identical to those written.
"""

import hashlib
import os
from pathlib import Path

import jax
import numpy as np

from .._core.atomic import atomic_write
from .._core.cachedir import touch
from .._core.fingerprint import code_fingerprint

#: Bumped when the file layout changes.
FORMAT = 1
_FIELDS = ("K", "f", "R", "r0", "node_modes", "node_u0", "ref_points", "nodes")
_dir: Path | None = None
_code_hash: str | None = None
#: Lookups in this process: ``{"hits": n, "misses": n, "writes": n}`` (for benchmarks and tests).
stats = {"hits": 0, "misses": 0, "writes": 0}


def set_table_cache_dir(path: str | os.PathLike | None) -> None:
    """Use ``path`` (created when needed) for condensed tables; ``None`` switches the cache off
    (the default: the library caches nothing unless asked; the command line asks)."""
    global _dir
    _dir = None if path is None else Path(path).expanduser()


def table_cache_dir() -> Path | None:
    """The folder in use, or ``None``."""
    return _dir


def _code_version() -> str:
    global _code_hash
    if _code_hash is None:
        _code_hash = code_fingerprint(FORMAT, Path(__file__).parent, "*.py")
    return _code_hash


def table_key(*inputs) -> str | None:
    """SHA-256 (hex) of the inputs of a condensation (any pytree: arrays, numbers, modules with
    static fields) and of the code version; ``None`` when an input is traced (no caching)."""
    leaves, treedef = jax.tree_util.tree_flatten(inputs)
    h = hashlib.sha256()
    h.update(_code_version().encode())
    h.update(str(jax.config.read("jax_enable_x64")).encode())
    h.update(str(treedef).encode())
    for leaf in leaves:
        if isinstance(leaf, jax.core.Tracer):
            return None
        if isinstance(leaf, (str, bytes)):
            h.update(b"s" + str(leaf).encode())
            continue
        a = np.asarray(leaf)
        if a.dtype == object:
            h.update(b"o" + repr(leaf).encode())
            continue
        h.update(f"a{a.dtype.str}{a.shape}".encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _path(key: str) -> Path | None:
    return None if _dir is None else _dir / f"{key}.npz"


def load(key: str | None):
    """The cached table of ``key`` (a :class:`~diffguide.fe.condense.CondensedTable`), or
    ``None`` (no cache, no file, or a file that is unreadable, incomplete or for another key)."""
    path = None if key is None else _path(key)
    if path is None:
        return None
    from .condense import CondensedTable

    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["key"]) != key:
                raise ValueError("another key")
            arrays = {k: np.array(z[k]) for k in _FIELDS}
    except Exception:  # missing, partial, corrupt, old: recompute (and rewrite)
        stats["misses"] += 1
        return None
    stats["hits"] += 1
    touch(path)  # used now: the cache's size limit removes the least recently used first
    import jax.numpy as jnp

    return CondensedTable(**{k: jnp.asarray(v) for k, v in arrays.items()})


def store(key: str | None, table) -> None:
    """Write ``table`` under ``key`` (atomically); silently nothing when no cache is set or the
    folder cannot be written."""
    path = None if key is None else _path(key)
    if path is None or any(
        isinstance(v, jax.core.Tracer) for v in jax.tree_util.tree_leaves(table)
    ):
        return
    arrays = {k: np.asarray(getattr(table, k)) for k in _FIELDS}
    try:
        atomic_write(path, lambda tmp: np.savez(tmp, key=np.asarray(key), **arrays))
        stats["writes"] += 1
    except OSError:
        pass
