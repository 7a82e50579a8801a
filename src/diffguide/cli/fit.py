"""``diffguide fit``: rail straightness profiles from measured pitch, yaw, roll."""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from ._common import check_tolerances, say
from ._export_options import FORMATS as EXPORT_FORMATS
from ._export_options import (
    AXIS_SIDE_HELP,
    FORMAT_HELP,
    add_controller_options,
    check_export,
    export_spec,
)

PRESETS = ("majda2012",)
#: Exit code when the results are written but the elastic fit did not converge.
EXIT_NOT_CONVERGED = 3


def add_parser(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "fit",
        help="identify rail straightness profiles (µm) from measured joint errors (CSV)",
        description="Fit the vertical and horizontal straightness profiles of both rails - and "
        "the table's equivalent thickness (for a table imported from an FE model, a scale on "
        "its stiffness) and the preload, which nobody knows - to measured "
        "joint kinematic errors (levels, interferometers) through the elastic machine model, by "
        "regularised Levenberg-Marquardt (marginal-likelihood weight), with posterior ±σ bands "
        "that include the structure's uncertainty and an identifiability report (with --rigid, "
        "the classical rigid-table inversion side by side). Input CSV: position_mm,point,x_mm,"
        "y_mm,quantity,"
        "value,unit[,sigma][,run][,direction][,instrument][,z_mm] (positions and points in mm; "
        "values in µm, mm, nm, in, µm/m, mm/m, µrad, mrad, arcsec, arcmin or deg). Output "
        "folder (written atomically): rails.csv (and rails_rigid.csv with --rigid) "
        "(rail,s_mm,vertical_um,vertical_sigma_um,horizontal_um,horizontal_sigma_um), fit.csv "
        "(every input row with fitted and residual, in its unit), layout.csv (the measured "
        "layout, for 'diffguide plan --start'), report.json, report.html (the metrologist's "
        "report: straightness per rail with its 95 % interval, verdict, figures; one "
        "self-contained file), "
        "posterior.json (the posterior, for 'diffguide predict'), "
        "profiles.png, curves.png. Exit codes: 0 converged; 3 results written but the fit did "
        "not converge (flagged in report.json); 2 bad input or options (nothing written).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--preset", default="majda2012", choices=PRESETS,
                   help="machine model (majda2012: 1000 x 500 mm table, rails 340 mm apart)")
    p.add_argument("--measurements", required=True, action="append", metavar="FILE.csv",
                   help="measurement file (see above); repeat it for several files, merged into "
                   "one data set (each reading keeps its file; a point at two places, a "
                   "channel at two heights, or one file twice - by another path, a link or a "
                   "copy - is refused naming both files)")
    p.add_argument("--measurements-format", dest="layout", choices=("auto", "long", "wide"),
                   default="auto",
                   help="layout of --measurements: long (one reading per row), wide (targets x "
                   "runs, ISO 230-2 style) or auto (detected; see 'diffguide import')")
    from .import_ import add_input_options

    add_input_options(p, " of all the files")
    p.add_argument("--machine-x0-mm", type=float, default=None,
                   help="machine coordinate (mm) of the table position x = 0 in the "
                   "compensation table (--export-compensation): X = x + machine x0; default: "
                   "the measurements' x0 (the table in the coordinates of the file)")
    p.add_argument("--allow-many-positions", action="store_true",
                   help="merge a file with more than 1000 distinct table positions (refused "
                   "otherwise: thousands, nearly one per reading, is what swapped position and "
                   "value columns look like)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output folder: new, empty, or an earlier output of this "
                   "command (replaced); any other non-empty folder, or '.', is refused")
    p.add_argument("--knot-spacing-mm", type=float, default=None,
                   help="B-spline knot spacing of the profiles (mm); default: the carriage's "
                   "loaded length (48 mm for majda2012)")
    p.add_argument("--lambda", dest="lam", type=float, default=None,
                   help="fixed smoothness weight instead of the chosen one (whitened units, as "
                   "report.json's 'lambda')")
    p.add_argument("--max-steps", type=int, default=60,
                   help="Levenberg-Marquardt step limit per pass (default 60); when it is reached "
                   "the best estimate so far is written, flagged as not converged (exit 3)")
    p.add_argument("--criterion", choices=("ml", "gcv"), default=None,
                   help="how the smoothness weight is chosen: marginal likelihood (default) or "
                   "generalised cross-validation; default: the config's [fit] criterion, else ml")
    p.add_argument("--structure", choices=("estimate", "fixed"), default=None,
                   help="estimate the table's equivalent thickness and the preload with the rails "
                   "(default), or hold them at the machine's values; default: the config's "
                   "[fit] structure, else estimate")
    p.add_argument("--thickness-prior-mm", metavar="VALUE,LO,HI", default=None,
                   help="prior of the equivalent plate thickness (mm): a value and a plausible "
                   "range (read as ±2σ of a log-normal prior); default: the config's [fit] "
                   "thickness_prior_mm, else the machine's thickness and [0.5, 2] times it")
    p.add_argument("--preload-prior", metavar="VALUE,LO,HI", default=None,
                   help="prior of the preload (fraction of C), as for the thickness; default: the "
                   "config's [fit] preload_prior, else the machine's preload and [0.25, 2] "
                   "times it")
    p.add_argument("--stiffness-prior", metavar="VALUE,LO,HI", default=None,
                   help="a table imported from an FE model ([table] source = \"superelement\") "
                   "has no thickness: the fit estimates a scale on its stiffness instead, with "
                   "this prior (read as ±2σ of a log-normal prior); default: the config's [fit] "
                   "stiffness_prior, else 1,0.5,2")
    p.add_argument("--rail-waviness-um", type=float, default=None, metavar="RMS",
                   help="RMS (µm) of the rails' short-wave content, shorter than about two knot "
                   "spacings, which the carriages average out and the data cannot show (state "
                   "it from the rails' grade): added in quadrature to every profile σ; default: "
                   "the config's [fit] rail_waviness_um, else 0 (the bands cover only what the "
                   "knots resolve)")
    p.add_argument("--rail-joints-mm", type=_joints_mm, default=None, metavar="S[,S...]",
                   help="where the rails are joined (mm along the rail, as rails.csv's s_mm): "
                   "each profile gains a step there, its height fitted and "
                   "reported; a step the knots cannot hold otherwise rings over several knot "
                   "spacings; default: the config's [fit] rail_joints_mm, else none")
    p.add_argument("--rigid", dest="rigid", action="store_const", const=True, default=None,
                   help="also run the classical rigid-table inversion (rails_rigid.csv, its "
                   "columns in fit.csv and report.json, a dashed curve in the plots); it costs "
                   "a second compilation, 3-6 s; default: the config's [fit] rigid, else off")
    p.add_argument("--no-rigid", dest="rigid", action="store_const", const=False,
                   help="no rigid-table inversion (the default; overrides [fit] rigid = true)")
    p.add_argument("--no-plots", action="store_true", help="do not write the PNG figures")
    p.add_argument("--tolerance-um", type=float, default=None, metavar="T",
                   help="straightness tolerance (µm) of every rail and plane over the measured "
                   "length: report.html, report.json and the console judge each straightness "
                   "(least-squares line, ISO 230-1) with its U (k = 2) by ISO 14253-1: pass if "
                   "value + U <= T, fail if value - U > T, otherwise not decidable")
    p.add_argument("--truth", metavar="FILE.csv", default=None,
                   help="known profiles (rail,s_mm,vertical_um,horizontal_um) to score the "
                   "fits against, e.g. data/majda2012_truth.csv")
    p.add_argument("--config", metavar="MACHINE.toml",
                   help="machine configuration file (TOML; see 'diffguide config'); overrides "
                   "--preset")
    p.add_argument("--export-compensation", metavar="FILE",
                   help="write a compensation table predicted by the fitted model for the point "
                   "--at over the stroke, in machine coordinates (X = x + --machine-x0-mm), "
                   "with σ (a column, or FILE's companion .sigma.csv); see --format")
    p.add_argument("--format", dest="comp_format", default="csv",
                   choices=EXPORT_FORMATS, help=FORMAT_HELP)
    p.add_argument("--axis-side", default=None, metavar="SIDE", help=AXIS_SIDE_HELP)
    add_controller_options(p)
    p.add_argument("--comp-points", type=int, default=71,
                   help="equidistant positions of the compensation table over the stroke "
                   "(default 71)")
    p.add_argument("--at", default="P5",
                   help="point of the compensation table: a measured point or a machine "
                   "control point (P1..P5 for majda2012)")
    p.add_argument("--at-z-mm", type=float, default=0.0, metavar="Z",
                   help="height of the compensated point above the table top (mm; the tool "
                   "point): EXX gains z·EBX and EYX −z·EAX, with their σ (default 0)")
    p.add_argument("--tol-um", type=float, default=2.0,
                   help="warn where another point's EXX/EYX/EZX depart from the rigid-body "
                   "prediction from --at by more than this (µm)")
    p.add_argument("--tol-urad", type=float, default=5.0,
                   help="warn where another point's EAX/EBX/ECX depart from --at's by more (µrad)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=run, figure_worker=True)
    return p


def _check_inputs(meas, args, cfg):
    """Points, positions and options checked against the machine actually used."""
    from ..inverse.merge import POSITION_TOL

    name = args.config or args.preset
    half_l, half_w = cfg["table"]["length_mm"] / 2e3, cfg["table"]["width_mm"] / 2e3
    for pname, (x, y) in zip(meas.point_names, meas.points_xy):
        if abs(x) > half_l or abs(y) > half_w:
            raise ValueError(
                f"{meas.source}: point {pname!r} at ({x * 1e3:g}, {y * 1e3:g}) mm is off the "
                f"{name} table (|x| <= {half_l * 1e3:g}, |y| <= {half_w * 1e3:g} mm)")
    stroke = cfg["machine"]["stroke_mm"] * 1e-3
    bad = np.abs(meas.position) > stroke / 2 + POSITION_TOL
    if bad.any():
        x = meas.position[bad][0]
        x0 = getattr(args, "input_info", {}).get("x0_mm", 0.0)
        raise ValueError(f"{meas.source}: position {x * 1e3:.4f} mm is outside the {name} "
                         f"stroke (±{stroke / 2 * 1e3:g} mm, to {POSITION_TOL * 1e6:g} µm; "
                         f"x = X − x0 with x0 = {x0:g} mm: "
                         "for positions in machine coordinates give --x0-mm, the machine "
                         "coordinate of mid-stroke, or --x0-mm middle)")
    if len(np.unique(np.round(meas.position, 9))) < 4:
        raise ValueError(f"{meas.source}: at least 4 distinct positions are needed for a fit")
    if args.knot_spacing_mm is not None and not (1.0 <= args.knot_spacing_mm <= 1000.0):
        raise ValueError(f"--knot-spacing-mm must be in [1, 1000] mm, got {args.knot_spacing_mm}")
    if not 0 <= args.max_steps <= 10000:
        raise ValueError(f"--max-steps must be an integer in [0, 10000], got {args.max_steps}")
    if args.lam is not None and not (np.isfinite(args.lam) and args.lam > 0):
        raise ValueError(f"--lambda must be a finite number > 0, got {args.lam}")
    w = args.rail_waviness_um
    if w is not None and not (np.isfinite(w) and 0.0 <= w <= 100.0):
        raise ValueError(f"--rail-waviness-um must be an RMS in [0, 100] µm, got {w}")
    for name in ("nx", "ny"):
        v = getattr(args, name)
        if v is not None and not 1 <= v <= 200:
            raise ValueError(f"--{name} must be an integer in [1, 200], got {v}")
    if args.export_compensation:  # checked here: a refusal after the fit would follow output
        points = list(dict.fromkeys([*cfg["points"], *meas.point_names]))
        if args.at not in points:
            raise ValueError(f"--at must be one of the points {', '.join(points)}, "
                             f"got {args.at!r}")
        if not 2 <= args.comp_points <= 10000:
            raise ValueError(f"--comp-points must be in [2, 10000], got {args.comp_points}")
        if not (np.isfinite(args.at_z_mm) and -500.0 <= args.at_z_mm <= 2000.0):
            raise ValueError(f"--at-z-mm must be in [-500, 2000] mm, got {args.at_z_mm:g}")
        check_tolerances(args)
        _check_export_options(args, cfg)
        _check_lead_for_fanuc(args, meas)
    from ._report import check_tolerance

    check_tolerance(args)


def read_truth(path, s_m):
    """Truth profiles ``(2, 2, len(s))`` (m) at ``s`` (m) from a rails CSV
    (:func:`diffguide.io.rails_csv.rails_at`: the reader of ``simulate --rails``)."""
    from ..io.rails_csv import rails_at

    return rails_at(path, s_m)


def _joints_mm(text: str) -> tuple[float, ...]:
    """``--rail-joints-mm``: comma-separated finite positions (mm)."""
    try:
        out = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected positions in mm separated by commas (e.g. 137,637), got {text!r}"
        ) from None
    if not all(np.isfinite(v) for v in out):
        raise argparse.ArgumentTypeError(f"rail joints must be finite (mm), got {text!r}")
    return out


