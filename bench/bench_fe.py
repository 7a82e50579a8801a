"""Benchmark: assembly + condensation of the majda2012 table (not a test).

Times ``majda2012_table(nx, ny).condense()`` (vmapped MITC4 element matrices, scatter into the
dense reduced matrix, master–slave ties of the 4 carriages + nut, dense Cholesky of the interior
block, recovery of the 5 control points) for meshes from 10 × 5 to 60 × 30 uniform divisions
(the footprint and point grid lines come on top). The first call (trace + compile + run) is
reported separately from the steady state (median of several runs). Run:

    PYTHONPATH=src python bench/bench_fe.py [--sizes 10x5 20x10 40x20 60x30] [--repeat 5]
"""

import argparse
import platform
import statistics
import time

import jax

jax.config.update("jax_enable_x64", True)

from diffguide.fe import majda2012_table  # noqa: E402


def _run(model):
    c = model.condense()
    jax.block_until_ready(c)
    return c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", default=["10x5", "20x10", "40x20", "60x30"])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print(f"jax {jax.__version__} on {platform.processor() or platform.machine()}, "
          f"{jax.devices()[0].platform}, float64")
    print(f"{'mesh':>7} {'grid':>7} {'nodes':>6} {'DOF':>6} {'reduced':>7} "
          f"{'first call s':>12} {'steady s (median)':>18} {'min':>7} {'max':>7}")
    for s in args.sizes:
        nx, ny = (int(v) for v in s.split("x"))
        model = majda2012_table(nx, ny)
        mesh = model.mesh
        t0 = time.perf_counter()
        c = _run(model)
        first = time.perf_counter() - t0
        reduced = 6 * mesh.n_nodes - 6 * sum(
            len(mesh.nodes_in_box(*p.box)) for p in model.patches) + c.K.shape[0]
        repeat = args.repeat if mesh.n_dof < 8000 else max(2, args.repeat // 2)
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            _run(model)
            times.append(time.perf_counter() - t0)
        grid = f"{len(mesh.xs) - 1}x{len(mesh.ys) - 1}"
        print(f"{s:>7} {grid:>7} {mesh.n_nodes:>6} {mesh.n_dof:>6} {reduced:>7} {first:>12.2f} "
              f"{statistics.median(times):>18.3f} {min(times):>7.3f} {max(times):>7.3f}",
              flush=True)


if __name__ == "__main__":
    main()
