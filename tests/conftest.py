import gc
import os
import shutil
import tempfile

# One OpenBLAS thread, set before NumPy loads (as the CLI does): next to JAX's own threads a
# threaded OpenBLAS oversubscribes a small machine and stalls the fits' small dense solves
# (a structure-estimated fit of the bundled data: 37 s -> 0.7 s steady state at load 4).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "standard")


import pytest  # noqa: E402

#: One persistent compilation cache for the whole session: a module's compiled programs are
#: freed after it (below), and the next module that lowers the same program reads XLA's
#: executable back instead of compiling it again. By default a fresh folder per test process
#: (with ``pytest -n``, each worker has its own, so that no process reads an entry another is
#: still writing), removed at the end, so that every run compiles every program once;
#: ``$DIFFGUIDE_TEST_JAX_CACHE`` names one to keep between serial runs. Programs with host
#: callbacks (equinox's checks under ``EQX_ON_ERROR=raise``) are never stored by JAX: those
#: compile as before. The executables are those XLA compiles (JAX keys the cache by the lowered
#: program, the compile options, the backend and the versions).
_KEEP_CACHE = bool(os.environ.get("DIFFGUIDE_TEST_JAX_CACHE"))
_SESSION_CACHE = os.environ.get("DIFFGUIDE_TEST_JAX_CACHE") or tempfile.mkdtemp(
    prefix="diffguide-test-jax-cache-")


def _use_session_cache():
    """Point JAX's persistent compilation cache at the session's folder, storing every program.

    A command line run in-process with ``--cache-dir`` points the cache at a test's folder for
    the rest of the process: this puts it back (and drops the cache object JAX initialised from
    that folder, a private name whose absence is tolerated)."""
    jax.config.update("jax_compilation_cache_dir", _SESSION_CACHE)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    try:
        from jax._src.compilation_cache import reset_cache
    except ImportError:  # pragma: no cover
        return
    reset_cache()


_use_session_cache()


def pytest_sessionfinish(session, exitstatus):
    if not _KEEP_CACHE:
        shutil.rmtree(_SESSION_CACHE, ignore_errors=True)


@pytest.fixture(autouse=True, scope="module")
def _fresh_jax_after_each_module():
    """Free each module's compiled programs; the session's compilation cache stays.

    Every compiled XLA:CPU program holds its own memory mappings, and JAX keeps every program
    it compiled for the life of the process. The whole suite in one process went past Linux's
    limit on mappings per process (``vm.max_map_count``, 65530 by default) and died with SIGSEGV
    inside XLA, twice at 77 % (once compiling, once serialising a program): measured, four
    modules leave ~7 000 mappings behind without this, ~2 800 with it.
    """
    yield
    jax.clear_caches()
    gc.collect()
    _use_session_cache()