def _settings(args, cfg):
    """The fit's settings (:mod:`diffguide.inverse.settings`): ``(structure, criterion,
    waviness (m), rigid)`` from the flags, else the configuration's ``[fit]`` section."""
    from ..inverse import settings

    structure, criterion = settings.fit_modes(cfg, args.structure, args.criterion)
    return (structure, criterion, settings.rail_waviness(cfg, args.rail_waviness_um),
            settings.rigid_wanted(cfg, args.rigid))


def structure_priors(args, cfg):
    """The structural priors of the flags ``--structure``, ``--thickness-prior-mm``,
    ``--preload-prior`` and the configuration (:func:`diffguide.inverse.settings.
    structure_priors`)."""
    from ..inverse.settings import structure_priors as priors

    return priors(cfg, structure=args.structure, thickness_prior_mm=args.thickness_prior_mm,
                  preload_prior=args.preload_prior,
                  stiffness_prior=getattr(args, "stiffness_prior", None))


def _jsonable(obj):
    """Plain JSON types (:func:`diffguide.io.fit_report.jsonable`; imported when called, so
    that ``--help`` does not load the library)."""
    from ..io.fit_report import jsonable

    return jsonable(obj)


def run(args) -> int:
    from ..inverse import MachineFamily
    from ..io.config import spec_from_config
    from ..io.fit_files import profile_grid
    from ..io.table_source import config_machine
    from ._common import machine_config

    t_start = time.perf_counter()
    cfg = machine_config(args)
    spec = spec_from_config(cfg)
    info: dict = {}
    meas, priors = _read(args, cfg, info)
    points = {n: tuple(map(float, xy)) for n, xy in zip(meas.point_names, meas.points_xy)}

    def make_machine(**kw):
        return config_machine(cfg, nx=args.nx, ny=args.ny, points=points, **kw)

    family = MachineFamily.build(make_machine, priors, progress=lambda t: say(args, t))
    fits, seconds = _fit_all(args, cfg, family, meas)
    elastic = fits[""]
    s_m = profile_grid(elastic.basis)
    profiles = {label: f.profiles(s_m) for label, f in fits.items()}
    truth = None
    if args.truth:
        raw = read_truth(args.truth, s_m)
        flat = elastic.basis.gauge_fix(s_m, raw.reshape(4, -1), elastic.fix_slope)
        truth = flat.reshape(2, 2, -1)
    report, written = _write_outputs(args, meas, fits, profiles, s_m, truth, seconds,
                                     family.base, t_start, cfg=cfg, info=info)
    if args.export_compensation:
        _export_compensation(args, cfg, spec, points, elastic, _machine_x0(args, info))
    _say_results(args, report, fits, written, t_start)
    _warn_validity(args, report, meas, cfg)
    return 0 if elastic.converged else EXIT_NOT_CONVERGED


