"""Caches that heal: every kind of damage to a cache file — truncation, flipped bits, appended
garbage, a foreign file under the entry's name, a folder or a dangling link in its place, a stale
or mismatched header — is reported (one ``CacheWarning``), the entry rebuilt, and the run gives
results bitwise equal to a clean run; a folder that cannot be written is reported once and the run
goes on uncached. For the three artefacts of ours (``tables/*.npz``, ``exports/*.jaxexport``,
``exports/*.out``) at the library level, and once end to end through ``diffguide fit`` (the
audit's case: four bytes flipped in the stored program, with JAX's own compilation-cache
entries damaged too)."""

import os
import pickle
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide._core import aot, cacheentry
from diffguide._core.caches import Caches, CacheWarning
from diffguide.machine.majda2012 import majda2012_table

pytest.importorskip("flatbuffers")  # jax.export's serialisation (without it: no export dir)
ROOT = Path(__file__).resolve().parents[1]
FIELDS = ("K", "f", "R", "r0", "node_modes", "node_u0", "ref_points", "nodes")


# ---- the two cached computations, run as a fresh process would (no in-memory state) ----------


def _tables():
    """Two small tables (two keys: one is the other's foreign content)."""
    return majda2012_table(4, 2), majda2012_table(4, 2, thickness=0.041)


def _run_tables(folder: Path) -> list[np.ndarray]:
    out = []
    for tm in _tables():
        table = tm.condense()
        out += [np.asarray(getattr(table, k)) for k in FIELDS]
    return out


def _model(k, x):
    e = jnp.sum(k[:, None] * jnp.abs(x[None, :] - 0.1) ** 3, axis=0)
    return {"energy": e, "force": jax.grad(lambda y: jnp.sum(k * y**2))(x[: k.shape[0]])}


def _run_programs(folder: Path) -> list[np.ndarray]:
    """Two calls of a freshly wrapped program (two keys: other shapes)."""
    prog = aot.cached_program(eqx.filter_jit(_model), "test.cache_damage")
    out = []
    for n in (5, 7):
        r = prog(jnp.arange(1.0, 3.0), jnp.linspace(-1.0, 1.0, n))
        out += [np.asarray(r["energy"]), np.asarray(r["force"])]
    return out


ARTEFACTS = {  # name -> (sub-folder, file pattern, run, the Caches' stats of it)
    "npz": ("tables", "*.npz", _run_tables, "table_stats"),
    "jaxexport": ("exports", "*.jaxexport", _run_programs, "export_stats"),
    "out": ("exports", "*.out", _run_programs, "export_stats"),
}


def _run(kind: str, folder: Path):
    sub, _, run, stats = ARTEFACTS[kind]
    with Caches(**{"tables" if sub == "tables" else "exports": folder / sub}) as caches:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            results = run(folder)
    said = [str(w.message) for w in caught if issubclass(w.category, CacheWarning)]
    return results, getattr(caches, stats), said


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """Per artefact kind: a cache folder filled by a clean run, and that run's results."""
    out = {}
    for kind in ("npz", "jaxexport"):
        folder = tmp_path_factory.mktemp(f"clean_{kind}")
        results, stats, said = _run(kind, folder)
        assert not said and stats.get("damaged", 0) == 0
        again, stats, said = _run(kind, folder)  # a second clean run reads every entry
        assert stats["hits"] == 2 and not said
        _same(again, results)
        out[kind] = (folder, results)
    out["out"] = out["jaxexport"]
    return out


def _same(a, b):
    assert len(a) == len(b)
    for u, v in zip(a, b):
        assert u.dtype == v.dtype and u.shape == v.shape
        assert u.tobytes() == v.tobytes()  # bitwise


# ---- the kinds of damage: each takes (the entry, another entry of the same kind) -------------


