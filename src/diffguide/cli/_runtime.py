"""The command line's run-time set-up, before JAX starts: equinox's error mode, XLA's CPU
flags, the persistent compilation cache (``--cache-dir``, ``--no-cache``) with its size limit,
float64. Nothing here imports JAX until :func:`prepare_runtime` runs.
"""

import math
import os
import sys
import warnings
from pathlib import Path

DEFAULT_CACHE_DIR = Path("~/.cache/diffguide/jax")
#: the cache folder's size limit (MB; ``$DIFFGUIDE_CACHE_MAX_MB`` overrides it): beyond it the
#: least recently used entries are removed when a command starts (:mod:`diffguide._core.cachedir`)
DEFAULT_CACHE_MAX_MB = 1024.0
#: condensed tables (:mod:`diffguide.fe.cache`) live in this sub-folder of the cache folder
TABLE_SUBDIR = "tables"
#: exported (traced) programs (:mod:`diffguide._core.aot`) live in this sub-folder
EXPORT_SUBDIR = "exports"
#: XLA's CPU compiler settings for a command-line run, by the jaxlib versions they were measured
#: on (XLA aborts on a flag it does not know, so never for other versions): XLA's classic loop
#: emitters instead of the fusion emitters (a first run compiles faster, results equal to
#: ~1e-12; bench/bench_cli.py compares first runs). (``--xla_cpu_use_thunk_runtime=
#: false`` is ignored by jaxlib 0.9.2, which only logs that it is no longer supported.) A user's
#: own ``XLA_FLAGS`` are kept and win.
XLA_CPU_FLAGS = {
    "0.9.2": ("--xla_cpu_use_fusion_emitters=false",),
}


def cache_dir(args) -> Path | None:
    """The compilation cache folder chosen by ``--cache-dir``, ``$DIFFGUIDE_CACHE_DIR`` or the
    default; ``None`` with ``--no-cache`` (or ``DIFFGUIDE_CACHE_DIR=""``)."""
    if getattr(args, "no_cache", False):
        return None
    text = getattr(args, "cache_dir", None)
    if text is None:
        text = os.environ.get("DIFFGUIDE_CACHE_DIR", str(DEFAULT_CACHE_DIR))
    if not text:
        return None
    return Path(text).expanduser()


def prepare_runtime(args):
    """Set up JAX for a command-line run, before it is imported; returns the command's caches.

    - ``EQX_ON_ERROR=nan`` unless the user set it: equinox's default error checks are host
      callbacks, which JAX refuses to store in the persistent cache, so without it a second run
      recompiles everything. The consequence: a check that fails inside compiled code gives NaN
      instead of an exception, and the solvers report NaN as non-convergence (exit 3).
    - the persistent compilation cache (:func:`cache_dir`; every compilation is stored), when
      this process starts JAX itself or the user named a folder explicitly.
    - float64 (micrometres on metre-scale geometry need it).

    Returns:
        with that folder, a :class:`~diffguide._core.caches.Caches` for the condensed tables in
        its sub-folder :data:`TABLE_SUBDIR` (:mod:`diffguide.fe.cache`) and the exported
        programs in :data:`EXPORT_SUBDIR` (:mod:`diffguide._core.aot`: a second run skips
        tracing the fit's linearisation and the sweep), for the caller to activate while the
        command runs (``with caches:``); else ``None`` (nothing is cached: ``--no-cache``).
    """
    if "equinox" not in sys.modules:
        os.environ.setdefault("EQX_ON_ERROR", "nan")
    jax_was_loaded = "jax" in sys.modules
    if not jax_was_loaded:
        _set_xla_cpu_flags()
    folder = cache_dir(args)
    if folder is not None and not jax_was_loaded:
        # XLA logs a line for every executable read from the cache: a warning ("Assume version
        # compatibility"), and on CPUs whose compiler tuning flags (+prefer-no-gather,
        # +prefer-no-scatter: tuning, not instructions) are not among the host's detected
        # features, two error lines per executable that "this could lead to SIGILL" (XLA's
        # cpu_aot_loader; openxla/xla issue 44565): a second `diffguide fit` printed 18 of
        # them. Python's errors and warnings are not affected (XLA's C++ log only).
        os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
    import jax

    _one_line_cache_warnings(folder)
    caches = None
    if folder is not None and (not jax_was_loaded or getattr(args, "cache_dir", None)):
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            warnings.warn(f"compilation cache disabled: {exc}", stacklevel=2)
        else:
            jax.config.update("jax_compilation_cache_dir", str(folder))
            # every compilation, not only those over JAX's default 1 s: a run compiles dozens
            # of small functions whose compilations add up to seconds
            jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
            jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
            from .._core.cachedir import prune
            from .._core.caches import Caches
            from .._core.jaxentries import check as check_jax_entries

            check_jax_entries(folder)  # swapped entries, a folder in an entry's place

            caches = Caches(tables=folder / TABLE_SUBDIR, exports=folder / EXPORT_SUBDIR)
            prune(folder, cache_max_bytes())
    from .._core.precision import enable_x64

    enable_x64()
    return caches