def _warn_validity(args, report, meas, cfg) -> None:
    """Each validity warning (report.json's ``validity``; and a compensation table over
    positions the data do not cover) once on stderr."""
    from ..inverse.validity import outside_measured

    lines = [f"{w['message']}; {w['action']}" for w in report.get("validity", [])]
    if args.export_compensation:
        half = cfg["machine"]["stroke_mm"] / 2e3
        lines += [str(w) for w in outside_measured(meas, [-half, half],
                                                   "the compensation table")]
    for line in dict.fromkeys(lines):
        print(f"diffguide fit: warning: {line}", file=sys.stderr)


def _read(args, cfg, info: dict):
    """The measurements (checked against the machine) and the structural priors."""
    from ..io.importers import read_any
    from .import_ import load_profile_args

    notes: list[str] = []
    meas = read_any(args.measurements, args.layout, args.x0_mm, notes, info,
                    allow_many_positions=args.allow_many_positions,
                    allow_conflicts=args.accept_file_conflicts,
                    profile=load_profile_args(args, args.measurements), encoding=args.encoding)
    args.input_info = info
    if args.machine_x0_mm is not None and not args.export_compensation:
        notes.append("--machine-x0-mm places the compensation table: without "
                     "--export-compensation it is only stated in report.json")
    for n in notes:
        say(args, f"note: {n}")
    _check_inputs(meas, args, cfg)
    priors = structure_priors(args, cfg)
    lines = ", ".join(map(str, meas.rejected[:10])) + (" ..." if len(meas.rejected) > 10 else "")
    say(args, f"{meas.source}: {len(meas.readings)} readings -> {meas.n} merged rows in "
               f"{len(meas.channels)} channels at {len(np.unique(meas.position))} positions"
               + (f"; {len(meas.rejected)} outlying readings set aside (lines {lines})"
                  if meas.rejected else ""))
    return meas, priors


