"""Every private JAX and equinox name diffguide uses, in one place, each with a fallback.

No public API answers these questions, so each is read from a private module. An upgrade may
move or remove one: the function then falls back to a documented, safe behaviour (never an
error), and ``tests/test_compat.py`` fails naming the symbol and what it serves, so that the
loss is noticed rather than silently paid for in speed.

=================================================  ==========================================
private symbol                                     used for (fallback when it is gone)
=================================================  ==========================================
``jax._src.core.trace_state_clean``                :func:`outside_traces` — the table
                                                   condensation compiles with its own XLA
                                                   options only outside other traces
                                                   (``False``: default options)
``jax._src.xla_bridge.backends_are_initialized``   :func:`backends_initialized` — whether
                                                   XLA's flags variable can still take effect
                                                   (``None``: unknown)
``jax._src.lib.lapack._lapack.initialize``         :func:`cpu_lapack_ready` — jaxlib's CPU
                                                   LAPACK kernels loaded before a stored
                                                   program runs (``False``: stored programs
                                                   are not read back)
``equinox._config.EQX_ON_ERROR``                   :func:`eqx_on_error` — part of a stored
                                                   program's key (``$EQX_ON_ERROR``, else
                                                   equinox's default ``"raise"``)
``jax._src.compilation_cache``                     :func:`jax_cache_decompress` — telling a
(``.decompress_executable``)                       damaged entry of JAX's compilation cache
                                                   (zlib, JAX's own fallback)
=================================================  ==========================================
"""

import os

#: ``(module, attribute path, what diffguide uses it for)`` of every private symbol
#: (tests/test_compat.py).
PRIVATE = (
    (
        "jax._src.core",
        "trace_state_clean",
        "whether no JAX transformation is being traced (fe.condense compiles the condensation "
        "with its own XLA options only then)",
    ),
    (
        "jax._src.xla_bridge",
        "backends_are_initialized",
        "whether XLA's flags variable can still take effect (the montecarlo command's CPU devices)",
    ),
    (
        "jax._src.lib",
        "lapack._lapack.initialize",
        "loading jaxlib's CPU LAPACK kernels before a stored program (jax.export) runs: without "
        "it a deserialised program's LAPACK calls crashed the process",
    ),
    (
        "jax._src.compilation_cache",
        "decompress_executable",
        "decompressing an entry of JAX's persistent compilation cache to tell a damaged one "
        "(_core.cachedir.drop_jax_entries)",
    ),
    (
        "equinox._config",
        "EQX_ON_ERROR",
        "equinox's error mode in effect, part of the key of stored programs (_core.aot)",
    ),
)


def outside_traces() -> bool:
    """Whether no JAX transformation is being traced; ``False`` when that cannot be told."""
    try:
        from jax._src.core import trace_state_clean
    except ImportError:  # pragma: no cover - moved: behave as if inside a trace
        return False
    return bool(trace_state_clean())


def backends_initialized() -> bool | None:
    """Whether JAX has initialised its backends (after which XLA's flags variable is ignored);
    ``None`` when that cannot be told."""
    try:
        from jax._src import xla_bridge

        return bool(xla_bridge.backends_are_initialized())
    except (ImportError, AttributeError):  # pragma: no cover - moved
        return None


def cpu_lapack_ready() -> bool:
    """Load jaxlib's CPU LAPACK kernels (their BLAS/LAPACK function pointers). JAX does it
    while lowering a LAPACK operation; a deserialised program is not lowered, and running its
    LAPACK custom calls without it crashed the process (segmentation fault, jax 0.9.2).
    ``True`` on other backends; ``False`` when it cannot be done."""
    import jax

    if jax.default_backend() != "cpu":
        return True
    try:
        from jax._src.lib import lapack

        lapack._lapack.initialize()
    except Exception:  # pragma: no cover - another jaxlib layout: do not risk it
        return False
    return True


def eqx_on_error() -> str:
    """equinox's error mode in this process (``"raise"``, ``"nan"``, ``"breakpoint"``): what
    equinox read from ``$EQX_ON_ERROR`` when it was imported."""
    try:
        from equinox._config import EQX_ON_ERROR
    except ImportError:  # pragma: no cover - moved: what equinox reads, with its default
        return os.environ.get("EQX_ON_ERROR", "raise")
    return str(EQX_ON_ERROR)


def jax_cache_decompress(data: bytes) -> bytes:
    """JAX's own decompression of a compilation-cache entry (zstd or zlib, as JAX chose); zlib,
    JAX's fallback, where the private function is gone. Raises on a damaged entry."""
    try:
        from jax._src.compilation_cache import decompress_executable
    except ImportError:  # pragma: no cover - moved: the zlib JAX falls back to
        import zlib

        return zlib.decompress(data)
    return decompress_executable(data)
