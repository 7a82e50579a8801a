"""Benchmark of the machine sweep (issue 4): steady-state time of a 141-position majda2012 sweep,
the full Jacobian of all joint errors w.r.t. all rail B-spline coefficients, and compile times.

Run: ``python bench/bench_machine.py`` (prints a table). Every figure is the median of several
runs in this process (compile excluded, reported separately); run it a few times in fresh
processes: timings vary between processes on a loaded machine.
"""

import os
import platform
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from diffguide.guideway.rails import SplineRail  # noqa: E402
from diffguide.machine.kinematics import joint_errors  # noqa: E402
from diffguide.machine.majda2012 import majda2012_machine, paper_variant  # noqa: E402

REPEATS = 15


def timed(fn, *args):
    t0 = time.perf_counter()
    jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t0
    times = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - t0)
    return first, float(np.median(times)), float(np.min(times))


def main():
    t0 = time.perf_counter()
    machine = majda2012_machine()
    jax.block_until_ready(machine.table.K)
    build = time.perf_counter() - t0
    positions = jnp.linspace(-0.35, 0.35, 141)

    sweep = jax.jit(lambda m, p: joint_errors(m, paper_variant(3), p).errors)
    sweep_first, sweep_med, sweep_min = timed(sweep, machine, positions)

    spacing, start = 0.04, -0.6
    n = int(round(1.2 / spacing)) + 3
    rng = np.random.default_rng(0)
    coeffs = jnp.asarray(rng.normal(scale=2e-6, size=4 * n))

    def errors(c):
        r1 = SplineRail(start, spacing, c[:n], c[n : 2 * n])
        r2 = SplineRail(start, spacing, c[2 * n : 3 * n], c[3 * n :])
        return joint_errors(machine, (r1, r2), positions).errors

    jac = jax.jit(jax.jacfwd(errors))
    jac_first, jac_med, jac_min = timed(jac, coeffs)
    shape = jac(coeffs).shape

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"jax {jax.__version__}, backend {jax.default_backend()}")
    print(f"majda2012 machine build (mesh 20x10, condensation, incl. compile): {build:.2f} s")
    print(f"{'quantity':58s} {'first call':>11s} {'median':>9s} {'min':>9s}")
    print(f"{'sweep: 141 positions, 5 points, 6 errors':58s} {sweep_first:10.2f}s "
          f"{sweep_med * 1e3:7.1f}ms {sweep_min * 1e3:7.1f}ms")
    print(f"{'jacfwd of all errors w.r.t. ' + str(4 * n) + ' rail coefficients ' + str(shape):58s} "
          f"{jac_first:10.2f}s {jac_med * 1e3:7.1f}ms {jac_min * 1e3:7.1f}ms")
    print("targets (2-core CPU): sweep <= 10 ms, Jacobian <= 200 ms, compile <= 20 s")


if __name__ == "__main__":
    main()