def _fit_all(args, cfg, family, meas):
    """The elastic fit, and the rigid-table inversion when asked for: ``({label: RailFit},
    {label: seconds})``, each summarised on the console."""
    from ..inverse import fit_rails, settings

    _, criterion, waviness, rigid = _settings(args, cfg)
    spacing = None if args.knot_spacing_mm is None else args.knot_spacing_mm * 1e-3
    fits, seconds = {}, {}
    models = [("", family)] + ([("_rigid", family.base.with_rigid_table())] if rigid else [])
    for label, m in models:
        t = time.perf_counter()
        say(args, f"{'rigid-table' if label else 'elastic'} fit: compiling and solving ...")
        fits[label] = fit_rails(m, meas, knot_spacing=spacing, lam=args.lam,
                                criterion=criterion, max_steps=args.max_steps,
                                waviness=waviness, method="linear" if label else "lm",
                                joints=settings.rail_joints(cfg, args.rail_joints_mm))
        seconds[label] = time.perf_counter() - t
        _say_fit(args, label, fits[label], meas, seconds[label])
    return fits, seconds


def _say_fit(args, label, f, meas, seconds) -> None:
    say(args, f"{'rigid-table' if label else 'elastic'} fit: chi2/dof = {f.chi2_dof:.3f} "
               f"(dof {f.dof:.1f}), lambda {f.lam:.3g} ({f.weight.criterion}), "
               f"{f.edf:.1f} effective parameters, {f.steps} LM steps, {f.message}, "
               f"{seconds:.1f} s")
    for name, v in f.structure.items():
        val, sd = ((v["value"] * 1e3, v["sigma"] * 1e3) if name == "thickness"
                   else (v["value"], v["sigma"]) if name == "stiffness"
                   else (v["value"] * 100, v["sigma"] * 100))
        unit = {"thickness": " mm", "stiffness": ""}.get(name, " % of C")
        label = "table stiffness scale" if name == "stiffness" else name
        say(args, f"  {label}: {val:.3g} ± {sd:.2g}{unit}"
                   + ("" if v["determined"] else " (not determined by the data: prior)"))
    for c, a in zip(f.alignment_channels, f.alignment):
        say(args, f"  alignment slope of {meas.channel_label(c)}: {a * 1e6:.3g} µm/m "
                   "(fitted, as ISO 230-1 removes it)")
    for d in f.joint_steps():
        say(args, f"  step at the rail joint s = {d['s'] * 1e3:g} mm, rail {d['rail']} "
                   f"{d['plane']}: {d['value'] * 1e6:+.3g} ± {d['sigma'] * 1e6:.2g} µm")


