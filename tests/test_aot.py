"""``diffguide._core.aot``: a program exported once is read back and gives the function's results
without tracing it again; a changed argument structure, shape, static field or code misses."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide._core import aot
from diffguide._core.caches import Caches, CacheWarning

pytest.importorskip("flatbuffers")  # jax.export's serialisation (without it: no export dir)
TRACES = {"n": 0}


class Spring(eqx.Module):
    k: jax.Array
    x0: jax.Array
    label: str = eqx.field(static=True)
    power: int = eqx.field(static=True, default=3)


class Out(eqx.Module):
    energy: jax.Array
    force: jax.Array
    label: str = eqx.field(static=True)


def _raw(spring: Spring, x):
    TRACES["n"] += 1  # runs only while tracing

    def energy(y):  # (n,) positions -> (n,) energies of both springs
        d = jnp.abs(y[None, :] - spring.x0[:, None])
        return jnp.sum(spring.k[:, None] * d**spring.power, axis=0)

    e = energy(x)
    f = jax.grad(lambda y: jnp.sum(energy(y)))(x)
    return Out(energy=jnp.sum(e), force=f, label=spring.label), (e, x.shape[0])


_model = eqx.filter_jit(_raw)


@pytest.fixture
def caches(tmp_path):
    with Caches(exports=tmp_path / "exports") as c:
        yield c


@pytest.fixture
def folder(caches):
    return caches.exports


def _spring(label="a", power=3):
    return Spring(jnp.array([2.0, 3.0]), jnp.array([0.1, -0.2]), label, power)


def _check_same(a, b):
    (oa, (ea, na)), (ob, (eb, nb)) = a, b
    assert oa.label == ob.label and na == nb
    for u, v in ((oa.energy, ob.energy), (oa.force, ob.force), (ea, eb)):
        np.testing.assert_array_equal(np.asarray(u), np.asarray(v))


def test_round_trip_identical_and_not_traced_again(caches, folder):
    x = jnp.linspace(-1.0, 1.0, 7)
    ref = _model(_spring(), x)
    stats = caches.export_stats
    assert stats == {"hits": 0, "exports": 0, "fallbacks": 0, "calls": 0, "damaged": 0}
    first = aot.cached_program(_model, "test.model")
    _check_same(first(_spring(), x), ref)
    assert stats["exports"] == 1
    assert len(list(folder.glob("*.jaxexport"))) == 1 and len(list(folder.glob("*.out"))) == 1
    # a new wrapper of a freshly jitted function (a new process): read from disk, not traced
    y = 2.0 * x - 0.3
    expected = _model(_spring(), y)
    traces = TRACES["n"]
    second = aot.cached_program(eqx.filter_jit(_raw), "test.model")
    _check_same(second(_spring(), y), expected)
    assert TRACES["n"] == traces
    assert stats["hits"] == 1
    second(_spring(), x)  # in-process: neither disk nor tracing
    assert stats["hits"] == 1 and TRACES["n"] == traces


def test_changed_keys_miss(folder, monkeypatch):
    x = jnp.linspace(-1.0, 1.0, 7)
    keys = {
        aot.program_key("test.model", (_spring(), x)),
        aot.program_key("test.model", (_spring(), jnp.linspace(-1, 1, 8))),  # shape
        aot.program_key("test.model", (_spring(power=2), x)),  # static field
        aot.program_key("test.model", (_spring(label="b"), x)),  # static string
        aot.program_key("test.other", (_spring(), x)),  # name
        aot.program_key("test.model", (_spring(), x.astype(jnp.float32))),  # dtype
    }
    assert len(keys) == 6
    same = aot.program_key("test.model", (_spring(), 3.0 * x))  # values do not matter
    assert same in keys
    monkeypatch.setattr(aot, "_code_hash", "another source")
    assert aot.program_key("test.model", (_spring(), x)) not in keys
    wrapped = aot.cached_program(_model, "test.model")
    wrapped(_spring(), x)
    wrapped(_spring(power=2), x)
    assert len(list(folder.glob("*.jaxexport"))) == 2


def test_damaged_file_and_traced_or_no_folder_fall_back(caches, folder):
    x = jnp.linspace(-1.0, 1.0, 5)
    aot.cached_program(_model, "test.model")(_spring(), x)
    (path,) = folder.glob("*.jaxexport")
    path.write_bytes(b"not a program")
    with pytest.warns(CacheWarning, match="was damaged"):  # said once, then rebuilt
        got = aot.cached_program(_model, "test.model")(_spring(), x)
    _check_same(got, _model(_spring(), x))
    assert path.read_bytes() != b"not a program"  # exported again
    # inside another trace: the function itself (differentiable)
    wrapped = aot.cached_program(_model, "test.model")
    g = jax.grad(lambda s: wrapped(_spring(), x * s)[0].energy)(1.0)
    assert np.isfinite(float(g))
    assert caches.export_stats["fallbacks"] >= 1
    n = len(list(folder.iterdir()))
    with Caches():  # caches without an exports folder, inside the active ones
        aot.cached_program(_model, "test.model")(_spring(), x + 1.0)
    assert len(list(folder.iterdir())) == n


def test_nothing_is_stored_without_active_caches(tmp_path):
    """The library's default: no caches, nothing written; the caches are scoped to their block
    (also when it ends with an exception)."""
    from diffguide._core.caches import active_caches

    x = jnp.linspace(-1.0, 1.0, 5)
    assert active_caches() is None and aot.export_dir() is None
    c = Caches(exports=tmp_path / "exports")
    with pytest.raises(RuntimeError):
        with c:
            assert active_caches() is c and aot.export_dir() == tmp_path / "exports"
            raise RuntimeError
    assert active_caches() is None
    _check_same(aot.cached_program(_model, "test.model")(_spring(), x), _model(_spring(), x))
    assert not (tmp_path / "exports").exists()
    assert c.export_stats["calls"] == 0


_LAPACK = r"""
import os, sys
os.environ["EQX_ON_ERROR"] = "nan"
import jax, jax.numpy as jnp, equinox as eqx
jax.config.update("jax_enable_x64", True)
from diffguide._core import aot
from diffguide._core.caches import Caches
caches = Caches(exports=sys.argv[1])

@eqx.filter_jit
def f(A, b):
    L = jnp.linalg.cholesky(A @ A.T + 3 * jnp.eye(4))
    return jax.scipy.linalg.cho_solve((L, True), b), jnp.linalg.solve(A + 4 * jnp.eye(4), b)

A = jnp.arange(16.0).reshape(4, 4) / 10
with caches:
    x, y = aot.cached_program(f, "test.lapack")(A, jnp.ones(4))
stats = caches.export_stats
print(stats["hits"], stats["exports"], repr(float(x[0])), repr(float(y[1])))
"""


def test_lapack_program_read_back_in_a_fresh_process(tmp_path):
    """LAPACK custom calls in a program read from disk by a process that never lowered one
    (jaxlib's kernels must be initialised first: without it the process crashed)."""
    import subprocess
    import sys

    def run():
        out = subprocess.run(
            [sys.executable, "-c", _LAPACK, str(tmp_path / "exports")],
            capture_output=True,
            text=True,
        )
        assert out.returncode == 0, out.stderr[-2000:]
        return out.stdout.split()

    first, second = run(), run()
    assert first[:2] == ["0", "1"] and second[:2] == ["1", "0"]
    assert first[2:] == second[2:]
    A = np.arange(16.0).reshape(4, 4) / 10
    assert float(first[2]) == pytest.approx(np.linalg.solve(A @ A.T + 3 * np.eye(4), np.ones(4))[0])