def _flip(path, where, n=1):
    b = bytearray(path.read_bytes())
    i = {"start": 0, "middle": len(b) // 2, "end": len(b) - n}[where]
    for j in range(i, i + n):
        b[j] ^= 0xFF
    path.write_bytes(bytes(b))


def _reheader(path, **changes):
    """A well-formed file with a valid checksum whose header says something else."""
    data = path.read_bytes()
    end = data.index(b"\n\n") + 1
    lines = data[len(cacheentry.MAGIC):end].decode().splitlines()
    header = dict(line.split(": ", 1) for line in lines)
    header.update({name: str(value) for name, value in changes.items()})
    text = "".join(f"{name}: {value}\n" for name, value in header.items())
    path.write_bytes(cacheentry.MAGIC + text.encode() + data[end:])


def _payload_of(path):
    data = path.read_bytes()
    return data[data.index(b"\n\n") + 2:]


def _swap_payload(path, other):
    """Another entry's (valid) payload behind this entry's header: the checksum no longer fits."""
    data = path.read_bytes()
    end = data.index(b"\n\n") + 2
    payload = _payload_of(other)
    if payload == data[end:]:  # the output structures of both programs: another pickle
        payload = pickle.dumps({"energy": None, "force": None})
    path.write_bytes(data[:end] + payload)


def _dangling(path):
    path.symlink_to(path.parent / "gone")


def _replace(path, make):
    path.unlink()
    make(path)


DAMAGE = {
    "truncated to 0": lambda p, o: p.write_bytes(b""),
    "truncated to half": lambda p, o: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]),
    "one byte short": lambda p, o: p.write_bytes(p.read_bytes()[:-1]),
    "bit flip at start": lambda p, o: _flip(p, "start"),
    "bit flip in middle": lambda p, o: _flip(p, "middle"),
    "bit flip at end": lambda p, o: _flip(p, "end"),
    "4 bytes flipped": lambda p, o: _flip(p, "middle", 4),
    "garbage appended": lambda p, o: p.write_bytes(p.read_bytes() + os.urandom(64)),
    "another entry's file": lambda p, o: shutil.copyfile(o, p),
    "random bytes": lambda p, o: p.write_bytes(np.random.default_rng(0).bytes(4096)),
    "a text file": lambda p, o: p.write_text("these are my notes\n"),
    "a pickle of the wrong structure": lambda p, o: p.write_bytes(pickle.dumps((1, 2, 3))),
    "the bare payload (no header)": lambda p, o: p.write_bytes(_payload_of(p)),
    "a folder in its place": lambda p, o: _replace(p, lambda q: (q.mkdir(), (q / "x").touch())),
    "a dangling link in its place": lambda p, o: _replace(p, _dangling),
    "stale jax version in the header": lambda p, o: _reheader(p, jax="0.4.1"),
    "stale diffguide version in the header": lambda p, o: _reheader(p, diffguide="0.0.1"),
    "old file format in the header": lambda p, o: _reheader(p, format=1),
    "another key in the header": lambda p, o: _reheader(p, key="0" * 64),
    "header cut mid-way": lambda p, o: p.write_bytes(p.read_bytes()[: len(cacheentry.MAGIC) + 20]),
    "checksum mismatch, valid-looking payload": lambda p, o: _swap_payload(p, o),
    "stated length wrong": lambda p, o: _reheader(p, bytes=1),
}


@pytest.mark.parametrize("damage", list(DAMAGE))
@pytest.mark.parametrize("kind", list(ARTEFACTS))
def test_damaged_entry_is_reported_rebuilt_and_results_identical(kind, damage, clean, tmp_path):
    source, expected = clean[kind]
    folder = tmp_path / "cache"
    shutil.copytree(source, folder, symlinks=True)
    sub, pattern = ARTEFACTS[kind][:2]
    entry, other = sorted((folder / sub).glob(pattern))
    DAMAGE[damage](entry, other)

    results, stats, said = _run(kind, folder)
    _same(results, expected)
    assert stats["damaged"] == 1, stats
    assert len(said) == 1 and entry.name in said[0] and "rebuilt" in said[0], said
    assert entry.is_file() and not entry.is_symlink()  # rewritten, and whole again
    again, stats, said = _run(kind, folder)  # the next run reads it: no damage left
    _same(again, expected)
    assert stats["damaged"] == 0 and stats["hits"] == 2 and not said