def _write_outputs(args, meas, fits, profiles, s_m, truth, seconds, machine, t_start, *,
                   cfg, info):
    """The output folder, staged and renamed into place (figures drawn by the figures'
    process meanwhile): ``(report, names of the files written)``."""
    from ..io.fit_files import fit_csv_text, layout_csv_text, rails_csv_text
    from ..io.fit_posterior import NAME as POSTERIOR
    from ..io.fit_posterior import posterior_json_text
    from ..io.fit_report import fit_report
    from ..plotting.render import FigureWorker
    from . import _report
    from ._outputs import output_folder

    with output_folder(args, "fit") as staged:
        figures = getattr(args, "figures", None) or FigureWorker()
        plots = {} if args.no_plots else _figures(meas, fits, profiles, s_m, truth)
        try:
            if plots:  # drawn by the figures' process while the rest is computed
                figures.submit(staged.tmp, list(plots.items()), dpi=110)
            elastic = fits[""]
            report = fit_report(
                meas, fits, profiles, seconds, machine, truth=truth, truth_file=args.truth,
                source={"preset": None if args.config else args.preset, "config": args.config,
                        "measurements": ", ".join(args.measurements)},
                exit_code=0 if elastic.converged else EXIT_NOT_CONVERGED)
            report["measurements"].update(_coordinates(args))
            report.update(_report.sections(args, report, meas, elastic, s_m, cfg, info))
            report_figures = None if args.no_plots else _report.submit_figures(
                figures, staged.tmp, _report.figure_jobs(report, meas, elastic, s_m))
            files = {"rails.csv": rails_csv_text(s_m, *profiles[""])}
            if "_rigid" in fits:
                files["rails_rigid.csv"] = rails_csv_text(s_m, *profiles["_rigid"])
            files["fit.csv"] = fit_csv_text(meas, fits)
            files["layout.csv"] = layout_csv_text(meas)
            files[POSTERIOR] = posterior_json_text(  # for diffguide predict
                elastic, meas, preset=None if args.config else args.preset,
                config=args.config, nx=args.nx, ny=args.ny,
                x0_mm=_machine_x0(args, getattr(args, "input_info", {})), machine_cfg=cfg)
            report["total_seconds"] = time.perf_counter() - t_start
            files["report.json"] = json.dumps(_jsonable(report), indent=1, allow_nan=False) + "\n"
            staged.write(files)
            figures.wait()
            files["report.html"] = _report.html_text(files["report.json"], report_figures)
            staged.write({"report.html": files["report.html"]})
        except BaseException:
            figures.close(kill=True)  # stop drawing into the staging folder before it goes
            raise
        staged.commit()
    return report, [*files, *plots]


