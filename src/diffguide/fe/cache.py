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
- **files**: one ``<key>.npz`` per table: a header (:mod:`diffguide._core.cacheentry`: the
  key, :data:`FORMAT`, the diffguide, JAX and jaxlib versions, the inputs' structure and the
  SHA-256 of the payload), then the :class:`~diffguide.fe.condense.CondensedTable` arrays as
  ``.npz`` bytes; written to a temporary file in the same folder and renamed into place (atomic:
  a reader sees a whole file or none; concurrent writers of one key write the same bytes).
- **robust**: a file that fails a check of its header or checksum, or cannot be read or
  unpacked, is reported (one :class:`~diffguide._core.caches.CacheWarning`), removed and
  rewritten with the table computed again; a folder that cannot be written to is reported once
  and the run goes on uncached.

A traced input (inside ``jit``/``grad``: differentiating w.r.t. the thickness or the node
coordinates) bypasses the cache. The arrays read back are bit-identical to those written.
Without active caches (the library's default) nothing is read or written; lookups are counted
in the active caches' ``table_stats``.
"""

import hashlib
import io
from pathlib import Path

import jax
import numpy as np

from .._core import cacheentry
from .._core.cachedir import touch
from .._core.caches import Caches
from .._core.fingerprint import code_fingerprint

#: Bumped when the file layout changes.
FORMAT = 2
_KIND = "diffguide.fe.cache"
_FIELDS = ("K", "f", "R", "r0", "node_modes", "node_u0", "ref_points", "nodes")
_code_hash: str | None = None  # the source hash, computed once per process
_inputs: dict[str, dict] = {}  # key -> what it was made from (for the file's header)


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
    arrays = []
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
        arrays.append(f"{a.dtype.str}{list(a.shape)}")
    key = h.hexdigest()
    _inputs[key] = {
        "code": _code_version(),
        "x64": bool(jax.config.read("jax_enable_x64")),
        "structure": str(treedef),
        "arrays": arrays,
    }
    return key


def _path(caches: Caches | None, key: str | None) -> Path | None:
    if caches is None or caches.tables is None or key is None:
        return None
    return caches.tables / f"{key}.npz"


def load(caches: Caches | None, key: str | None):
    """The arrays of the table of ``key`` (``{field: array}`` of a
    :class:`~diffguide.fe.condense.CondensedTable`, which the caller builds) in ``caches``,
    or ``None`` (no table cache, no file, or a damaged one: reported and removed, so that the
    caller computes the table and :func:`store` writes it again)."""
    path = _path(caches, key)
    if path is None:
        return None
    stats = caches.table_stats
    try:
        found = cacheentry.read(path, _KIND, key, FORMAT)
        if found is not None:
            with np.load(io.BytesIO(found[1]), allow_pickle=False) as z:
                arrays = {k: np.array(z[k]) for k in _FIELDS}
    except Exception as exc:  # failed a check, or a payload numpy cannot unpack
        cacheentry.heal(stats, path, exc)
        found = None
    if found is None:
        stats["misses"] += 1
        return None
    stats["hits"] += 1
    touch(path)  # used now: the cache's size limit removes the least recently used first
    return {k: jax.numpy.asarray(v) for k, v in arrays.items()}


def store(caches: Caches | None, key: str | None, table) -> None:
    """Write ``table`` under ``key`` in ``caches`` (atomically); nothing without a table cache,
    and a folder that cannot be written is reported once (the run goes on uncached)."""
    path = _path(caches, key)
    if path is None or any(
        isinstance(v, jax.core.Tracer) for v in jax.tree_util.tree_leaves(table)
    ):
        return
    buffer = io.BytesIO()
    np.savez(buffer, **{k: np.asarray(getattr(table, k)) for k in _FIELDS})
    data = cacheentry.encode(_KIND, key, FORMAT, buffer.getvalue(), _inputs.get(key))
    if cacheentry.write(caches, path, data):
        caches.table_stats["writes"] += 1
