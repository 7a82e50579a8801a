"""Benchmark of the cross table (issue 42): the ``majda2012-cross`` machine's errors at its
control points over a 9 × 9 (X, Y) grid, written as a CSV, as a whole process.

Run: ``python bench/bench_cross.py [CACHE_DIR]``. It runs the same job three times in fresh
processes sharing one cache folder (the command line's caches: condensed tables, exported
programs, the persistent compilation cache): the first fills it (cold), the others are warm.
Prints each process's wall time and the load average. The job: build the cross table, solve
the grid (rails: X rail 1 and Y rail 1 bent as the paper's eq. 4, Δ = 0.05 mm, vertically),
write ``cross_errors.csv``.
"""

import os
import subprocess
import sys
import tempfile
import time

JOB = r"""
import argparse, sys
from pathlib import Path
from diffguide.cli._common import prepare_runtime
caches = prepare_runtime(argparse.Namespace(cache_dir=sys.argv[1], no_cache=False))
import numpy as np
from diffguide._core.aot import cached_program
from diffguide.io.atomic import atomic_write_text
from diffguide.io.cross_csv import cross_errors_csv
from diffguide.machine.cross import build_cross
from diffguide.machine.majda2012 import paper_variant
from diffguide.machine.paper_cross import majda2012_cross_spec
from diffguide.machine.volumetric import cross_errors_traced
with caches:
    cross = build_cross(majda2012_cross_spec())
    run = cached_program(cross_errors_traced, "machine.volumetric.cross_errors",
                         compiler_options={"xla_backend_optimization_level": 0})
    X, Y = np.linspace(-0.35, 0.35, 9), np.linspace(-0.23, 0.23, 9)
    e = run(cross, paper_variant(1), paper_variant(1), X, Y)
    assert bool(np.all(np.asarray(e.converged)))
    atomic_write_text(Path(sys.argv[2]) / "cross_errors.csv", cross_errors_csv(e))
"""


def main():
    cache = sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp(prefix="dg-cross-cache-")
    out = tempfile.mkdtemp(prefix="dg-cross-out-")
    env = dict(os.environ, TF_CPP_MIN_LOG_LEVEL="3")
    for label in ("cold", "warm", "warm"):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", JOB, cache, out], check=True, env=env)
        print(f"{label}: {time.perf_counter() - t0:.2f} s  (load {os.getloadavg()[0]:.1f})")
    print(f"csv: {os.path.join(out, 'cross_errors.csv')}")


if __name__ == "__main__":
    main()
