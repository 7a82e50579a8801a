"""Benchmark: rail identification on the bundled data (not a test).

1. Library: ``fit_rails`` (elastic model, LM + GCV + covariance) on
   ``data/majda2012_measurements.csv``; the first call (trace + compile + run) is reported
   separately from the steady state (median of ``--repeat`` runs); the rigid-table linear
   inversion likewise; the machine build (table condensation) on its own.
2. End to end: ``diffguide fit --preset majda2012 --measurements ... --out ...`` in fresh
   processes (median of ``--cli-repeat``), everything included (imports, machine, both fits,
   compiles, report, plots).

Targets (2-core CPU): steady-state fit <= 2 s, CLI <= 30 s. Run:

    python bench/bench_fit.py [--repeat 5] [--cli-repeat 3]
"""

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

from diffguide.inverse import fit_rails  # noqa: E402
from diffguide.io.measurements import read_measurements  # noqa: E402
from diffguide.machine.majda2012 import majda2012_machine  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--cli-repeat", type=int, default=3)
    args = ap.parse_args()
    print(f"jax {jax.__version__} on {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}, float64")
    meas = read_measurements(DATA)
    points = {n: tuple(map(float, xy)) for n, xy in zip(meas.point_names, meas.points_xy)}
    machine, t_build = _timed(lambda: majda2012_machine(points=points))
    print(f"machine build (condensation): {t_build:.2f} s; {meas.n} merged rows")
    for label, m, method in (("elastic LM", machine, "lm"),
                             ("rigid-table linear", machine.with_rigid_table(), "linear")):
        fit, first = _timed(lambda: fit_rails(m, meas, method=method))
        times = [_timed(lambda: fit_rails(m, meas, method=method))[1] for _ in range(args.repeat)]
        print(f"{label:>20}: first call {first:.2f} s; steady median {statistics.median(times):.2f}"
              f" s (min {min(times):.2f}, max {max(times):.2f}, n={len(times)}); "
              f"LM steps {fit.steps}, chi2/dof {fit.chi2_dof:.3f}")
    cli = []
    for _ in range(args.cli_repeat):
        with tempfile.TemporaryDirectory() as tmp:
            cmd = [sys.executable, "-m", "diffguide.cli", "fit", "--preset", "majda2012",
                   "--measurements", str(DATA), "--out", str(Path(tmp) / "out"), "--quiet"]
            _, t = _timed(lambda: subprocess.run(cmd, check=True))
            cli.append(t)
    print(f"end-to-end CLI (fresh process): median {statistics.median(cli):.1f} s "
          f"(min {min(cli):.1f}, max {max(cli):.1f}, n={len(cli)}); load average now "
          f"{os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