def test_stored_program_failing_when_run_is_rebuilt(clean, tmp_path, monkeypatch):
    """A program that passes every check but fails when compiled or run (as the audit's flipped
    bytes did before the checksum) is reported and exported again, not passed on as a model
    failure."""
    source, expected = clean["jaxexport"]
    folder = tmp_path / "cache"
    shutil.copytree(source, folder)
    load = aot.cached_program._load

    def broken(self, *a):
        prog = load(self, *a)

        def fail(*xs):
            raise RuntimeError("failed to deserialize portable artifact")

        return None if prog is None else (fail, *prog[1:])

    monkeypatch.setattr(aot.cached_program, "_load", broken)
    results, stats, said = _run("jaxexport", folder)
    _same(results, expected)
    assert stats["damaged"] == 2 and stats["exports"] == 2 and len(said) == 2
    assert all("failed to deserialize" in s for s in said)


@pytest.mark.parametrize("kind", ["npz", "jaxexport"])
def test_unwritable_cache_folder_runs_uncached_and_says_so_once(kind, clean, tmp_path):
    """A cache folder that cannot be written (here a file where the folder should be: the tests
    run as root, where permissions do not stop a write) gives the clean results, one line."""
    sub = ARTEFACTS[kind][0]
    folder = tmp_path / "cache"
    folder.mkdir()
    (folder / sub).write_text("not a folder")
    results, stats, said = _run(kind, folder)
    _same(results, clean[kind][1])
    assert len(said) == 1 and "cannot be written" in said[0] and "uncached" in said[0], said
    assert stats["hits"] == 0


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root reads any file")
@pytest.mark.parametrize("kind", list(ARTEFACTS))
def test_unreadable_entry_is_rebuilt(kind, clean, tmp_path):
    source, expected = clean[kind]
    folder = tmp_path / "cache"
    shutil.copytree(source, folder)
    sub, pattern = ARTEFACTS[kind][:2]
    entry = sorted((folder / sub).glob(pattern))[0]
    entry.chmod(0)
    results, stats, said = _run(kind, folder)
    _same(results, expected)
    assert stats["damaged"] == 1 and len(said) == 1


def test_cli_fit_heals_the_audits_flipped_program_and_jax_entries(tmp_path):
    """The audit's case end to end: after a first ``diffguide fit``, four bytes flipped in the
    middle of the stored program (``exports/*.jaxexport``) and of every JAX compilation-cache
    entry; the next fit exits 0 with a bitwise identical ``rails.csv``, says what it rebuilt,
    and leaves entries that JAX can read again."""
    from diffguide._core.compat import jax_cache_decompress

    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    cache = tmp_path / "cache"

    def fit(out):
        cmd = [sys.executable, "-c", "import sys; from diffguide.cli import main; "
               "sys.exit(main())", "fit", "--preset", "majda2012",
               "--measurements", str(ROOT / "data" / "majda2012_measurements.csv"),
               "--out", str(out), "--mesh", "8x4", "--no-plots", "-q",
               "--cache-dir", str(cache)]
        return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)

    first = fit(tmp_path / "a")
    assert first.returncode == 0, first.stderr
    jax_entries = sorted(cache.glob("*-cache"))
    (program,) = cache.glob("exports/*.jaxexport")
    for path in [program, *jax_entries]:
        _flip(path, "middle", 4)
    second = fit(tmp_path / "b")
    assert second.returncode == 0, second.stderr
    rails = [(tmp_path / run / "rails.csv").read_bytes() for run in "ab"]
    assert rails[0] == rails[1]
    assert f"cache entry {program} was damaged (checksum mismatch); rebuilt" in second.stderr
    assert "did not converge" not in second.stderr
    cacheentry.read(program, aot._PROGRAM, program.name.split(".")[0], aot.FORMAT)  # whole again
    for path in sorted(cache.glob("*-cache")):
        jax_cache_decompress(path.read_bytes())
    if jax_entries:
        assert "JAX compilation cache entry" in second.stderr
