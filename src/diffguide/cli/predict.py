"""``diffguide predict``: the joint errors, with σ, at any points of the table from a fit;
the work is :func:`diffguide.jobs.predict_job`."""

import argparse
import sys
import time

import numpy as np

from ._common import say


def warn(line: str) -> None:
    """A warning on stderr (also with --quiet)."""
    print(f"diffguide predict: warning: {line}", file=sys.stderr)


def add_parser(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "predict",
        help="joint errors (µm, µrad) with σ at any points of the table, from a fit's output",
        description="Predict the six joint errors of the X axis (EXX EYX EZX in µm, EAX EBX ECX "
        "in µrad) at points of the table where no instrument stood - the tool's point, a "
        "fixture - over table positions, from the rails AND the structure (thickness, preload) "
        "a 'diffguide fit --out DIR' estimated, with 1σ from the fit's full posterior (rails, "
        "structure, lead and alignment nuisances). EXX includes the fitted lead (feed-screw) "
        "error when the data held EXX. Positions outside the measured range are refused "
        "unless --extrapolate (then flagged, with their large σ). The fitted model is solved "
        "once over the positions and any point of the table top follows from the condensed "
        "table (the shell's shape functions between the mesh nodes): --grid NXxNY gives the "
        "error map over the whole top at every position. Output CSV (written atomically): "
        "position_mm,point,x_mm,y_mm, EXX_um..ECX_urad, EXX_sigma_um..ECX_sigma_urad, "
        "extrapolated.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--fit", required=True, metavar="DIR",
                   help="a 'diffguide fit --out' folder (its posterior.json)")
    p.add_argument("--point", action="append", default=[], metavar="NAME:X_MM,Y_MM",
                   help="a point on the table top (mm; repeatable), e.g. Q1:300,-100")
    p.add_argument("--points", metavar="FILE.csv",
                   help="points file: point,x_mm,y_mm (added to --point)")
    p.add_argument("--grid", metavar="NXxNY",
                   help="the error map: NX x NY points equally spaced over the whole table top "
                   "(edges included; NX, NY in 2..201, at most 201x201 at 71 positions), named "
                   "G{i}_{j}, instead of --point/--points, e.g. 21x11")
    p.add_argument("--grid-plot", metavar="FILE.png",
                   help="with --grid: a figure of the six errors and their σ over the table "
                   "top at the last position")
    p.add_argument("--positions-mm", metavar="START:STOP:N",
                   help="table positions (mm, inclusive, 2 <= N <= 100000; positions x points "
                   "at most what fits 2 GB of σ Jacobians, which the message states); default "
                   "the measured range at 71 positions")
    p.add_argument("--positions", metavar="FILE.csv", dest="positions_file",
                   help="positions file: position_mm (instead of --positions-mm)")
    p.add_argument("--extrapolate", action="store_true",
                   help="allow positions outside the measured range (flagged, large σ)")
    p.add_argument("--z-mm", type=float, default=0.0, metavar="Z",
                   help="height of the points above the table top (mm; the tool point or a "
                   "workpiece feature): EXX gains z·EBX and EYX −z·EAX (Abbe), with their σ; "
                   "default 0, the table top")
    p.add_argument("--accept-machine-change", action="store_true",
                   help="predict although the machine file (or the preset) differs from the "
                   "one the fit was made with: the differences are then printed as a warning "
                   "and recorded in the output's header (default: refused, exit 2)")
    p.add_argument("--out", required=True, metavar="FILE.csv", help="output CSV")
    p.set_defaults(func=run)
    return p


def settings_from_args(args):
    """The :class:`diffguide.jobs.PredictSettings` of the parsed options (checked there)."""
    from ..jobs import PredictSettings

    return PredictSettings(**{k: getattr(args, k) for k in PredictSettings.fields()
                              if hasattr(args, k)})


def run(args) -> int:
    from ..jobs import predict_job

    t0 = time.perf_counter()
    res = predict_job(settings_from_args(args), warn=warn)
    written = res.write(args.out)
    for path in written[1:]:
        say(args, f"wrote {path}")
    _summary(args, res.prediction, time.perf_counter() - t0)
    return 0


def _summary(args, pred, seconds: float) -> None:
    """Per point: the largest |error| and σ of each quantity over the positions."""
    from ..machine.errors import ERRORS

    err, sig = pred.user_units()
    lo, hi = (v * 1e3 for v in pred.position_range)
    n_out = int(np.sum(pred.extrapolated))
    say(args, f"predicted {len(pred.positions)} positions x {len(pred.point_names)} points "
               f"(measured range {lo:g} .. {hi:g} mm"
               + (f"; {n_out} positions extrapolated, flagged" if n_out else "") + ")"
               + ("; EXX includes the fitted lead error" if pred.lead else
                  "; no EXX data: EXX without lead error"))
    if pred.grid_shape is not None:
        parts = [f"{e.name} {np.max(np.abs(err[..., k])):.3g}±{np.max(sig[..., k]):.2g}"
                 for k, e in enumerate(ERRORS)]
        say(args, "  grid {} x {} over the table top, max |error| ± max σ: {} (µm, µrad)".format(
            *pred.grid_shape, ", ".join(parts)))
    for j, name in enumerate(() if pred.grid_shape else pred.point_names):
        x, y = pred.points_xy[j] * 1e3
        parts = [f"{e.name} {np.max(np.abs(err[:, j, k])):.3g}±{np.max(sig[:, j, k]):.2g}"
                 for k, e in enumerate(ERRORS)]
        say(args, f"  {name} ({x:g}, {y:g}) mm, max |error| ± max σ: {', '.join(parts)} "
                  "(µm, µrad)")
    say(args, f"wrote {args.out} in {seconds:.1f} s")
