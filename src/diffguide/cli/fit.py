"""``diffguide fit``: rail straightness profiles from measured pitch, yaw, roll."""

import argparse
import math
import sys
import time

from ._common import PRESETS, say
from ._export_options import AXIS_SIDE_HELP, FORMAT_HELP, add_controller_options
from ._export_options import FORMATS as EXPORT_FORMATS
from ._input_options import add_input_options


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


def _joints_mm(text: str) -> tuple[float, ...]:
    """``--rail-joints-mm``: comma-separated finite positions (mm)."""
    try:
        out = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected positions in mm separated by commas (e.g. 137,637), got {text!r}"
        ) from None
    if not all(math.isfinite(v) for v in out):
        raise argparse.ArgumentTypeError(f"rail joints must be finite (mm), got {text!r}")
    return out


def settings_from_args(args):
    """The :class:`diffguide.jobs.FitSettings` of the parsed options (checked there)."""
    from ..jobs import FitSettings

    given = {k: getattr(args, k) for k in FitSettings.fields() if hasattr(args, k)}
    return FitSettings(**given)


def run(args) -> int:
    from ..jobs import fit_job
    from ._interrupt import checkpoint

    t_start = time.perf_counter()
    res = fit_job(settings_from_args(args), progress=lambda t: say(args, t),
                  figures=getattr(args, "figures", None))
    written = res.write(args.out, checkpoint=checkpoint)
    for path in res.compensation:
        say(args, f"wrote {path} (point {args.at}, {args.comp_format})")
    for w in res.compensation_warnings:
        print(f"diffguide fit: warning: {w}", file=sys.stderr)
    _say_results(args, res, written, t_start)
    for line in res.validity_warnings:
        print(f"diffguide fit: warning: {line}", file=sys.stderr)
    return res.exit_code


def _say_results(args, res, written, t_start) -> None:
    """The console's closing lines: truth scores, what the data do not determine (and the
    planner's command for it), the files, a warning when the fit did not converge."""
    from ..io.report_text import misfit_lines, undetermined_lines
    from ._report import say_straightness

    report, elastic = res.report, res.fits[""]
    if args.truth:
        e = report["truth"]["rms_error_um"]
        say(args, "profile rms error vs truth: elastic {:.3f} µm".format(e["elastic"]["all"])
             + (", rigid table {:.3f} µm".format(e["rigid_table"]["all"]) if "_rigid" in res.fits
                else ""))
    for line in misfit_lines(report):  # the likely cause of a chi2/dof far above 1
        say(args, line)
    for line in undetermined_lines(report["identifiability"], elastic.waviness):
        say(args, line)
    if report.get("plan_suggestion"):
        say(args, f"what more instruments would determine there: {report['plan_suggestion']}")
    say_straightness(args, report)
    say(args, f"wrote {args.out}/ ({', '.join(written)}) in {time.perf_counter() - t_start:.1f} s")
    if not elastic.converged:
        print(f"diffguide fit: warning: the fit did not converge ({elastic.message}); the results "
              f"in {args.out}/ are the best estimate so far and are flagged in report.json",
              file=sys.stderr)
    sys.stdout.flush()
