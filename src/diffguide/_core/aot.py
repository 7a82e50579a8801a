"""Traced programs stored on disk (``jax.export``): a second process skips the tracing.

JAX's persistent compilation cache skips XLA's compilation on a second run, but not JAX's own
tracing and lowering, which for the fit's linearisation (a ``jacfwd`` through the implicit
equilibrium, vmapped over the positions) costs seconds. :class:`cached_program` wraps a function
of pytrees (equinox modules, arrays, static fields) so that, called within
``with Caches(exports=folder):`` (:class:`diffguide._core.caches.Caches`; the command line
activates ``<cache dir>/exports`` for each command):

- **key**: SHA-256 of the function's name, the structure of its arguments (the pytree
  definition with every static field and non-array leaf, by ``repr``), every array argument's
  shape, dtype and weak type, and everything else that changes the program: the source of every
  module of the ``diffguide`` package, the diffguide, JAX and jaxlib versions, the backend, the
  float width, equinox's ``EQX_ON_ERROR`` and :data:`FORMAT`. Arguments whose ``repr`` holds a
  memory address (``" at 0x"``) are not cached (the key would differ in every process).
- **files**: ``<key>.jaxexport`` — the serialised :class:`jax.export.Exported` (StableHLO) of
  the function of the flattened array arguments — and ``<key>.out`` — the output's structure
  (a pickle of the output with every array replaced by a marker), each behind a header
  (:mod:`diffguide._core.cacheentry`: the key, :data:`FORMAT`, the diffguide, JAX and jaxlib
  versions, what the key was made from, the payload's SHA-256; the ``.out`` names its program's
  SHA-256 too). Both are written to a temporary file and renamed into place. A process that
  finds them checks them, deserialises the program and calls it: XLA compiles it (or loads it
  from the persistent compilation cache); nothing is traced. The first process exports (traces
  once) and calls the exported program too, so that the function is traced only once there as
  well, and a run from the cache gives the same bits as the run that filled it.
- **robust**: a file that fails its checks, a program that cannot be deserialised, does not
  match the call's arguments, or fails when it is compiled or run the first time, is reported
  (one :class:`~diffguide._core.caches.CacheWarning`), removed with its partner and exported
  again — never passed on as a failure of the model. A program that cannot be exported (e.g.
  one holding host callbacks: equinox's checks with ``EQX_ON_ERROR=raise``) and any call from
  inside another trace fall back to calling the function itself; every fallback is counted in
  the active caches' ``export_stats``. A folder that cannot be written to is reported once; the
  exported program is then used in this process only.

Without active caches or their ``exports`` folder (the library's default), or without the
``flatbuffers`` package (which ``jax.export`` needs to serialise), the wrapper calls the
function unchanged. The
results of the stored program are those of the function (same StableHLO; compared in
``tests/test_aot.py``). As with JAX's compilation cache, the folder holds code that is run: it
must be the user's own.
"""

import functools
import hashlib
import importlib.util
import pickle
from collections.abc import Callable
from pathlib import Path

import equinox as eqx
import jax

from . import cacheentry
from .cachedir import touch
from .caches import Caches, active_caches
from .compat import cpu_lapack_ready, eqx_on_error
from .fingerprint import code_fingerprint

#: Bumped when the file layout changes.
FORMAT = 2
_PROGRAM, _OUTPUT = "diffguide._core.aot.program", "diffguide._core.aot.output"
_code_hash: str | None = None  # the source hash, computed once per process


@functools.cache
def _can_serialise() -> bool:
    """``jax.export`` serialises with the ``flatbuffers`` package (jax does not require it)."""
    return importlib.util.find_spec("flatbuffers") is not None


def export_dir(caches: Caches | None = None) -> Path | None:
    """The folder of stored programs of ``caches`` (default: the active ones), or ``None``
    (none, or no ``flatbuffers`` to serialise with)."""
    caches = active_caches() if caches is None else caches
    if caches is None or caches.exports is None or not _can_serialise():
        return None
    return caches.exports


def _code_version() -> str:
    """Hash of the package source and the versions that change a traced program."""
    global _code_hash
    if _code_hash is None:
        _code_hash = code_fingerprint(FORMAT, Path(__file__).resolve().parents[1], "**/*.py")
    return _code_hash


def _environment() -> str:
    return "|".join(
        (
            _code_version(),
            jax.default_backend(),
            str(jax.config.read("jax_enable_x64")),
            eqx_on_error(),
        )
    )


