"""``diffguide plan``: where to put the instruments so that the data determine the rails
(:func:`diffguide.jobs.plan_job` does the work; this module parses and prints)."""

import argparse
import time

from ..jobs.plan import CRITERIA, KIND_READS
from ._common import say


def add_parser(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "plan",
        help="plan a measurement: which instruments where on the table, for the smallest "
        "predicted profile σ",
        description="Choose where to place levels, angular interferometers and straightness "
        "optics on the table so that the fit determines the rails (and the table's thickness and "
        "preload) best: the posterior of the linearised fit is predicted for every candidate "
        "placement (one forward-mode Jacobian of the machine model), with a prior from the "
        "expected rail RMS, and placements are added greedily, each the one that lowers the "
        "criterion most. Output folder (written atomically): plan.csv (the chosen placements "
        "in order, what each bought), report.json (the plan, the user's plan for comparison, "
        "profile σ, structure identifiability, the prior's lambda to pass to 'diffguide fit "
        "--lambda'), plan.png (table top), sigma.png (profile σ along the rails). Sites CSV: "
        "name,x_mm,y_mm. Compare CSV: instrument,point,x_mm,y_mm (instrument: level, "
        "interferometer or straightness), or 'bundled' (levels at the four corners 50 mm "
        "inside the edges, an interferometer at the centre).",
    )
    _add_machine_arguments(p)
    _add_instrument_arguments(p)
    _add_site_arguments(p)
    _add_experiment_arguments(p)
    _add_structure_arguments(p)
    p.set_defaults(func=run)
    return p


def _add_machine_arguments(p) -> None:
    """The machine and the output folder."""
    p.add_argument(
        "--preset",
        default="majda2012",
        choices=("majda2012",),
        help="machine model (majda2012: 1000 x 500 mm table)",
    )
    p.add_argument(
        "--config",
        metavar="MACHINE.toml",
        help="machine configuration file (TOML); overrides --preset",
    )
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output folder: new, empty, or an earlier output of this "
                   "command (replaced); any other non-empty folder, or '.', is refused")


def _add_instrument_arguments(p) -> None:
    """Per instrument kind: how many, the σ of one reading, what it reads."""
    for kind, n, sig, unit in (
        ("level", 4, 4.0, "urad"),
        ("interferometer", 1, 2.0, "urad"),
        ("straightness", 0, 1.0, "um"),
    ):
        flag = (
            "interferometers"
            if kind == "interferometer"
            else ("levels" if kind == "level" else "straightness")
        )
        p.add_argument(
            f"--{flag}", type=int, default=n, metavar="N", help=f"{kind}s available (default {n})"
        )
        p.add_argument(
            f"--{kind}-sigma-{unit}",
            type=float,
            default=sig,
            metavar="SIGMA",
            help=f"σ of one {kind} reading ({'µm/m' if unit == 'urad' else 'µm'}; default {sig:g})",
        )
        p.add_argument(
            f"--{kind}-reads",
            default=",".join(KIND_READS[kind]),
            metavar="Q[,Q]",
            help=f"what one {kind} reads, among {','.join(KIND_READS[kind])} (default both)",
        )


def _add_site_arguments(p) -> None:
    """Candidate sites, placements already decided, the plan to compare with."""
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--grid",
        default="7x3",
        metavar="NXxNY",
        help="candidate sites: an NX x NY grid over the table top, 50 mm inside the "
        "edges (default 7x3)",
    )
    g.add_argument("--sites", metavar="SITES.csv", help="candidate sites: name,x_mm,y_mm")
    p.add_argument(
        "--start",
        metavar="PLAN.csv|bundled",
        default=None,
        help="placements already decided (same format as --compare; the layout.csv that "
        "'diffguide fit' writes works as it is): kept, and the instruments of --levels, "
        "--interferometers, --straightness are added to them (default: none, plan from scratch)",
    )
    p.add_argument(
        "--compare",
        metavar="PLAN.csv|bundled",
        default=None,
        help="a plan to compare with (default: the --start plan where given, else bundled); "
        "'none' for no comparison",
    )


def _add_experiment_arguments(p) -> None:
    """Positions, runs, the prior's expected rail RMS and the criterion."""
    p.add_argument(
        "--positions",
        type=int,
        default=36,
        metavar="N",
        help="table positions read, evenly over the stroke (default 36)",
    )
    p.add_argument("--runs", type=int, default=5, help="runs per direction (default 5)")
    p.add_argument(
        "--unidirectional",
        action="store_true",
        help="forward runs only (default: forward and backward)",
    )
    p.add_argument(
        "--rail-rms-um",
        type=float,
        default=1.0,
        help="expected RMS of the rail profiles (µm; default 1): sets the prior",
    )
    p.add_argument(
        "--criterion",
        choices=CRITERIA,
        default="worst",
        help="worst: largest profile σ (default); A: RMS profile σ; D: log det of "
        "the posterior covariance; work: largest σ of the errors at --work-point",
    )
    p.add_argument(
        "--work-point", metavar="X,Y", default=None, help="work point (mm) for --criterion work"
    )
    p.add_argument(
        "--work-reads",
        default="EAX,EBX,ECX",
        metavar="Q[,Q]",
        help="errors predicted at the work point (default EAX,EBX,ECX)",
    )


def _add_structure_arguments(p) -> None:
    """The structure's unknowns and priors, the prior draws, the figures."""
    p.add_argument(
        "--structure",
        choices=("estimate", "fixed"),
        default=None,
        help="table thickness and preload unknown, as 'diffguide fit' estimates them "
        "(default, or the configuration's [fit] section), or known",
    )
    p.add_argument(
        "--thickness-prior-mm",
        metavar="VALUE,LO,HI",
        default=None,
        help="as 'diffguide fit' (default: the machine's, [0.5, 2] times it)",
    )
    p.add_argument(
        "--preload-prior",
        metavar="VALUE,LO,HI",
        default=None,
        help="as 'diffguide fit' (default: the machine's, [0.25, 2] times it)",
    )
    p.add_argument(
        "--stiffness-prior",
        metavar="VALUE,LO,HI",
        default=None,
        help="as 'diffguide fit': a table imported from an FE model (default: the file's "
        "[fit] stiffness_prior, else 1,0.5,2)",
    )
    p.add_argument(
        "--draws",
        type=int,
        default=8,
        help="prior rail draws at which the experiment is linearised (default 8)",
    )
    p.add_argument("--no-plots", action="store_true", help="do not write the PNG figures")


def settings_from_args(args):
    """The :class:`diffguide.jobs.PlanSettings` of the parsed options (checked there)."""
    from ..jobs import PlanSettings

    return PlanSettings(**{k: getattr(args, k) for k in PlanSettings.fields() if hasattr(args, k)})


def run(args) -> int:
    from ..jobs import plan_job
    from ._interrupt import checkpoint

    t_start = time.perf_counter()
    res = plan_job(settings_from_args(args), progress=lambda t: say(args, t))
    written = res.write(args.out, checkpoint=checkpoint)
    say(args, f"wrote {args.out}/ ({', '.join(written)}) in {time.perf_counter() - t_start:.1f} s")
    return 0
