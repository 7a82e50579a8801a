"""Benchmark of the cross table (issue 42): the ``majda2012-cross`` machine's errors at its
control points over a 9 × 9 (X, Y) grid, written as a CSV, as a whole process.

Run: ``python bench/bench_cross.py [CACHE_DIR]``. It runs ``diffguide simulate --preset
majda2012-cross --grid-xy 9x9`` three times in fresh processes sharing one cache folder
(condensed tables, exported programs, the persistent compilation cache): the first fills it
(cold), the others are warm. Prints each process's wall time and the load average (for a
figure to quote, time it with the one-axis ``simulate`` side by side, e.g. ``farm-bench``).
"""

import os
import subprocess
import sys
import tempfile
import time

COMMAND = ["-m", "diffguide.cli", "simulate", "--preset", "majda2012-cross", "--grid-xy", "9x9",
           "-q"]


def main():
    cache = sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp(prefix="dg-cross-cache-")
    out = tempfile.mkdtemp(prefix="dg-cross-out-")
    env = dict(os.environ, TF_CPP_MIN_LOG_LEVEL="3")
    for label in ("cold", "warm", "warm"):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, *COMMAND, "--cache-dir", cache, "--out",
                        os.path.join(out, "cross_errors.csv")], check=True, env=env)
        print(f"{label}: {time.perf_counter() - t0:.2f} s  (load {os.getloadavg()[0]:.1f})")
    print(f"csv: {os.path.join(out, 'cross_errors.csv')}")


if __name__ == "__main__":
    main()