#: how JAX (0.9) begins the warning for a compilation-cache entry it cannot read
_JAX_READ_ERROR = "Error reading persistent compilation cache entry for '"


def _one_line_cache_warnings(folder: Path | None) -> None:
    """Print each :class:`~diffguide._core.caches.CacheWarning` (a damaged cache entry that was
    rebuilt, a cache folder that cannot be written) as one line on stderr, ``diffguide: ...``,
    without the source line Python's default format adds; and where JAX warns that it cannot
    read one of its compilation-cache entries in ``folder``, remove the damaged entry
    (:func:`diffguide._core.cachedir.drop_jax_entries`), so that the fresh compilation is
    stored in its place, and say so in one line. Other warnings are left as they are."""
    from .._core.caches import CacheWarning

    shown = getattr(warnings.showwarning, "diffguide_shown", warnings.showwarning)

    def show(message, category, filename, lineno, file=None, line=None):
        out = sys.stderr if file is None else file
        text = str(message)
        if issubclass(category, CacheWarning):
            print(f"diffguide: {text}", file=out)
        elif folder is not None and text.startswith(_JAX_READ_ERROR):
            from .._core.cachedir import drop_jax_entries

            name = text[len(_JAX_READ_ERROR):].split("'", 1)[0]
            for path, why in drop_jax_entries(folder, name) or [(name, text)]:
                why = why if len(why) <= 200 else why[:197] + "..."
                print(f"diffguide: JAX compilation cache entry {path} was damaged ({why}); "
                      "compiled again", file=out)
        else:
            shown(message, category, filename, lineno, file, line)

    show.diffguide_shown = shown
    warnings.showwarning = show


def cache_max_bytes() -> int:
    """The cache folder's size limit in bytes: ``$DIFFGUIDE_CACHE_MAX_MB`` (MB, > 0), else
    :data:`DEFAULT_CACHE_MAX_MB`; ``ValueError`` naming the variable for anything else."""
    text = os.environ.get("DIFFGUIDE_CACHE_MAX_MB", "").strip()
    if not text:
        return int(DEFAULT_CACHE_MAX_MB * 2**20)
    try:
        mb = float(text)
    except ValueError:
        mb = float("nan")
    if not (math.isfinite(mb) and mb > 0):
        raise ValueError(f"DIFFGUIDE_CACHE_MAX_MB must be a size in MB > 0, got {text!r}")
    return int(mb * 2**20)


def _set_xla_cpu_flags() -> None:
    """Add :data:`XLA_CPU_FLAGS` for the installed jaxlib to ``XLA_FLAGS`` (before JAX starts);
    a flag the user set already is left as they set it."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        flags = XLA_CPU_FLAGS.get(version("jaxlib"), ())
    except PackageNotFoundError:
        return
    given = os.environ.get("XLA_FLAGS", "")
    named = {f.split("=", 1)[0] for f in given.split()}
    extra = [f for f in flags if f.split("=", 1)[0] not in named]
    if extra:
        os.environ["XLA_FLAGS"] = " ".join([given, *extra]).strip()

