"""``diffguide plan``: where to put the instruments so that the data determine the rails."""

import argparse
import json
import time

import numpy as np

from ._common import say

#: What each kind reads: :data:`diffguide.planning.KINDS`, restated so that parsing the
#: command line does not import JAX (a test asserts they agree).
QUANTITY_CHOICES = {
    "level": ("EBX", "EAX"),
    "interferometer": ("EBX", "ECX"),
    "straightness": ("EYX", "EZX"),
}


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
            default=",".join(QUANTITY_CHOICES[kind]),
            metavar="Q[,Q]",
            help=f"what one {kind} reads, among {','.join(QUANTITY_CHOICES[kind])} (default both)",
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
        choices=("worst", "A", "D", "work"),
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


def _table_mm(cfg) -> tuple[float, float]:
    return cfg["table"]["length_mm"], cfg["table"]["width_mm"]


def _sites(args, cfg) -> dict:
    """Candidate sites ``{name: (x, y)}`` (m): ``--sites`` or the ``--grid``."""
    from ..planning.instruments import grid_sites
    from ..io.plan_files import read_sites
    from ._common import parse_mesh_text

    if args.sites:
        return read_sites(args.sites, _table_mm(cfg))
    if cfg.get("table_source"):  # an imported table knows only its retained points
        from ..io.table_source import retained_points

        return retained_points(cfg)
    try:
        nx, ny = parse_mesh_text(args.grid, most=400)
    except ValueError:
        raise ValueError(
            f"--grid must be NXxNY with integers >= 1, e.g. 7x3, got {args.grid!r}"
        ) from None
    if nx * ny > 400:
        raise ValueError(f"--grid {args.grid}: at most 400 sites")
    return grid_sites(cfg["table"]["length_mm"] * 1e-3, cfg["table"]["width_mm"] * 1e-3, nx, ny)


def _start_and_compare(args, cfg, sites):
    """``--start`` and the plan to compare with (``--compare``; by default the ``--start`` plan
    where given, else the bundled layout) as ``(kind, site)``, adding their sites to ``sites``
    where new."""
    from ..io.plan_files import read_placements

    table = _table_mm(cfg)
    start = [] if args.start is None else read_placements(args.start, "--start", table, sites)
    which = args.compare if args.compare is not None else (args.start or "bundled")
    compare = None if which == "none" else read_placements(which, "--compare", table, sites)
    return start, compare


