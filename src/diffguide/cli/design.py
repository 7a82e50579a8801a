"""``diffguide design``: the machine layout that minimises an error statistic over random rails,
within bounds and constraints (:func:`diffguide.studies.design.design`)."""

import argparse
import json
import sys

import numpy as np

from ._common import add_machine_arguments
from ..jobs.study import check_study
from ._study_options import add_study_arguments, split_cpu_into_devices

# diffguide.studies.design_space.VARIABLES / CONSTRAINTS, named here so that --help imports no
# JAX (tests/test_design.py checks they agree): name -> (user unit, SI per user unit)
VARIABLE_UNITS = {"thickness": ("mm", 1e-3), "carriage_spacing": ("mm", 1e-3),
                  "rail_spacing": ("mm", 1e-3), "preload_fraction": ("%", 1e-2),
                  "E": ("GPa", 1e9)}
CONSTRAINT_UNITS = {"mass": "kg", "preload": "N", "spacing": "mm", "rail_length": "mm"}


def add_parser(sub) -> None:
    p = sub.add_parser(
        "design",
        help="the design (thickness, carriage and rail spacing, preload, E) that minimises an "
        "error statistic over random rails",
        description="Minimise the mean or a percentile of an error measure over random rails "
        "(the same rails at every trial design: common random numbers) over the chosen design "
        "variables, within bounds and constraints, by SLSQP with exact gradients (forward-mode "
        "AD through the build and the equilibrium). Then the start and the optimum on fresh "
        "rails, with 95 % intervals, and the improvement with its paired interval.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    add_machine_arguments(p)
    p.add_argument("--vary", action="append", required=True, metavar="NAME[=LO:HI]",
                   help="a design variable and its bounds in user units: thickness (mm), "
                   "carriage_spacing (mm), rail_spacing (mm), preload_fraction (%%), E (GPa); "
                   "without =LO:HI its default bounds (the spacings: the range where the mesh "
                   "keeps its topology; wider bounds re-centre the mesh). Repeat for several")
    p.add_argument("--objective", default="roll-difference:mean",
                   help="MEASURE:STATISTIC; MEASURE 'roll-difference' (µrad) or "
                   "'range:ERR:POINT' (e.g. range:EBX:P1); STATISTIC 'mean' or 'pNN' "
                   "(the NN %% quantile, Harrell-Davis). Or plan:CRITERION, the fit's "
                   "predicted σ for the --plan (no random rails): plan:A (RMS profile σ, µm), "
                   "plan:worst (largest profile σ, µm), plan:work (largest σ of the predicted "
                   "errors at --work-point)")
    p.add_argument("--plan", default="bundled", metavar="PLACEMENTS.csv",
                   help="with a plan: objective, the measurement plan: 'bundled' (two-axis "
                   "levels at the corners 50 mm inside the edges, an interferometer at the "
                   "centre) or a CSV instrument,x_mm,y_mm (as 'diffguide plan --compare'; "
                   "instrument level, interferometer or straightness), read at the --positions")
    p.add_argument("--plan-runs", type=int, default=5,
                   help="with a plan: objective, runs per direction (two directions)")
    p.add_argument("--work-point", default=None, metavar="X,Y",
                   help="with plan:work, the work point on the table top (mm)")
    p.add_argument("--work-reads", default="EAX,EBX",
                   help="with plan:work, the predicted errors at the work point")
    p.add_argument("--constraint", action="append", default=None, metavar="Q<=V",
                   help="QUANTITY<=V, >=V or =V: mass (kg, the plate), preload (N, total), "
                   "spacing (mm: carriage spacing - (table length - carriage length)), "
                   "rail_length (mm: stroke + carriage spacing + carriage length). Repeat")
    p.add_argument("--rail-rms-um", type=float, default=1.0,
                   help="RMS straightness of each rail and plane (µm)")
    p.add_argument("--samples", type=int, default=64,
                   help="random rail pairs of the optimisation (the same at every design)")
    p.add_argument("--check-samples", type=int, default=64,
                   help="fresh random rail pairs re-evaluating the start and the optimum (0: none)")
    p.add_argument("--max-iter", type=int, default=30, help="SLSQP iterations at most")
    add_study_arguments(p)
    p.add_argument("--out", default="design.csv",
                   help="the history of evaluations (CSV, user units)")
    p.add_argument("--json", default="design.json", help="the result (JSON, user units)")
    p.add_argument("--plot", default=None, help="also write the convergence plot (PNG)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=run)


def parse_vary(text: str) -> tuple[str, tuple[float, float] | None]:
    """``NAME=LO:HI`` (user units) → ``(NAME, (lo, hi) SI)``; ``NAME`` → ``(NAME, None)``."""
    name, _, rng = text.partition("=")
    name = name.strip()
    if name not in VARIABLE_UNITS:
        raise ValueError(f"--vary {text!r}: NAME must be one of {', '.join(VARIABLE_UNITS)}")
    unit, scale = VARIABLE_UNITS[name]
    if not rng:
        return name, None
    try:
        lo, hi = (float(v) for v in rng.split(":"))
    except ValueError:
        raise ValueError(f"--vary {text!r}: bounds must be LO:HI in {unit}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
        raise ValueError(f"--vary {text!r}: bounds must be finite with 0 < LO < HI ({unit})")
    return name, (lo * scale, hi * scale)


def _check(args) -> None:
    if not 8 <= args.samples <= 1_000_000:
        raise ValueError(f"--samples must be in 8..1000000, got {args.samples}")
    if not 0 <= args.check_samples <= 1_000_000:
        raise ValueError(f"--check-samples must be in 0..1000000, got {args.check_samples}")
    if not (np.isfinite(args.rail_rms_um) and 0 < args.rail_rms_um <= 1e4):
        raise ValueError(f"--rail-rms-um must be in (0, 10000] µm, got {args.rail_rms_um}")
    if not 1 <= args.max_iter <= 1000:
        raise ValueError(f"--max-iter must be in 1..1000, got {args.max_iter}")
    if args.rigid_table:
        raise ValueError("--rigid-table: a design varies the elastic table; not supported here")
    check_study(args)
    if not 1 <= args.plan_runs <= 1000:
        raise ValueError(f"--plan-runs must be in 1..1000, got {args.plan_runs}")
    if args.objective == "plan:work" and args.work_point is None:
        raise ValueError("--objective plan:work needs --work-point X,Y (mm)")
    names = [parse_vary(v)[0] for v in args.vary]
    if len(set(names)) != len(names):
        raise ValueError(f"--vary: each variable once, got {', '.join(names)}")


def measurement_plan(args, cfg, positions):
    """The :class:`~diffguide.studies.design_plan.MeasurementPlan` of ``--plan``,
    ``--plan-runs``, ``--work-point``/``--work-reads``, ``--rail-rms-um`` at ``positions`` (m)."""
    from ..planning.instruments import bundled_layout_mm
    from ..io.plan_files import read_placement_rows
    from ..studies.design_plan import MeasurementPlan
    from .plan import parse_work_point

    table = (cfg["table"]["length_mm"], cfg["table"]["width_mm"])
    rows = bundled_layout_mm(*table) if args.plan == "bundled" else read_placement_rows(
        args.plan, table)
    work = None
    if args.work_point is not None:
        wx, wy = parse_work_point(args.work_point, table)
        wq = tuple(q.strip().upper() for q in args.work_reads.split(","))
        work = (wx * 1e-3, wy * 1e-3, wq)
    try:
        return MeasurementPlan(tuple((k, x * 1e-3, y * 1e-3) for k, x, y in rows), positions,
                               runs=args.plan_runs, rail_rms=args.rail_rms_um * 1e-6,
                               work_point=work)
    except ValueError as exc:
        raise ValueError(f"--plan {args.plan}: {exc}") from None


def history_csv(res) -> str:
    """One row per evaluation (user units): variables, objective with its interval, its
    derivatives, failed samples."""
    u = 1e6
    head = ["evaluation", "iteration"]
    head += [f"{n}_{unit}" for n, unit in zip(res.variables, res.units)]
    ou = res.unit
    head += [f"objective_{ou}", f"objective_low_{ou}", f"objective_high_{ou}"]
    head += [f"d_objective_d_{n}_{ou}_per_{unit}" for n, unit in zip(res.variables, res.units)]
    head += ["failed", "stage"]
    lines = [",".join(head).replace("µ", "u").replace("%", "pct")]
    for k, r in enumerate(res.history, 1):
        cells = [str(k), str(r["iteration"])]
        cells += [f"{x / s:.8g}" for x, s in zip(r["x"], res.scales)]
        cells += [f"{v * u:.8g}" for v in (r["objective"], *r["interval"])]
        cells += [f"{g * u * s:.8g}" for g, s in zip(r["gradient"], res.scales)]
        cells += [str(r["failed"]), str(r.get("stage", 0))]
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def _est(e) -> dict | None:
    if e is None:
        return None
    return {"value": e.value * 1e6, "interval": [v * 1e6 for v in e.interval], "samples": e.n,
            "failed": e.failed}


def as_json(res) -> dict:
    """The result for ``--json`` (user units)."""
    from ..studies.design_space import CONSTRAINTS

    variables = {}
    for j, (n, unit, s) in enumerate(zip(res.variables, res.units, res.scales)):
        variables[n] = {"unit": unit, "bounds": [b / s for b in res.bounds[j]],
                        "start": res.start[j] / s, "optimum": res.optimum[j] / s,
                        "sensitivity": res.sensitivities[j] * 1e6 * s,
                        "sensitivity_unit": f"{res.unit}/{unit}"}
    cons = []
    for text, slack, active in res.constraints:
        q = CONSTRAINTS[text.split()[0]]
        cons.append({"constraint": text, "slack": slack / q.scale, "unit": q.unit,
                     "active": active})
    return {"objective": res.objective.text(), "unit": res.unit,
            "variables": variables, "before": _est(res.before), "after": _est(res.after),
            "fresh_before": _est(res.fresh_before), "fresh_after": _est(res.fresh_after),
            "improvement": _est(res.improvement), "improved": res.improved,
            "constraints": cons, "active_bounds": [list(a) for a in res.active_bounds],
            "evaluations": res.evaluations, "sample_sweeps": res.sample_sweeps,
            "samples": res.n_samples, "seed": res.seed, "fresh_seed": res.fresh_seed,
            "success": res.success, "message": res.message, "seconds": res.seconds,
            "stages": [{"stage": st["stage"], "carriage_x_mm": [v * 1e3 for v in st["carriage_x"]],
                        "rail_y_mm": [v * 1e3 for v in st["rail_y"]],
                        "optimum": [v / s for v, s in zip(st["optimum"], res.scales)],
                        "objective": st["objective"] * 1e6, "recentred": st["recentred"],
                        "message": st["message"]} for st in res.stages]}


def report(res) -> str:
    """The result in words (user units)."""
    ou = res.unit

    def est(e):
        return f"{e.value * 1e6:.4g} {ou} (95 % interval {e.interval[0] * 1e6:.4g} .. " \
               f"{e.interval[1] * 1e6:.4g})"

    what = f"{res.n_samples} samples" if res.n_samples else "deterministic, no random rails"
    lines = [f"design for minimum {res.objective.text()} ({what}, "
             f"{res.evaluations} evaluations, {res.seconds:.0f} s; SLSQP: {res.message})"]
    for j, (n, unit, s) in enumerate(zip(res.variables, res.units, res.scales)):
        lines.append(f"  {n}: {res.start[j] / s:.5g} -> {res.optimum[j] / s:.5g} {unit} "
                     f"(bounds {res.bounds[j][0] / s:.5g} .. {res.bounds[j][1] / s:.5g}; "
                     f"d objective/d {n} = {res.sensitivities[j] * 1e6 * s:.4g} {ou}/{unit})")
    if res.n_samples:
        lines.append(f"  objective on the optimisation samples: {est(res.before)} -> "
                     f"{est(res.after)}")
    else:
        lines.append(f"  objective: {res.before.value * 1e6:.4g} -> {res.after.value * 1e6:.4g} "
                     f"{ou} (improvement {res.improvement.value * 1e6:.4g} {ou}, exact)")
    for text, slack, active in res.constraints:
        lines.append(f"  constraint {text}: {'active' if active else 'inactive'} "
                     f"(slack {slack:.4g} SI)")
    for n, side in res.active_bounds:
        lines.append(f"  {n} at its {side} bound")
    if len(res.stages) > 1:
        lines.append(f"  re-centrings of the mesh: {sum(st['recentred'] for st in res.stages)}; "
                     "the optimum on its own mesh")
    if res.fresh_before is not None:
        if res.improved:
            verdict = "improved (beyond its interval)"
        elif res.improvement.interval[1] < 0:
            verdict = ("worse than the start beyond its interval (the start breaks a "
                       "constraint, or the optimisation samples are too few: more --samples)")
        else:
            verdict = ("NOT improved beyond its interval: more --samples/--check-samples, or "
                       "the start is already near the optimum")
        lines.append(f"on {res.fresh_before.n} fresh samples (seed {res.fresh_seed}): start "
                     f"{est(res.fresh_before)}, optimum {est(res.fresh_after)}; improvement "
                     f"{est(res.improvement)}: {verdict}")
    return "\n".join(lines)


def run(args) -> int:
    from ..io.atomic import atomic_savefig, atomic_write_text  # here: --help imports no JAX

    _check(args)
    if args.cpu_devices is None or args.cpu_devices > 1:
        split_cpu_into_devices(args.cpu_devices)  # before the first array; no-op afterwards
    from ..machine.build import with_overrides
    from ..studies.design import design, parse_objective
    from ..studies.design_space import parse_constraint
    from ._common import machine_config
    from ..jobs.positions import default_positions, parse_positions
    from ..jobs.study import KERNELS as _KERNELS
    from ..jobs.study import PLANES as _PLANES
    from ._common import parse_mesh_text as parse_mesh

    objective = parse_objective(args.objective)  # malformed input fails before any solve
    if objective.measure != "plan" and args.work_point is not None:
        raise ValueError("--work-point is read only with --objective plan:work")
    constraints = [parse_constraint(c) for c in args.constraint or ()]
    varied = [parse_vary(v) for v in args.vary]
    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    cfg = machine_config(args)
    if cfg.get("table_source"):
        raise ValueError(f"{args.config}: the table is imported from "
                         f"{cfg['table_source']['given']} (source = \"superelement\"): a design "
                         "varies the plate and the layout, which an imported matrix fixes; "
                         "design on the plate model, then reduce the chosen design in your FE code")
    positions = default_positions(cfg) if args.positions is None else parse_positions(
        args.positions)
    half = cfg["machine"]["stroke_mm"] / 2
    if np.max(np.abs(positions)) * 1e3 > half + 1e-9:
        raise ValueError(f"--positions must lie within the ±{half:g} mm stroke of "
                         f"{args.config or args.preset}, got {args.positions!r}")
    from ..io.config import spec_from_config

    nx, ny = parse_mesh(args.mesh) if args.mesh else (None, None)
    spec = with_overrides(spec_from_config(cfg), nx=nx, ny=ny)
    say(f"design of {args.config or args.preset} (mesh {args.mesh or 'of the machine file'}): "
        f"{objective.text()} over "
        f"{', '.join(n for n, _ in varied)}; "
        + (f"the {args.plan} plan" if objective.measure == "plan" else f"{args.samples} samples")
        + f" x {len(positions)} positions per evaluation (the first compiles)")
    res = design(
        spec, positions, variables=[n for n, _ in varied], bounds=[b for _, b in varied],
        objective=objective, constraints=constraints, rail_rms=args.rail_rms_um * 1e-6,
        correlation_length=args.corr_mm * 1e-3, kernel=_KERNELS[args.kernel],
        planes=_PLANES[args.planes], mounting=None if args.mounting == "none" else args.mounting,
        n_samples=args.samples, check_samples=args.check_samples, seed=args.seed,
        chunk_size=args.chunk, max_iterations=args.max_iter, progress=say,
        plan=measurement_plan(args, cfg, positions) if objective.measure == "plan" else None)
    if not args.quiet:
        print(report(res))
    atomic_write_text(args.out, history_csv(res))
    atomic_write_text(args.json, json.dumps(as_json(res), indent=2) + "\n")
    say(f"wrote {args.out}, {args.json}")
    if args.plot:
        from ..plotting import figure_of
        from ..plotting.design import plot_design_convergence

        fig = figure_of(plot_design_convergence(res, f"{args.config or args.preset}: "
                                                     f"{objective.text()}"))
        atomic_savefig(fig, args.plot, dpi=110)
        say(f"wrote {args.plot}")
    return 0
