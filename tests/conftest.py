import gc
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
def _fresh_jax_after_each_module():
    """Free each module's compiled programs, and forget JAX's persistent compilation cache.

    - Every compiled XLA:CPU program holds its own memory mappings, and JAX keeps every program
      it compiled for the life of the process. The whole suite in one process went past
      Linux's limit on mappings per process (``vm.max_map_count``, 65530 by default) and died
      with SIGSEGV inside XLA, twice at 77 % (once compiling, once serialising a program):
      measured, four modules leave ~7 000 mappings behind without this, ~2 800 with it.
    - A command line run in-process with ``--cache-dir`` points JAX's persistent cache at a
      test's folder for the rest of the process; every module starts without one.
    """
    yield
    jax.clear_caches()
    gc.collect()
    jax.config.update("jax_compilation_cache_dir", None)
    try:  # the cache object JAX initialised from the folder (private: tolerate its absence)
        from jax._src.compilation_cache import reset_cache
    except ImportError:  # pragma: no cover
        return
    reset_cache()
