"""A disk cache of condensed tables: a table condensed once is read back, not recomputed.

The condensation (:func:`diffguide.fe.condense`) is a one-time computation per table, but the
command line repeats it on every run (``diffguide fit`` condenses the table at nine thicknesses
and the prior value, ``simulate`` once): ~0.05-0.1 s each with concrete inputs (NumPy), seconds
for the first compiled call with traced ones. Within ``with Caches(tables=folder):``
(:class:`diffguide._core.caches.Caches`; the command line activates ``<cache dir>/tables`` for
each command — its ``--cache-dir``, ``$DIFFGUIDE_CACHE_DIR``, default ``~/.cache/diffguide/jax``
— and ``--no-cache`` switches it off), every condensation with concrete inputs is looked up
first:

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
Without active caches (the library's default) nothing is read or written; lookups are counted
in the active caches' ``table_stats``.
"""

import hashlib
from pathlib import Path

import jax
import numpy as np

from .._core.atomic import atomic_write
from .._core.cachedir import touch
from .._core.caches import Caches
from .._core.fingerprint import code_fingerprint

#: Bumped when the file layout changes.
FORMAT = 1
_FIELDS = ("K", "f", "R", "r0", "node_modes", "node_u0", "ref_points", "nodes")
_code_hash: str | None = None  # the source hash, computed once per process


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


def _path(caches: Caches | None, key: str | None) -> Path | None:
    if caches is None or caches.tables is None or key is None:
        return None
    return caches.tables / f"{key}.npz"


def load(caches: Caches | None, key: str | None):
    """The table of ``key`` (a :class:`~diffguide.fe.condense.CondensedTable`) in ``caches``,
    or ``None`` (no table cache, no file, or a file that is unreadable, incomplete or for
    another key)."""
    path = _path(caches, key)
    if path is None:
        return None
    from .condense import CondensedTable

    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["key"]) != key:
                raise ValueError("another key")
            arrays = {k: np.array(z[k]) for k in _FIELDS}
    except Exception:  # missing, partial, corrupt, old: recompute (and rewrite)
        caches.table_stats["misses"] += 1
        return None
    caches.table_stats["hits"] += 1
    touch(path)  # used now: the cache's size limit removes the least recently used first
    import jax.numpy as jnp

    return CondensedTable(**{k: jnp.asarray(v) for k, v in arrays.items()})


def store(caches: Caches | None, key: str | None, table) -> None:
    """Write ``table`` under ``key`` in ``caches`` (atomically); silently nothing without a
    table cache or when the folder cannot be written."""
    path = _path(caches, key)
    if path is None or any(
        isinstance(v, jax.core.Tracer) for v in jax.tree_util.tree_leaves(table)
    ):
        return
    arrays = {k: np.asarray(getattr(table, k)) for k in _FIELDS}
    try:
        atomic_write(path, lambda tmp: np.savez(tmp, key=np.asarray(key), **arrays))
        caches.table_stats["writes"] += 1
    except OSError:
        pass
