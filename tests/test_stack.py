"""The numerical stack: the fit Jacobian is reproduced by fresh processes.

A wrong Jacobian is silent (a wrong fit), and a compiler that miscompiles the ``jacfwd`` through
the implicit solve now and then would show as two fresh compilations that disagree. So this test
compiles the full fit Jacobian in two fresh processes and requires them to agree
(test_inverse.py compares it with central differences); the second process compiles with the
command line's XLA flags for the installed jaxlib (``cli._runtime.XLA_CPU_FLAGS``), so these are
held to the same Jacobian.
"""

import json
import os
import pathlib
import subprocess
import sys

import numpy as np

from diffguide.cli._runtime import XLA_CPU_FLAGS

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
