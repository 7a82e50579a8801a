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
    if not pts and not args.grid:
        raise ValueError("give at least one point: --point NAME:X_MM,Y_MM or --points FILE.csv "
                         "(or --grid NXxNY)")
    if pts and args.grid:
        raise ValueError("give --grid or --point/--points, not both")
    return pts


def parse_grid(text: str, n_positions: int) -> tuple[int, int]:
    """``--grid NXxNY`` → ``(NX, NY)``, checked (:func:`~diffguide.inverse.error_map.check_grid`);
    a ``ValueError`` naming the option and the value."""
    from ..inverse.error_map import check_grid

    nx, sep, ny = str(text).strip().lower().partition("x")
    if not (sep and nx.strip().isdigit() and ny.strip().isdigit()):
        raise ValueError(f"--grid must be NXxNY with whole numbers (e.g. 21x11), got {text!r}")
    try:
        return check_grid((int(nx), int(ny)), n_positions)
    except ValueError as exc:
        raise ValueError(f"--grid {text}: {exc}") from None


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
    plate; :func:`diffguide.jobs.machine.machine_builder`) and a note of what changed in
    it since the fit (None: nothing): the fit's machine file or preset, refused where it
    changed unless ``--accept-machine-change``."""
    from ..io.config import default_config, load_config, spec_from_config
    from ..io.fit_posterior import machine_changes
    from ..jobs.machine import machine_builder

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
    from ..inverse.error_map import error_map
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
    kw = dict(measured_points=meta["points_m"], nx=m.get("nx"), ny=m.get("ny"),
              extrapolate=args.extrapolate, z=args.z_mm * 1e-3)
    if args.grid_plot and not args.grid:
        raise ValueError("--grid-plot needs --grid NXxNY")
    if args.grid:
        if make_machine is not None:
            raise ValueError("--grid: the table is imported (a reduced matrix): it knows only "
                             "its retained nodes; predict there with --point/--points")
        pred = error_map(post, spec, parse_grid(args.grid, len(x)), x, **kw)
    else:
        pred = predict(post, spec, points, x, make_machine=make_machine, **kw)
    src = f"from the fit in {Path(args.fit).resolve()}" + (
        f"; WARNING: {changed} (--accept-machine-change)" if changed else "")
    atomic_write_text(args.out, prediction_csv_text(pred, src, meta.get("x0_mm")))
    if args.grid_plot:
        _grid_plot(args, pred)
    _summary(args, pred, time.perf_counter() - t0)
    return 0


def _grid_plot(args, pred) -> None:
    """``--grid-plot``: the errors and σ over the table top at the last position."""
    from ..io.atomic import atomic_savefig
    from ..plotting import figure_of
    from ..plotting.errors import plot_error_map

    err, sig = pred.user_units()
    fig = figure_of(plot_error_map(
        pred.points_xy, pred.grid_shape, err[-1], sig[-1],
        f"errors over the table top at x = {pred.positions[-1] * 1e3:g} mm (1σ below)"))
    atomic_savefig(fig, args.grid_plot, dpi=100)
    say(args, f"wrote {args.grid_plot}")


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
