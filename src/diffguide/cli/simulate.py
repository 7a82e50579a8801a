"""``diffguide simulate``: joint kinematic errors over the stroke (the paper's Figs. 7–9);
the work is :func:`diffguide.jobs.simulate_job`."""

import argparse
import sys

from ..jobs.simulate_cross import CROSS_PRESET
from ._common import PRESETS, add_machine_arguments
from ._export_options import AXIS_SIDE_HELP, FORMAT_HELP, FORMATS, add_controller_options


def add_parser(sub) -> None:
    p = sub.add_parser(
        "simulate",
        help="joint kinematic errors (µm, µrad) at the control points over the stroke",
        description="Equilibrium of the table on its four carriages at every position, and the "
        "six joint kinematic errors (ISO 230-1: EXX, EYX, EZX in µm; EAX roll, EBX pitch, ECX "
        "yaw in µrad = µm/m) at each control point, relative to the reference position x = 0.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    add_machine_arguments(p, presets=(*PRESETS, CROSS_PRESET))
    p.add_argument(
        "--grid-xy",
        default="9x9",
        metavar="NXxNY",
        help=f"with --preset {CROSS_PRESET} or a cross machine file (the table on a saddle): "
        "NX table positions X "
        "and NY saddle positions Y over both strokes; the CSV has the six errors of the table "
        "relative to the bed (EX..EZ µm, EA..EC µrad) at each point, from X = Y = 0",
    )
    p.add_argument(
        "--variant",
        type=int,
        choices=(1, 2, 3),
        default=1,
        help="the paper's rail error Δ/2·(x + x²), x in m, Δ = 0.05 mm: 1 rail 1 vertical; "
        "2 rail 1 horizontal; 3 rail 1 vertical and rail 2 horizontal (ignored with --rails)",
    )
    p.add_argument(
        "--rails",
        help="rail profiles CSV: rail,s_mm,vertical_um,horizontal_um (rail 1 at -Y, 2 at +Y; "
        "s along the rail from under the table centre at x = 0)",
    )
    p.add_argument(
        "--positions",
        default=None,
        help="table positions x START:STOP:COUNT (mm, from mid-stroke; not machine "
        "coordinates: --machine-x0-mm does not shift them; COUNT at most 100000); default: "
        "the machine's whole stroke at 71 positions",
    )
    p.add_argument("--rigid-table", action="store_true", help="infinitely stiff table")
    p.add_argument("--mesh", help="table mesh NXxNY (elements); default from the machine (20x10)")
    p.add_argument("--out", required=True, help="output CSV (one row per position and point)")
    p.add_argument("--plot", help="output figure (PNG): the six errors against position")
    p.add_argument(
        "--export-compensation",
        metavar="FILE",
        help="also write a compensation table for --at in --format (machine coordinates X = x + "
        "--machine-x0-mm; docs: compensation-exports)",
    )
    p.add_argument("--at", default="P5", help="the control point of the compensation table")
    p.add_argument(
        "--format",
        dest="comp_format",
        default="csv",
        choices=FORMATS,
        help=FORMAT_HELP,
    )
    p.add_argument(
        "--axis-side",
        default=None,
        metavar="SIDE",
        help=AXIS_SIDE_HELP,
    )
    add_controller_options(p)
    p.add_argument(
        "--machine-x0-mm",
        "--x0-mm",
        dest="machine_x0_mm",
        type=float,
        default=0.0,
        help="machine coordinate (mm) of the table position x = 0 (mid-stroke), default 0: "
        "only the compensation table is written at X = x + x0; --positions and the --out CSV "
        "stay in table positions x. --x0-mm is its former name, kept: the same quantity as "
        "'fit --x0-mm', which there also converts the measurement files' positions "
        "(x = X - x0) before placing the table",
    )
    p.add_argument(
        "--tol-um",
        type=float,
        default=2.0,
        help="warn where another point's EXX/EYX/EZX depart from the rigid-body "
        "prediction from --at by more than this (µm)",
    )
    p.add_argument(
        "--tol-urad",
        type=float,
        default=5.0,
        help="warn where another point's EAX/EBX/ECX depart from --at's by more (µrad)",
    )
    p.add_argument(
        "--field-plot",
        metavar="FILE.png",
        help="maps of EZX (µm), roll and pitch (µrad) over the whole table top at "
        "the sweep position nearest --field-at",
    )
    p.add_argument(
        "--field-at",
        type=float,
        default=None,
        help="table position (mm) of --field-plot; default: the last position",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=run)


def settings_from_args(args):
    """The :class:`diffguide.jobs.SimulateSettings` of the parsed options (checked there)."""
    from ..jobs import SimulateSettings

    return SimulateSettings(**{k: getattr(args, k) for k in SimulateSettings.fields()
                               if hasattr(args, k)})


def run(args) -> int:
    from ..jobs import simulate_job

    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    res = simulate_job(settings_from_args(args), progress=say)
    if not res.converged:
        print(f"diffguide simulate: error: {res.failure}; nothing written", file=sys.stderr)
        return res.exit_code
    for path in res.write(args.out):
        say(f"wrote {path}")
    for w in res.compensation_warnings + res.validity_warnings:
        print(f"diffguide simulate: warning: {w}", file=sys.stderr)
    return 0
