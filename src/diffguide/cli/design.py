"""``diffguide design``: the machine layout that minimises an error statistic over random rails,
within bounds and constraints (:func:`diffguide.jobs.design_job` does the work; this module
parses and prints)."""

import argparse
import sys

from ._common import add_machine_arguments
from ._study_options import add_study_arguments, split_cpu_into_devices


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


def settings_from_args(args):
    """The :class:`diffguide.jobs.DesignSettings` of the parsed options (checked there)."""
    from ..jobs import DesignSettings

    return DesignSettings(**{k: getattr(args, k) for k in DesignSettings.fields()
                             if hasattr(args, k)})


def run(args) -> int:
    settings = settings_from_args(args)
    if args.cpu_devices is None or args.cpu_devices > 1:
        split_cpu_into_devices(args.cpu_devices)  # before the first array; no-op afterwards
    from ..jobs import design_job

    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    res = design_job(settings, progress=say)
    if not args.quiet:
        print(report(res.result))
    written = res.write()
    say(f"wrote {', '.join(written[:2])}")
    if len(written) > 2:
        say(f"wrote {written[2]}")
    return 0