def _say_results(args, report, fits, written, t_start) -> None:
    """The console's closing lines: truth scores, what the data do not determine (and the
    planner's command for it), the files, a warning when the fit did not converge."""
    from ..io.fit_report import misfit_lines, undetermined_lines

    elastic = fits[""]
    if args.truth:
        e = report["truth"]["rms_error_um"]
        say(args, "profile rms error vs truth: elastic {:.3f} µm".format(e["elastic"]["all"])
             + (", rigid table {:.3f} µm".format(e["rigid_table"]["all"]) if "_rigid" in fits
                else ""))
    for line in misfit_lines(report):  # the likely cause of a chi2/dof far above 1
        say(args, line)
    blind = undetermined_lines(report["identifiability"], elastic.waviness)
    for line in blind:
        say(args, line)
    if report.get("plan_suggestion"):
        say(args, f"what more instruments would determine there: {report['plan_suggestion']}")
    from ._report import say_straightness

    say_straightness(args, report)
    say(args, f"wrote {args.out}/ ({', '.join(written)}) in {time.perf_counter() - t_start:.1f} s")
    if not elastic.converged:
        print(f"diffguide fit: warning: the fit did not converge ({elastic.message}); the results "
              f"in {args.out}/ are the best estimate so far and are flagged in report.json",
              file=sys.stderr)
    sys.stdout.flush()


def _machine_x0(args, info) -> float:
    """The export's x0: ``--machine-x0-mm``, else the measurements' (the first file's)."""
    return args.machine_x0_mm if args.machine_x0_mm is not None else info.get("x0_mm", 0.0)


def _coordinates(args) -> dict:
    """report.json's statement of the coordinates: every file's x0 and its source, and the
    compensation table's (``args.input_info``, set by :func:`_read`)."""
    info = getattr(args, "input_info", {})
    return {"files": [{"file": i["file"], "layout": i.get("layout"),
                       "encoding": i.get("encoding"), "x0_mm": i.get("x0_mm"),
                       "x0_source": i.get("x0_source"), "metadata": i.get("metadata", {})}
                      for i in info.get("files", [])],
            "x0_mm": info.get("x0_mm"), "machine_x0_mm": _machine_x0(args, info),
            "coordinates": "x = X - x0: X the file's position (machine coordinate), x the table "
                           "position (0 mid-stroke); the compensation table is written at "
                           "X = x + machine_x0_mm"}


