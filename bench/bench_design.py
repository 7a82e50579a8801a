"""Benchmark: design with gradients against a brute-force grid (``diffguide.studies.design``;
not a test).

The two-variable problem of issue 32: the ``majda2012`` table's thickness (30..80 mm) and carriage
spacing (within the range where the mesh keeps its topology) for the smallest mean corner roll
difference over random rails (σ = 1 µm, ℓ = 200 mm, both rails and planes), the table's mass at
most ``--mass-kg``. The optimiser (SLSQP with forward-mode gradients, common random numbers)
against a ``--grid`` × ``--grid`` grid of the same objective on the same rails (values only,
rebuilt machines, infeasible points left out). Reported: each one's optimum, its objective, its
model evaluations (an evaluation = one build and one sweep of every sample; the optimiser's
carry the derivatives too), wall time and sample sweeps per second, and whether the optimum
lies within one grid spacing of the grid's. The compile time of each is measured separately
(a first call) and not counted in the wall times. Run:

    python bench/bench_design.py                          # 10x5 mesh, 32 samples, 15x15 grid
    python bench/bench_design.py --samples 256 --grid 25  # larger
    python bench/bench_design.py --host-devices 2         # shard the samples over 2 CPU devices

The GPU check, one short call on a machine with the project's tree and its own JAX (every JAX
device is used; nothing to install with PYTHONPATH):

    PYTHONPATH=src python bench/bench_design.py --samples 4096 --grid 11 --json $OUT/design.json

(not yet run on a GPU: the sessions that built it had no device.)
"""

import argparse
import json
import os
import platform
import sys
import time


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--samples", type=int, default=32)
    p.add_argument("--positions", type=int, default=15)
    p.add_argument("--mesh", default="10x5")
    p.add_argument("--grid", type=int, default=15)
    p.add_argument("--mass-kg", type=float, default=180.0)
    p.add_argument("--chunk", type=int, default=None)
    p.add_argument("--host-devices", type=int, default=1)
    p.add_argument("--json", default=None, help="also write the figures as JSON")
    args = p.parse_args(argv)
    if args.host_devices > 1:  # before jax is imported
        flag = f" --xla_force_host_platform_device_count={args.host_devices}"
        os.environ["XLA_FLAGS"] = os.environ.get("XLA_FLAGS", "") + flag
    import jax
    import numpy as np

    jax.config.update("jax_enable_x64", True)
    from diffguide.machine.build import build_machine, with_overrides
    from diffguide.machine.paper import majda2012_spec
    from diffguide.studies.design import design, design_knots
    from diffguide.studies.design_space import carriage_spacing_range, parse_constraint
    from diffguide.studies.montecarlo import batched_sweep
    from diffguide.studies.random_rails import GaussianRailModel, sample_rails
    from diffguide.studies.tolerance import measure_values

    nx, ny = (int(v) for v in args.mesh.split("x"))
    spec = with_overrides(majda2012_spec(), nx=nx, ny=ny)
    positions = np.linspace(-0.35, 0.35, args.positions)
    s_lo, s_hi = carriage_spacing_range(spec)
    bounds = [(0.03, 0.08), (s_lo, s_hi)]
    mass = parse_constraint(f"mass<={args.mass_kg}")
    knots = design_knots(spec, positions, 0.2, bounds[1])
    devices = jax.devices()
    out = {"jax": jax.__version__, "cpu": platform.processor() or platform.machine(),
           "cores": os.cpu_count(), "devices": f"{len(devices)} x {devices[0].platform}",
           "mesh": args.mesh, "samples": args.samples, "positions": args.positions,
           "grid": args.grid, "mass_kg": args.mass_kg}
    kw = dict(variables=("thickness", "carriage_spacing"), bounds=bounds, constraints=[mass],
              n_samples=args.samples, check_samples=0, knots=knots, chunk_size=args.chunk)

    t0 = time.perf_counter()  # compile (and a throw-away run of 1 iteration)
    design(spec, positions, max_iterations=1, **kw)
    out["optimiser_compile_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = design(spec, positions, **kw)
    wall = time.perf_counter() - t0
    out["optimiser"] = {"thickness_mm": res.optimum[0] * 1e3,
                        "carriage_spacing_mm": res.optimum[1] * 1e3,
                        "objective_urad": res.after.value * 1e6, "evaluations": res.evaluations,
                        "wall_s": wall, "sample_sweeps_per_s": res.sample_sweeps / wall,
                        "message": res.message}

    rails = sample_rails(0, args.samples, GaussianRailModel(1e-6, 0.2), knots=knots)
    rho_lw = float(spec.table.material.rho) * spec.table.length * spec.table.width
    ts = np.linspace(*bounds[0], args.grid)
    ss = np.linspace(*bounds[1], args.grid)

    def value(t, s):
        m = build_machine(spec, thickness=t, carriage_spacing=s)
        return float(np.mean(measure_values(batched_sweep(m, rails, positions,
                                                          chunk_size=args.chunk),
                                            "roll_difference")))

    t0 = time.perf_counter()
    value(ts[0], ss[0])
    out["grid_compile_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    feasible = [(t, s) for t in ts for s in ss if rho_lw * t <= args.mass_kg * (1 + 1e-9)]
    grid = [(value(t, s), t, s) for t, s in feasible]
    wall_g = time.perf_counter() - t0
    best = min(grid)
    out["grid"] = {"thickness_mm": best[1] * 1e3, "carriage_spacing_mm": best[2] * 1e3,
                   "objective_urad": best[0] * 1e6, "evaluations": len(grid), "wall_s": wall_g,
                   "sample_sweeps_per_s": len(grid) * args.samples / wall_g,
                   "spacing_mm": [(ts[1] - ts[0]) * 1e3, (ss[1] - ss[0]) * 1e3]}
    within = (abs(res.optimum[0] - best[1]) <= ts[1] - ts[0]
              and abs(res.optimum[1] - best[2]) <= ss[1] - ss[0])
    out["within_grid_spacing"] = bool(within)
    out["evaluation_ratio"] = len(grid) / res.evaluations
    o, g = out["optimiser"], out["grid"]
    print(f"{out['devices']}, jax {out['jax']}, mesh {args.mesh}, {args.samples} samples x "
          f"{args.positions} positions, mass <= {args.mass_kg:g} kg")
    for name, r in (("optimiser", o), ("grid", g)):
        print(f"  {name:9}: thickness {r['thickness_mm']:.3f} mm, spacing "
              f"{r['carriage_spacing_mm']:.2f} mm, objective {r['objective_urad']:.4f} µrad; "
              f"{r['evaluations']} evaluations, {r['wall_s']:.1f} s, "
              f"{r['sample_sweeps_per_s']:.0f} sample sweeps/s")
    print(f"  compile: optimiser {out['optimiser_compile_s']:.1f} s, grid "
          f"{out['grid_compile_s']:.1f} s; optimum within one grid spacing "
          f"({g['spacing_mm'][0]:.2f} mm, {g['spacing_mm'][1]:.2f} mm): {within}; "
          f"{out['evaluation_ratio']:.1f}x fewer evaluations")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=2)
    return 0 if within else 1


if __name__ == "__main__":
    sys.exit(main())
