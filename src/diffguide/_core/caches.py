"""The disk caches of a run, held by one explicit object that is active within a ``with`` block.

Two caches make a second run of a command fast: the condensed tables
(:mod:`diffguide.fe.cache`) and the traced programs stored with ``jax.export``
(:mod:`diffguide._core.aot`). The library writes neither unless its caller asks, by making a
:class:`Caches` and activating it::

    with Caches(tables=folder / "tables", exports=folder / "exports"):
        fit = fit_rails(...)  # condensations and the fit's linearisation read and fill folder

Outside such a block nothing is cached (the default). The active caches are held in a
:class:`contextvars.ContextVar`: scoped to the block (restored on exit, also on an exception),
nothing is set on import, and other threads and contexts do not see them. The command line
activates one for the duration of each command (``--cache-dir``, ``$DIFFGUIDE_CACHE_DIR``;
none with ``--no-cache``).
"""

import contextvars
import dataclasses
import os
from pathlib import Path

_ACTIVE: contextvars.ContextVar["Caches | None"] = contextvars.ContextVar(
    "diffguide_caches", default=None
)


class CacheWarning(RuntimeWarning):
    """A cache entry was damaged and has been rebuilt, or a cache folder cannot be written to
    (the run goes on uncached): never a failure of the run (:mod:`diffguide._core.cacheentry`)."""


def _table_counters() -> dict[str, int]:
    return {"hits": 0, "misses": 0, "writes": 0, "damaged": 0}


def _export_counters() -> dict[str, int]:
    return {"hits": 0, "exports": 0, "fallbacks": 0, "calls": 0, "damaged": 0}


@dataclasses.dataclass(eq=False)
class Caches:
    """Where the caches of a run live, and what they did.

    Attributes:
        tables: folder of condensed tables (``<key>.npz``), created when first written;
            ``None``: tables are not cached.
        exports: folder of stored programs (``<key>.jaxexport``, ``<key>.out``); ``None``:
            programs are traced in every process.
        table_stats: lookups of tables while active: ``hits``, ``misses``, ``writes``,
            ``damaged`` (files that failed their checks, reported and rebuilt).
        export_stats: calls of stored programs while active: ``hits`` (read from disk),
            ``exports`` (traced and written), ``fallbacks`` (the function called directly),
            ``calls``, ``damaged`` (files that failed their checks, or a stored program that
            failed to load or run: reported and rebuilt).
        unwritable: the folders found unwritable while active (each reported once).
    """

    tables: Path | None = None
    exports: Path | None = None
    table_stats: dict[str, int] = dataclasses.field(default_factory=_table_counters)
    export_stats: dict[str, int] = dataclasses.field(default_factory=_export_counters)
    unwritable: set = dataclasses.field(default_factory=set)
    _tokens: list = dataclasses.field(default_factory=list, repr=False)

    def __post_init__(self):
        for name in ("tables", "exports"):
            value = getattr(self, name)
            if value is not None:
                if not isinstance(value, (str, os.PathLike)):
                    raise TypeError(f"{name} must be a folder path or None, got {value!r}")
                setattr(self, name, Path(value).expanduser())

    def __enter__(self) -> "Caches":
        self._tokens.append(_ACTIVE.set(self))
        return self

    def __exit__(self, *exc) -> None:
        _ACTIVE.reset(self._tokens.pop())


def active_caches() -> Caches | None:
    """The caches activated by the innermost enclosing ``with Caches(...)``, or ``None``."""
    return _ACTIVE.get()
