"""Benchmark: prediction from a fit without condensing the table again (not a test).

In one process, on the bundled data's fit (``diffguide fit --preset majda2012 --measurements
data/majda2012_measurements.csv``, made here unless ``--fit DIR`` names one):

1. the first prediction (the fitted machine condensed at three structure values, compiles,
   the sweep with its Jacobian): once;
2. 2 new points x 71 positions, the fit's sweep kept (``posterior_sweep``'s cache): new
   points every run;
3. the same with new positions every run (the sweep solved again: the equilibria and their
   Jacobian; the machines kept);
4. the error map, a 21 x 11 grid x 71 positions with σ (sweep kept), and with new positions;
5. for comparison the former route (``_predict_recondensed``, the table condensed again with
   lines through the points): its machines kept, and with new points.

Each figure is the median of ``--repeat`` runs after one warm-up. Targets: (2) <= 50 ms,
(4) <= 2 s. The load average is printed before and after: the figures mean something only on
an idle machine. ``--json FILE`` writes the times of (2) and (4) (s) for
``bench/make_table.py``; ``--skip-former`` leaves out (5). The command line's figure, a warm
``diffguide predict`` in a fresh process, is ``bench/bench_cli.py``'s. Run:

    python bench/bench_predict.py [--fit DIR] [--repeat 5] [--json FILE] [--skip-former]
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

from diffguide.inverse.error_map import error_map  # noqa: E402
from diffguide.inverse.predict import _predict_recondensed, predict  # noqa: E402
from diffguide.io.config import default_config, spec_from_config  # noqa: E402
from diffguide.io.fit_posterior import read_fit_posterior  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"


def _load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def _times(fn, repeat: int) -> list[float]:
    fn(0)  # warm-up
    times = []
    for k in range(1, repeat + 1):
        t = time.perf_counter()
        fn(k)
        times.append(time.perf_counter() - t)
    return times


def _median(fn, repeat: int, keep: list | None = None) -> str:
    times = _times(fn, repeat)
    if keep is not None:
        keep.extend(times)
    return (f"median {statistics.median(times) * 1e3:.1f} ms (min {min(times) * 1e3:.1f}, "
            f"max {max(times) * 1e3:.1f}, n={len(times)})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fit", help="a 'diffguide fit --out' folder (default: fitted here)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--json", help="write the times (s) of (2) and (4) to this file")
    ap.add_argument("--skip-former", action="store_true", help="leave out (5)")
    args = ap.parse_args()
    kept = {"first": [], "points": [], "grid": []}
    print(f"jax {jax.__version__} on {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, float64; load average {_load()}")
    with tempfile.TemporaryDirectory() as tmp:
        fit_dir = args.fit
        if fit_dir is None:
            fit_dir = str(Path(tmp) / "fit")
            cli = str(Path(sys.executable).parent / "diffguide")
            subprocess.run([cli, "fit", "--preset", "majda2012",
                            "--measurements", str(DATA), "--out", fit_dir, "--no-plots", "-q"],
                           check=True, stderr=subprocess.DEVNULL)
        post, meta = read_fit_posterior(fit_dir)
    spec = spec_from_config(default_config())
    mp = meta["points_m"]
    x = np.linspace(*post.position_range, 71)

    def points(k):  # two new points for every run (off the mesh's grid lines)
        return {"Q1": (0.3 + 1e-3 * k, -0.1), "Q2": (-0.2, 0.15 - 1e-3 * k)}

    def shifted(k):  # 71 new positions for every run (the same shape: no compilation)
        return x * (1.0 - 1e-4 * k)

    t = time.perf_counter()
    predict(post, spec, points(100), x, measured_points=mp)
    kept["first"].append(time.perf_counter() - t)
    print(f"1. first prediction (3 condensations, compiles, sweep): {kept['first'][0]:.2f} s")
    print("2. 2 points x 71 positions, sweep kept:          ",
          _median(lambda k: predict(post, spec, points(k), x, measured_points=mp), args.repeat,
                  kept["points"]))
    print("3. 2 points x 71 new positions (sweep again):    ",
          _median(lambda k: predict(post, spec, points(k), shifted(k + 10), measured_points=mp),
                  args.repeat))
    print("4. error map 21 x 11 x 71 positions with σ:      ",
          _median(lambda k: error_map(post, spec, (21, 11), x, measured_points=mp),
                  args.repeat, kept["grid"]))
    print("   the same at 71 new positions (sweep again):   ",
          _median(lambda k: error_map(post, spec, (21, 11), shifted(k + 20),
                                      measured_points=mp), args.repeat))
    if args.json:
        Path(args.json).write_text(json.dumps(kept), encoding="utf-8")
    if not args.skip_former:
        _former(post, spec, points, x, mp, args.repeat)
    print(f"load average after: {_load()}")


def _former(post, spec, points, x, mp, repeat) -> None:
    print("5. former route, its machines kept (same points):",
          _median(lambda k: _predict_recondensed(post, spec, points(0), x, measured_points=mp),
                  min(repeat, 3)))
    t = time.perf_counter()
    _predict_recondensed(post, spec, points(200), x, measured_points=mp)
    print(f"   former route, new points (condensed again):    {time.perf_counter() - t:.2f} s")


if __name__ == "__main__":
    main()
