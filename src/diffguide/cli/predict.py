"""``diffguide predict``: the joint errors, with σ, at any points of the table from a fit."""

import argparse
import sys
import time
from pathlib import Path

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
        "unless --extrapolate (then flagged, with their large σ). The table is condensed again "
        "with the new points in its mesh (about a second per structure value; three with the "
        "thickness estimated). Output CSV (written atomically): position_mm,point,x_mm,y_mm, "
        "EXX_um..ECX_urad, EXX_sigma_um..ECX_sigma_urad, extrapolated.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--fit", required=True, metavar="DIR",
                   help="a 'diffguide fit --out' folder (its posterior.json)")
    p.add_argument("--point", action="append", default=[], metavar="NAME:X_MM,Y_MM",
                   help="a point on the table top (mm; repeatable), e.g. Q1:300,-100")
    p.add_argument("--points", metavar="FILE.csv",
                   help="points file: point,x_mm,y_mm (added to --point)")
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


def _points(args) -> dict:
    """The points ``{name: (x, y)}`` (m) of ``--point`` and ``--points``."""
    from ..io.prediction_csv import parse_point, read_points_file

    pts: dict = {}
    for text in args.point:
        name, xy = parse_point(text)
        if name in pts:
            raise ValueError(f"--point {name!r} given twice")
        pts[name] = xy
    if args.points:
        for name, xy in read_points_file(args.points).items():
            if name in pts:
                raise ValueError(f"{args.points}: point {name!r} is also given by --point")
            pts[name] = xy
    if not pts:
        raise ValueError("give at least one point: --point NAME:X_MM,Y_MM or --points FILE.csv")
    return pts


def _positions(args, post) -> np.ndarray:
    """The table positions (m): ``--positions-mm``, ``--positions`` or the measured range."""
    from ..io.prediction_csv import read_positions_file
    from .simulate import parse_positions

    if args.positions_mm and args.positions_file:
        raise ValueError("give --positions-mm or --positions, not both")
    if args.positions_file:
        return read_positions_file(args.positions_file)
    if args.positions_mm:
        try:
            return parse_positions(args.positions_mm)
        except ValueError as exc:
            raise ValueError(str(exc).replace("--positions", "--positions-mm")) from None
    return np.linspace(*post.position_range, 71)


def _positions_option(args) -> str:
    """The option that gave the positions, with its value, for a message."""
    if args.positions_file:
        return f"--positions {args.positions_file}"
    return f"--positions-mm {args.positions_mm}" if args.positions_mm else "the measured range"


def _machine_spec(args, meta: dict):
    """The fitted machine's specification, its builder for ``predict`` (``None`` for the
    plate; :func:`diffguide.io.table_source.machine_builder`) and a note of what changed in
    it since the fit (None: nothing): the fit's machine file or preset, refused where it
    changed unless ``--accept-machine-change``."""
    from ..io.config import default_config, load_config, spec_from_config
    from ..io.fit_posterior import machine_changes
    from ..io.table_source import machine_builder

    m = meta["machine"]
    what = f"machine file {m['config']}" if m.get("config") else f"preset {m['preset']}"
    cfg = load_config(m["config"]) if m.get("config") else default_config()
    changes = machine_changes(meta, cfg)
    note = None
    if changes:
        note = f"the {what} changed since the fit: " + "; ".join(changes)
        if not args.accept_machine_change:
            raise ValueError(f"{note}. The fit's posterior belongs to the machine it was fitted "
                             "with: fit again, or give --accept-machine-change to predict "
                             "with the changed machine anyway")
        warn(f"{note} (predicting anyway: --accept-machine-change)")
    return spec_from_config(cfg), machine_builder(cfg, m.get("nx"), m.get("ny")), note


def run(args) -> int:
    from ..inverse.predict import check_size, predict
    from ..io.atomic import atomic_write_text
    from ..io.fit_posterior import read_fit_posterior
    from ..io.prediction_csv import prediction_csv_text

    t0 = time.perf_counter()
    if not (np.isfinite(args.z_mm) and -500.0 <= args.z_mm <= 2000.0):
        raise ValueError(f"--z-mm must be in [-500, 2000] mm, got {args.z_mm:g}")
    post, meta = read_fit_posterior(args.fit)
    for line in meta["warnings"]:
        warn(line)
    points = _points(args)
    x = _positions(args, post)
    check_size(len(x), len(set(points) | set(meta["points_m"])), post.cov.shape[0],
               _positions_option(args))
    spec, make_machine, changed = _machine_spec(args, meta)
    m = meta["machine"]
    pred = predict(post, spec, points, x, measured_points=meta["points_m"], nx=m.get("nx"),
                   ny=m.get("ny"), extrapolate=args.extrapolate, z=args.z_mm * 1e-3,
                   make_machine=make_machine)
    src = f"from the fit in {Path(args.fit).resolve()}" + (
        f"; WARNING: {changed} (--accept-machine-change)" if changed else "")
    atomic_write_text(args.out, prediction_csv_text(pred, src, meta.get("x0_mm")))
    _summary(args, pred, time.perf_counter() - t0)
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
    for j, name in enumerate(pred.point_names):
        x, y = pred.points_xy[j] * 1e3
        parts = [f"{e.name} {np.max(np.abs(err[:, j, k])):.3g}±{np.max(sig[:, j, k]):.2g}"
                 for k, e in enumerate(ERRORS)]
        say(args, f"  {name} ({x:g}, {y:g}) mm, max |error| ± max σ: {', '.join(parts)} "
                  "(µm, µrad)")
    say(args, f"wrote {args.out} in {seconds:.1f} s")
