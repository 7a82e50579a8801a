import os

# One OpenBLAS thread, set before NumPy loads (as the CLI does): next to JAX's own threads a
# threaded OpenBLAS oversubscribes a small machine and stalls the fits' small dense solves
# (a structure-estimated fit of the bundled data: 37 s -> 0.7 s steady state at load 4).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "standard")


import pytest  # noqa: E402


@pytest.fixture(autouse=True, scope="module")
def _no_compilation_cache_across_modules():
    """A command line run in-process with ``--cache-dir`` points JAX's persistent compilation
    cache at a test's folder for the rest of the process; forget it after each module, so every
    module starts without a persistent cache (as the suite's first module does). A full run once
    crashed (SIGSEGV) inside XLA's serialisation of a program written to a cache set by an
    earlier module that had damaged cache entries on purpose (test_cache_damage)."""
    yield
    jax.config.update("jax_compilation_cache_dir", None)
    try:  # the cache object JAX initialised from the folder (private: tolerate its absence)
        from jax._src.compilation_cache import reset_cache
    except ImportError:  # pragma: no cover
        return
    reset_cache()
