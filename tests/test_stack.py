"""The numerical stack: the version guard, and the fit Jacobian reproduced by fresh processes.

jax/jaxlib 0.10.2 returned a wrong ``jacfwd`` through the hand-written implicit solve in about
one of four fresh compilations on a 2-core CPU (and sometimes deadlocked); 0.9.2 was clean. A
wrong Jacobian is silent, so this test compiles the full fit Jacobian in two fresh processes and
requires them to agree (test_inverse.py compares it with central differences); the second
process compiles with the command line's XLA flags for the installed jaxlib
(``cli._common.XLA_CPU_FLAGS``), so these are held to the same Jacobian.
"""

import json
import os
import pathlib
import subprocess
import sys
import warnings

import numpy as np
import pytest

from diffguide._core import stack
from diffguide.cli._common import XLA_CPU_FLAGS

_JACOBIAN = r"""
import json, sys
import numpy as np
import diffguide
diffguide.enable_x64()
from diffguide import majda2012_machine, read_measurements, fit_rails
meas = read_measurements(sys.argv[1])
m = majda2012_machine(nx=8, ny=4, points=dict(zip(meas.point_names, map(tuple, meas.points_xy))))
fit = fit_rails(m, meas, method="linear", lam=1.0, reject_outliers=False)
np.save(sys.argv[2], np.asarray(fit.jacobian_full))
print(json.dumps(list(np.asarray(fit.jacobian_full).shape)))
"""


def test_fit_jacobian_is_the_same_in_two_fresh_processes(tmp_path):
    data = pathlib.Path(__file__).parents[1] / "data" / "majda2012_measurements.csv"
    from importlib.metadata import version

    cli_flags = " ".join(XLA_CPU_FLAGS.get(version("jaxlib"), ()))
    jacs = []
    for k in range(2):
        out = tmp_path / f"J{k}.npy"
        env = dict(os.environ)
        if k == 1 and cli_flags:
            env["XLA_FLAGS"] = f"{env.get('XLA_FLAGS', '')} {cli_flags}".strip()
        proc = subprocess.run(
            [sys.executable, "-c", _JACOBIAN, str(data), str(out)],
            capture_output=True,
            text=True,
            timeout=900,
            env=env,
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
        shape = json.loads(proc.stdout.strip().splitlines()[-1])
        jacs.append(np.load(out))
        assert list(jacs[-1].shape) == shape and np.all(np.isfinite(jacs[-1]))
    scale = np.abs(jacs[0]).max()
    assert scale > 0
    np.testing.assert_allclose(jacs[1], jacs[0], rtol=0, atol=1e-9 * scale)


@pytest.mark.parametrize(
    "versions, bad",
    [
        ({"jax": "0.9.2", "jaxlib": "0.9.2"}, False),
        ({"jax": "0.10.2", "jaxlib": "0.10.2"}, True),
        ({"jax": "0.9.2", "jaxlib": "0.10.2"}, True),
        ({"jax": "0.11.0", "jaxlib": "0.11.0"}, False),
    ],
)
def test_known_bad_versions_are_named(versions, bad):
    problems = stack.known_problems(versions)
    assert bool(problems) == bad
    if bad:
        assert "0.10.2" in problems[0] and "jacfwd" in problems[0]


def test_guard_warns_once_and_can_be_silenced(monkeypatch):
    monkeypatch.setattr(stack, "installed_versions", lambda: {"jax": "0.10.2", "jaxlib": "0.10.2"})
    monkeypatch.setattr(stack, "_warned", False)
    monkeypatch.delenv("DIFFGUIDE_ALLOW_BAD_JAX", raising=False)
    with pytest.warns(RuntimeWarning, match="0.10.2"):
        stack.check_stack()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        stack.check_stack()  # once per process
    monkeypatch.setattr(stack, "_warned", False)
    monkeypatch.setenv("DIFFGUIDE_ALLOW_BAD_JAX", "1")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        stack.check_stack()