def parse_work_point(text: str, table_mm) -> tuple[float, float]:
    """``--work-point X,Y`` (mm), checked to lie on the ``table_mm = (length, width)`` top."""
    from ..planning.instruments import check_on_table

    try:
        wx, wy = (float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--work-point must be X,Y (mm), got {text!r}") from None
    check_on_table("work point", wx, wy, table_mm, "--work-point")
    return wx, wy


def _work_point(args, cfg, sites):
    """``("WORK", quantities)`` from ``--work-point``/``--work-reads`` (the site added to
    ``sites``), or None."""
    if args.work_point is None:
        return None
    wx, wy = parse_work_point(args.work_point, _table_mm(cfg))
    wq = tuple(q.strip().upper() for q in args.work_reads.split(","))
    bad = [q for q in wq if q not in ("EYX", "EZX", "EAX", "EBX", "ECX")]
    if bad or not wq:
        raise ValueError(f"--work-reads must be among EYX,EZX,EAX,EBX,ECX, got {args.work_reads!r}")
    sites["WORK"] = (wx * 1e-3, wy * 1e-3)
    return ("WORK", wq)


def _instruments(args):
    from ..planning import Instrument

    out = []
    for kind, count, sig, reads in (
        ("level", args.levels, args.level_sigma_urad * 1e-6, args.level_reads),
        (
            "interferometer",
            args.interferometers,
            args.interferometer_sigma_urad * 1e-6,
            args.interferometer_reads,
        ),
        (
            "straightness",
            args.straightness,
            args.straightness_sigma_um * 1e-6,
            args.straightness_reads,
        ),
    ):
        if not 0 <= count <= 50:
            raise ValueError(f"the number of {kind}s must be in [0, 50], got {count}")
        if not (np.isfinite(sig) and sig > 0):
            raise ValueError(f"the {kind} reading σ must be > 0, got {sig * 1e6:g}")
        q = tuple(s.strip().upper() for s in reads.split(",") if s.strip())
        bad = [x for x in q if x not in QUANTITY_CHOICES[kind]]
        if not q or bad:
            raise ValueError(
                f"--{kind}-reads: a {kind} reads "
                f"{' and/or '.join(QUANTITY_CHOICES[kind])}, got {reads!r}"
            )
        out.append(Instrument(kind, count, q, sig))
    if sum(i.count for i in out) == 0:
        raise ValueError(
            "no instruments to place (--levels, --interferometers, --straightness are all 0)"
        )
    return out


def _check(args):
    if not 4 <= args.positions <= 1000:
        raise ValueError(f"--positions must be in [4, 1000], got {args.positions}")
    if not 1 <= args.runs <= 1000:
        raise ValueError(f"--runs must be in [1, 1000], got {args.runs}")
    if not (np.isfinite(args.rail_rms_um) and 0 < args.rail_rms_um <= 1000):
        raise ValueError(f"--rail-rms-um must be in (0, 1000] µm, got {args.rail_rms_um}")
    if not 1 <= args.draws <= 100:
        raise ValueError(f"--draws must be in [1, 100], got {args.draws}")
    if args.criterion == "work" and args.work_point is None:
        raise ValueError("--criterion work needs --work-point X,Y (mm)")


def _family(args, cfg, spec, sites, n_candidates, instruments):
    """The machine family over ``sites`` (structure unknown as ``diffguide fit`` has it, or as
    the options say) and its priors, after a line saying what is planned."""
    from ..inverse import MachineFamily
    from ..jobs.machine import config_machine
    from ..jobs.fit import structure_priors

    priors = structure_priors(
        argparse.Namespace(
            structure=args.structure,
            criterion=None,
            thickness_prior_mm=args.thickness_prior_mm,
            preload_prior=args.preload_prior,
            stiffness_prior=args.stiffness_prior,
        ),
        cfg,
    )

    def make_machine(**kw):
        return config_machine(cfg, nx=args.nx, ny=args.ny, points=sites, **kw)

    kinds = ", ".join(
        f"{i.count} {i.kind}(s) reading {'+'.join(i.quantities)}" for i in instruments if i.count
    )
    say(
        args,
        f"plan: {n_candidates} candidate sites, {kinds}"
        f"; {args.positions} positions x {args.runs} runs"
        + ("" if args.unidirectional else " x 2 directions"),
    )
    return MachineFamily.build(make_machine, priors, progress=lambda t: say(args, t)), priors


def run(args) -> int:
    from ..planning import plan
    from ..io.config import spec_from_config
    from ..io.plan_files import plan_csv, plan_report
    from ._common import machine_config
    from ._outputs import write_dir
    from ..io.report_text import jsonable as _jsonable

    t_start = time.perf_counter()
    _check(args)
    cfg = machine_config(args)
    spec = spec_from_config(cfg)
    instruments = _instruments(args)
    sites = _sites(args, cfg)
    candidates = tuple(sites)
    start, compare = _start_and_compare(args, cfg, sites)
    used = {k for k, _ in (compare or []) + start}
    instruments = [i for i in instruments if i.count > 0 or i.kind in used]
    work = _work_point(args, cfg, sites)
    family, priors = _family(args, cfg, spec, sites, len(candidates), instruments)
    half = cfg["machine"]["stroke_mm"] / 2
    result = plan(
        family,
        np.linspace(-half, half, args.positions) * 1e-3,
        instruments=instruments,
        criterion=args.criterion,
        compare=compare,
        start=start,
        rail_rms=args.rail_rms_um * 1e-6,
        runs=args.runs,
        bidirectional=not args.unidirectional,
        candidates=candidates,
        work_point=work,
        progress=lambda t: say(args, t),
        n_draws=args.draws,
    )
    say(
        args,
        f"plan: worst profile σ {result.best.worst * 1e6:.3f} µm"
        + (f" (your plan: {result.compare.worst * 1e6:.3f} µm)" if compare else "")
        + f", prior only {result.prior.worst * 1e6:.3f} µm; {result.seconds:.1f} s",
    )
    settings = {
        "command": "diffguide plan",
        "preset": None if args.config else args.preset,
        "config": args.config,
        "mesh": args.mesh,  # None: the machine's default table mesh
        "rail_rms_um": args.rail_rms_um,
        "positions": args.positions,
        "runs": args.runs,
        "directions": 1 if args.unidirectional else 2,
        "structure": "estimate" if priors.active() else "fixed",
        "draws": args.draws,
    }
    report = plan_report(result, sites, start, compare, settings)
    files = {"plan.csv": plan_csv(result)}
    if not args.no_plots:
        files.update(_figures(result, cfg, compare))
    report["total_seconds"] = time.perf_counter() - t_start
    files["report.json"] = json.dumps(_jsonable(report), indent=1, allow_nan=False) + "\n"
    write_dir(args, "plan", files)
    say(args, f"wrote {args.out}/ ({', '.join(files)}) in {time.perf_counter() - t_start:.1f} s")
    return 0


def _figures(result, cfg, compare):
    from ..plotting import figure_of
    from ..plotting.plan import plot_plan_sigma, plot_plan_sites

    ax = plot_plan_sites(
        result.sites,
        result.candidates,
        result.placements,
        compare=compare or (),
        table_mm=(cfg["table"]["length_mm"], cfg["table"]["width_mm"]),
        rails_y_mm=cfg["guideway"]["rail_y_mm"],
        carriages_x_mm=cfg["guideway"]["carriage_x_mm"],
        title=f"measurement plan ({result.criterion}): worst profile σ "
        f"{result.best.worst * 1e6:.2f} µm"
        + (f", your plan {result.compare.worst * 1e6:.2f} µm" if compare else ""),
    )
    sig = {"plan": result.best.sigma}
    if compare:
        sig["your plan"] = result.compare.sigma
    sig["prior only"] = result.prior.sigma
    axes = plot_plan_sigma(
        result.best.s,
        sig,
        background=("prior only",),
        title="predicted σ of the rail profiles (mean and common slope removed)",
    )
    return {"plan.png": figure_of(ax), "sigma.png": figure_of(axes)}
