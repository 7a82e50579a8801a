"""Benchmark: measurement planning for ``majda2012`` (not a test).

The planner of ``diffguide plan``'s defaults: a 7 × 3 grid of candidate sites, 36 positions,
4 two-axis levels + 1 interferometer (+ optionally straightness optics), the structure unknown
(the fit's default priors, 8 prior rail draws), the worst-profile-σ criterion, compared with the
bundled layout. Reported: the machine family's build (9 table condensations) on its own, then
``plan(...)`` twice — the first call (trace + compile + sensitivities + greedy), the second
(compiled) — split into the sensitivities (build_planner) and the greedy selection. Run:

    python bench/bench_plan.py [--grid 7x3] [--draws 8] [--json FILE]
"""

import argparse
import json
import os
import platform
import time

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from diffguide.inverse import MachineFamily, Prior, StructurePriors  # noqa: E402
from diffguide.planning import Instrument, build_planner, grid_sites  # noqa: E402
from diffguide.machine.majda2012 import majda2012_machine  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", default="7x3")
    ap.add_argument("--draws", type=int, default=8)
    ap.add_argument("--json", default=None, help="write the timings to this JSON file")
    ap.add_argument("--plot", default=None, help="write a bar chart of the timings (PNG)")
    args = ap.parse_args()
    nx, ny = (int(v) for v in args.grid.split("x"))
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    print(
        f"jax {jax.__version__} on {machine}, load average {os.getloadavg()[0]:.1f}, float64; "
        f"grid {nx}x{ny}, {args.draws} draws"
    )
    sites = grid_sites(1.0, 0.5, nx, ny)
    positions = np.linspace(-0.35, 0.35, 36)
    t = time.perf_counter()
    priors = StructurePriors(Prior(0.05, 0.025, 0.10), Prior(0.08, 0.02, 0.16))
    family = MachineFamily.build(lambda **kw: majda2012_machine(points=sites, **kw), priors)
    t_family = time.perf_counter() - t
    print(f"machine family (9 condensations): {t_family:.1f} s")
    corners = [n for n, (x, y) in sites.items() if abs(abs(x) - 0.45) < 1e-9 and abs(y) > 0.19]
    centre = min(sites, key=lambda n: np.hypot(*sites[n]))
    bundled = [("level", n) for n in corners] + [("interferometer", centre)]
    rows = []
    for call in ("first", "second"):
        t = time.perf_counter()
        planner = build_planner(
            family,
            [Instrument("level", 4), Instrument("interferometer", 1)],
            positions,
            n_draws=args.draws,
        )
        t_sens = time.perf_counter() - t
        t = time.perf_counter()
        steps, best = planner.greedy()
        ref = planner.evaluate(bundled)
        t_greedy = time.perf_counter() - t
        rows.append(
            {
                "call": call,
                "sensitivities_s": t_sens,
                "greedy_s": t_greedy,
                "total_s": t_sens + t_greedy,
            }
        )
        print(
            f"{call} call: sensitivities {t_sens:.1f} s, greedy + comparison {t_greedy:.1f} s, "
            f"total {t_sens + t_greedy:.1f} s; worst σ {best.worst * 1e6:.3f} µm "
            f"(bundled {ref.worst * 1e6:.3f} µm)"
        )
    if args.plot:
        _plot(args.plot, t_family, rows, machine, args)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(
                {
                    "machine": machine,
                    "jax": jax.__version__,
                    "grid": args.grid,
                    "draws": args.draws,
                    "family_s": t_family,
                    "load_average": os.getloadavg()[0],
                    "calls": rows,
                },
                fh,
                indent=1,
            )


def _plot(path, t_family, rows, machine, args) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 2.8), constrained_layout=True)
    labels = ["machine family\n(9 condensations)"] + [f"plan(), {r['call']} call" for r in rows]
    y = np.arange(len(labels))[::-1]
    ax.barh(y[0], t_family, color="0.6")
    for k, r in enumerate(rows):
        ax.barh(
            y[k + 1],
            r["sensitivities_s"],
            color="tab:blue",
            label="sensitivities (Jacobians)" if k == 0 else None,
        )
        ax.barh(
            y[k + 1],
            r["greedy_s"],
            left=r["sensitivities_s"],
            color="tab:orange",
            label="greedy + comparison" if k == 0 else None,
        )
        ax.text(r["total_s"], y[k + 1], f" {r['total_s']:.1f} s", va="center")
    ax.text(t_family, y[0], f" {t_family:.1f} s", va="center")
    ax.set_yticks(y, labels)
    ax.set_xlabel("seconds")
    ax.set_xlim(0, 1.2 * max([t_family] + [r["total_s"] for r in rows]))
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title(
        f"diffguide plan, majda2012, {args.grid} sites, 36 positions, "
        f"{args.draws} draws — {machine}",
        fontsize=9,
    )
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