def _parts(args: tuple):
    """``(array leaves, their treedef, static leaves, static treedef)`` of ``args``."""
    dyn, static = eqx.partition(args, eqx.is_array)
    leaves, treedef = jax.tree_util.tree_flatten(dyn)
    s_leaves, s_treedef = jax.tree_util.tree_flatten(static)
    return leaves, treedef, s_leaves, s_treedef


def program_key(name: str, args: tuple, parts=None) -> str | None:
    """SHA-256 (hex) of a call ``name(*args)`` (see the module docstring); ``None`` when it
    cannot be cached (a traced argument, or a static part whose ``repr`` holds an address)."""
    leaves, treedef, s_leaves, s_treedef = _parts(args) if parts is None else parts
    if any(isinstance(leaf, jax.core.Tracer) for leaf in leaves):
        return None
    text = f"{name}|{_environment()}|{treedef}|{s_treedef}|{s_leaves!r}"
    if " at 0x" in text:
        return None
    h = hashlib.sha256(text.encode())
    for leaf in leaves:
        weak = bool(getattr(leaf, "weak_type", False))
        h.update(f"{leaf.dtype.str}{tuple(leaf.shape)}{weak};".encode())
    return h.hexdigest()


class _Array:
    """Marks where an output array goes in the stored output structure."""