def _export_compensation(args, cfg, spec, measured_points, fit, x0_mm=0.0) -> None:
    """``--export-compensation``: the fitted model's errors at ``--at`` over the stroke in
    ``--format`` (:func:`diffguide.studies.compensation.fitted_compensation`), written next
    to each other, and a warning per point where a rigid-body compensation would not hold."""
    from ..io.atomic import atomic_write_text
    from ..io.table_source import machine_builder
    from ..studies.compensation import fitted_compensation

    points = {k: (v[0] * 1e-3, v[1] * 1e-3) for k, v in cfg["points"].items()}
    points.update(measured_points)  # --at and the counts were checked before the fit
    half = cfg["machine"]["stroke_mm"] / 2
    files, warnings = fitted_compensation(
        spec, fit, np.linspace(-half, half, args.comp_points), args.at, export_spec(args, cfg),
        points=points, nx=args.nx, ny=args.ny, x0_mm=x0_mm,
        source=f"predicted by the elastic model fitted to {', '.join(args.measurements)}",
        tol_um=args.tol_um, tol_urad=args.tol_urad, z=args.at_z_mm * 1e-3,
        make_machine=machine_builder(cfg, args.nx, args.ny))
    base = Path(args.export_compensation)
    for suffix, text in files.items():
        path = base if not suffix else base.with_name(base.stem + suffix)
        atomic_write_text(path, text)
        say(args, f"wrote {path} (point {args.at}, {args.comp_format})")
    for w in warnings:
        print(f"diffguide fit: warning: {w}", file=sys.stderr)


def _check_export_options(args, cfg) -> None:
    """Every refusal of the export (its options, settings and table) before the fit."""
    half = cfg["machine"]["stroke_mm"] / 2
    check_export(args, cfg, np.linspace(-half, half, args.comp_points),
                 _machine_x0(args, getattr(args, "input_info", {})))


def _check_lead_for_fanuc(args, meas) -> None:
    """A FANUC pitch table is the positioning error, lead included: the fit has the lead only
    from EXX readings, so without them ``--format fanuc`` is refused before the fit (it was
    refused after it, the output folder written)."""
    from ..inverse.data import QUANTITIES

    if args.comp_format == "fanuc" and QUANTITIES.index("EXX") not in set(
            np.asarray(meas.quantity).tolist()):
        raise ValueError(
            f"--format fanuc: {', '.join(args.measurements)} hold no EXX (positioning) readings, "
            "so the fit has no lead error of the drive, and a FANUC pitch error compensation "
            "table holds the positioning error with it; measure EXX (a linear interferometer), "
            "or export another --format")


def _figures(meas, fits, profiles, s_m, truth):
    """The two figures, as jobs for the output folder (drawn on bare ``Figure`` objects with
    fixed margins: :mod:`diffguide.plotting.fit`)."""
    from ..io.measurements import QUANTITIES
    from ..plotting.render import FigureJob

    labels = {"": "elastic", "_rigid": "rigid table"}
    fig1 = FigureJob("diffguide.plotting.fit:profiles_figure",
                     (s_m, {labels[k]: v for k, v in profiles.items()}), {"truth": truth})
    chan = meas.channel_index()
    channels = []
    for c, (_, q, _) in enumerate(meas.channels):
        sel = chan == c
        unit = "µm" if QUANTITIES[q] in ("EXX", "EYX", "EZX") else "µm/m"
        rigid = fits["_rigid"].fitted[sel] * 1e6 if "_rigid" in fits else None
        channels.append((meas.channel_label(c), unit,
                         meas.position[sel] * 1e3, meas.value[sel] * 1e6,
                         meas.sigma[sel] * 1e6, fits[""].fitted[sel] * 1e6, rigid))
    return {"profiles.png": fig1,
            "curves.png": FigureJob("diffguide.plotting.fit:curves_figure", (channels,))}
