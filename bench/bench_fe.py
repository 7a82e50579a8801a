"""Benchmark: assembly + condensation of the majda2012 table (not a test).

Times ``majda2012_table(nx, ny).condense(method=...)`` (vmapped MITC4 element matrices, master–slave
ties of the 4 carriages + nut, the interior solve, recovery of the 5 control points and of all
nodes) for the block-tridiagonal path (``banded``, the default: element matrices scattered
straight into the diagonal/sub-diagonal blocks, block Cholesky by ``lax.scan``) and optionally
the dense reference path (``dense``: dense reduced matrix, dense Cholesky).

Each (size, method) runs in ``--procs`` fresh processes: the first call (trace + compile + run,
nothing cached) and the steady state (median of ``--repeat`` further calls) are reported as
medians over the processes. Then the agreement of the two paths (max relative difference of
``K``, ``f``, ``R``, ``r0``, ``node_modes``, ``node_u0``) on ``--agree`` meshes. The load average
is printed before and after: the figures mean something only on an idle machine. Run:

    .venv/bin/python bench/bench_fe.py [--sizes 20x10 40x20 60x30 100x50] [--methods banded]
        [--procs 3] [--repeat 3] [--agree 20x10]
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time

FIELDS = ("K", "f", "R", "r0", "node_modes", "node_u0")


def _load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def _one(size: str, method: str, repeat: int) -> None:
    """Child process: time one (size, method), print one JSON line."""
    t_import = time.perf_counter()
    import jax

    jax.config.update("jax_enable_x64", True)
    from diffguide.machine.majda2012 import majda2012_table

    t_import = time.perf_counter() - t_import
    nx, ny = (int(v) for v in size.split("x"))
    model = majda2012_table(nx, ny)
    t0 = time.perf_counter()
    jax.block_until_ready(model.condense(method=method))
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        jax.block_until_ready(model.condense(method=method))
        times.append(time.perf_counter() - t0)
    mesh = model.mesh
    print(
        json.dumps(
            dict(
                grid=f"{len(mesh.xs) - 1}x{len(mesh.ys) - 1}",
                dof=mesh.n_dof,
                block=6 * min(len(mesh.xs), len(mesh.ys)),
                n_blocks=max(len(mesh.xs), len(mesh.ys)),
                import_s=t_import,
                first=first,
                steady=statistics.median(times),
            )
        )
    )


def _agree(size: str) -> None:
    """Child process: max relative difference banded vs dense, one JSON line."""
    import jax
    import numpy as np

    jax.config.update("jax_enable_x64", True)
    from diffguide.fe import Rib
    from diffguide.machine.majda2012 import majda2012_table

    nx, ny = (int(v) for v in size.split("x"))
    out = {}
    for label, ribs in (
        ("plain", ()),
        ("ribbed", (Rib("x", 0.0, 0.03, 0.05), Rib("y", 0.1, 0.02, 0.04))),
    ):
        model = majda2012_table(nx, ny, ribs=ribs)
        a, b = model.condense(method="banded"), model.condense(method="dense")
        out[label] = max(
            float(np.abs(np.asarray(getattr(a, k)) - np.asarray(getattr(b, k))).max())
            / float(np.abs(np.asarray(getattr(b, k))).max())
            for k in FIELDS
        )
    print(json.dumps(out))


def _child(args: list[str]) -> dict:
    r = subprocess.run(
        [sys.executable, __file__, *args], capture_output=True, text=True, check=True
    )
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", default=["20x10", "40x20", "60x30", "100x50"])
    ap.add_argument("--methods", nargs="+", default=["banded"], choices=["banded", "dense"])
    ap.add_argument("--procs", type=int, default=3, help="fresh processes per size (median)")
    ap.add_argument("--repeat", type=int, default=3, help="steady-state calls per process")
    ap.add_argument("--agree", nargs="*", default=["20x10"], help="meshes for banded vs dense")
    ap.add_argument("--one", nargs=2, metavar=("SIZE", "METHOD"), help=argparse.SUPPRESS)
    ap.add_argument("--agree-one", metavar="SIZE", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        return _one(*args.one, args.repeat)
    if args.agree_one:
        return _agree(args.agree_one)

    import jax

    print(
        f"jax {jax.__version__} on {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} CPUs, float64; load average before: {_load()}"
    )
    print(
        f"{'mesh':>7} {'method':>7} {'grid':>7} {'DOF':>6} {'blocks':>10} "
        f"{'first call s':>12} {'steady s':>9} {'(range over processes)':>24}"
    )
    for s in args.sizes:
        for method in args.methods:
            runs = [
                _child(["--one", s, method, "--repeat", str(args.repeat)])
                for _ in range(args.procs)
            ]
            r0 = runs[0]
            first = [r["first"] for r in runs]
            steady = [r["steady"] for r in runs]
            blocks = f"{r0['n_blocks']}x{r0['block']}" if method == "banded" else "-"
            print(
                f"{s:>7} {method:>7} {r0['grid']:>7} {r0['dof']:>6} {blocks:>10} "
                f"{statistics.median(first):>12.2f} {statistics.median(steady):>9.3f} "
                f"{f'{min(first):.2f}-{max(first):.2f} / {min(steady):.3f}-{max(steady):.3f}':>24}",
                flush=True,
            )
    for s in args.agree:
        a = _child(["--agree-one", s])
        print(
            f"banded vs dense at {s}: max relative difference {a['plain']:.1e} (plain), "
            f"{a['ribbed']:.1e} (2 ribs)",
            flush=True,
        )
    print(f"load average after: {_load()}")


if __name__ == "__main__":
    main()