class cached_program:
    """``fn`` (a function of pytrees returning a pytree of arrays and static data), stored and
    reloaded as an exported program within active caches with an ``exports`` folder (module
    docstring).

    Arguments:
        fn: the function (typically already ``eqx.filter_jit``-ed: it is what runs without a
            folder and inside other traces).
        name: a stable name for the keys (e.g. ``"inverse.fit._linearise"``).
        compiler_options: XLA options for compiling the stored program (e.g.
            ``{"xla_backend_optimization_level": 0}`` for a program that runs once per process,
            where compiling at the default level costs more than it saves); ``None``: defaults.
    """

    def __init__(self, fn: Callable, name: str, compiler_options: dict | None = None):
        functools.update_wrapper(self, fn, updated=())
        self.fn = fn
        self.name = name
        self.compiler_options = dict(compiler_options or {})
        self._programs: dict[tuple[Path, str], tuple[Callable, object] | None] = {}
        self._keys: dict = {}  # in-process: hashable call signature -> key

    def __call__(self, *args):
        caches = active_caches()
        folder = export_dir(caches)
        if folder is None:
            return self.fn(*args)
        stats = caches.export_stats
        stats["calls"] += 1
        parts = _parts(args)
        leaves = parts[0]
        if any(isinstance(leaf, jax.core.Tracer) for leaf in leaves):
            stats["fallbacks"] += 1
            return self.fn(*args)
        try:  # the string key (repr of every static field) costs ms: once per signature
            sig = (
                folder,
                parts[1],
                parts[3],
                tuple(parts[2]),
                tuple((v.shape, v.dtype, bool(getattr(v, "weak_type", False))) for v in leaves),
            )
            key = self._keys.get(sig) or self._keys.setdefault(
                sig, program_key(self.name, args, parts)
            )
        except TypeError:  # an unhashable static leaf
            key = program_key(self.name, args, parts)
        if key is None:
            stats["fallbacks"] += 1
            return self.fn(*args)
        if (folder, key) in self._programs:
            prog = self._programs[folder, key]
        else:
            prog = self._load(folder, key, leaves, caches) or self._export(
                folder, key, args, caches
            )
            self._programs[folder, key] = prog  # None: cannot be exported, do not try again
        if prog is None:
            stats["fallbacks"] += 1
            return self.fn(*args)
        call, template, from_disk = prog
        if from_disk:  # its first call compiles it: a damaged program may fail only now
            try:
                out = jax.block_until_ready(call(*leaves))
            except Exception as exc:
                cacheentry.heal(stats, self._paths(folder, key)[0], exc)
                cacheentry.discard(self._paths(folder, key)[1])
                prog = self._programs[folder, key] = self._export(folder, key, args, caches)
                if prog is None:
                    stats["fallbacks"] += 1
                    return self.fn(*args)
                call, template, _ = prog
                out = call(*leaves)
            else:
                self._programs[folder, key] = (call, template, False)
        else:
            out = call(*leaves)
        out = iter(out)
        t_leaves, t_def = jax.tree_util.tree_flatten(template)
        return jax.tree_util.tree_unflatten(
            t_def, [next(out) if isinstance(v, _Array) else v for v in t_leaves]
        )

    def _jit(self, exported):
        if self.compiler_options:
            return jax.jit(exported.call, compiler_options=self.compiler_options)
        return jax.jit(exported.call)

    @staticmethod
    def _paths(folder: Path, key: str) -> tuple[Path, Path]:
        return folder / f"{key}.jaxexport", folder / f"{key}.out"

    def _load(self, folder: Path, key: str, leaves: list, caches: Caches):
        """``(program, output structure, True)`` read from ``folder``, or ``None``: no files
        (a miss), or damaged ones (reported and removed)."""
        if not cpu_lapack_ready():
            return None
        paths = self._paths(folder, key)
        stats = caches.export_stats
        which = 0
        try:
            prog = cacheentry.read(paths[0], _PROGRAM, key, FORMAT)
            which = 1
            out = cacheentry.read(paths[1], _OUTPUT, key, FORMAT)
            if prog is None or out is None:  # a miss (a lone partner is overwritten)
                return None
            if out[0].get("inputs.program_sha256") != prog[0]["sha256"]:
                raise cacheentry.Damaged("written with another program file")
            which = 0
            exported = jax.export.deserialize(bytearray(prog[1]))
            which = 1
            template = pickle.loads(out[1])
            _check_signature(exported, template, leaves)
        except Exception as exc:  # failed a check, cannot be deserialised or unpickled
            cacheentry.heal(stats, paths[which], exc)
            cacheentry.discard(paths[1 - which])
            return None
        stats["hits"] += 1
        touch(paths[0])  # used now: the cache's size limit removes the least recently used
        touch(paths[1])
        return self._jit(exported), template, True

    def _export(self, folder: Path, key: str, args: tuple, caches: Caches):
        """``(program, output structure, False)``: ``fn`` exported, and written to ``folder``
        where it can be; ``None`` where it cannot be exported."""
        dyn, static = eqx.partition(args, eqx.is_array)
        leaves, treedef = jax.tree_util.tree_flatten(dyn)
        box = {}

        def flat(*xs):
            out = self.fn(*eqx.combine(jax.tree_util.tree_unflatten(treedef, xs), static))
            box["template"] = jax.tree_util.tree_map(
                lambda v: _Array() if eqx.is_array(v) else v, out
            )
            return [v for v in jax.tree_util.tree_leaves(out) if eqx.is_array(v)]

        specs = [
            jax.ShapeDtypeStruct(v.shape, v.dtype, weak_type=bool(getattr(v, "weak_type", False)))
            for v in leaves
        ]
        try:
            exported = jax.export.export(jax.jit(flat))(*specs)
            blob = bytes(exported.serialize())
            template = pickle.dumps(box["template"])
        except Exception:  # e.g. host callbacks (EQX_ON_ERROR=raise) or an unpicklable output
            return None
        inputs = {
            "name": self.name,
            "environment": _environment(),
            "arguments": [f"{s.dtype}{list(s.shape)}{'w' if s.weak_type else ''}" for s in specs],
            "structure": str(treedef),
        }
        prog_path, out_path = self._paths(folder, key)
        prog_file = cacheentry.encode(_PROGRAM, key, FORMAT, blob, inputs)
        inputs["program_sha256"] = hashlib.sha256(blob).hexdigest()
        out_file = cacheentry.encode(_OUTPUT, key, FORMAT, template, inputs)
        # the structure first: a reader finds the program only once both are there
        if cacheentry.write(caches, out_path, out_file):
            cacheentry.write(caches, prog_path, prog_file)
        stats = caches.export_stats
        stats["exports"] += 1
        return self._jit(exported), box["template"], False


def _check_signature(exported, template, leaves: list) -> None:
    """:class:`~diffguide._core.cacheentry.Damaged` unless the stored program takes arrays
    of the call's shapes and dtypes and returns as many as its output structure holds."""
    given = [(tuple(v.shape), v.dtype) for v in leaves]
    takes = [(tuple(a.shape), a.dtype) for a in exported.in_avals]
    if given != takes:
        raise cacheentry.Damaged("the stored program takes other arguments")
    markers = sum(isinstance(v, _Array) for v in jax.tree_util.tree_leaves(template))
    if markers != len(exported.out_avals):
        raise cacheentry.Damaged("the stored output structure does not fit the program")


def cached(name: str, compiler_options: dict | None = None) -> Callable[[Callable], cached_program]:
    """Decorator form of :class:`cached_program`: ``@cached("inverse.fit._linearise")``."""
    return lambda fn: cached_program(fn, name, compiler_options)
