"""The private JAX and equinox names diffguide relies on (``diffguide._core.compat``) are still
there and still mean what they meant. A failure here after an upgrade names the symbol and what
it serves: the code falls back safely (slower or without a cache), but the loss must be seen."""

import importlib
import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import pytest

from diffguide._core import compat


def _what(module, name):
    return next(w for m, n, w in compat.PRIVATE if (m, n) == (module, name))


@pytest.mark.parametrize("module, name, what", compat.PRIVATE, ids=lambda v: str(v)[:40])
def test_private_symbol_exists(module, name, what):
    try:
        mod = importlib.import_module(module)
    except ImportError as exc:  # pragma: no cover - an upgrade removed it
        pytest.fail(f"private module {module} is gone ({exc}); diffguide used it for: {what}")
    obj = mod
    for part in name.split("."):
        assert hasattr(obj, part), (
            f"private symbol {module}.{name} is gone; diffguide used it for: {what} "
            "(update diffguide._core.compat)"
        )
        obj = getattr(obj, part)


def test_trace_state_clean_tells_traces_apart():
    what = _what("jax._src.core", "trace_state_clean")
    seen = []

    def f(x):
        seen.append(compat.outside_traces())
        return x

    assert compat.outside_traces(), f"outside any trace it must be True ({what})"
    jax.jit(f)(1.0)
    jax.grad(f)(1.0)
    assert seen == [False, False], f"inside jit/grad it must be False, got {seen} ({what})"


def test_backends_initialized_is_known_after_the_first_array():
    jnp.zeros(1).block_until_ready()
    assert compat.backends_initialized() is True, _what(
        "jax._src.xla_bridge", "backends_are_initialized"
    )


def test_backends_initialized_is_false_in_a_fresh_process():
    code = (
        "import jax\nfrom diffguide._core import compat\n"
        "print(compat.backends_initialized())\njax.numpy.zeros(1)\n"
        "print(compat.backends_initialized())\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["False", "True"], (
        out.stdout,
        _what("jax._src.xla_bridge", "backends_are_initialized"),
    )


def test_cpu_lapack_kernels_can_be_initialised():
    assert compat.cpu_lapack_ready(), (
        "jax._src.lib.lapack._lapack.initialize() failed: "
        + _what("jax._src.lib", "lapack._lapack.initialize")
    )


def test_eqx_on_error_is_what_equinox_read_from_the_environment():
    code = "from diffguide._core import compat\nprint(compat.eqx_on_error())\n"
    for value in ("nan", "raise"):
        env = dict(os.environ, EQX_ON_ERROR=value)
        out = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, env=env
        )
        assert out.returncode == 0, out.stderr[-2000:]
        assert out.stdout.strip() == value, _what("equinox._config", "EQX_ON_ERROR")
