"""``diffguide simulate``: joint kinematic errors over the stroke (the paper's Figs. 7–9)."""

import argparse

import numpy as np

from .._core.limits import MAX_MESH_DIVISIONS, MAX_POSITIONS, check_range
from ..jobs.export import check_export, check_tolerances, export_spec
from ._common import PRESETS, add_machine_arguments, machine_config
from ._export_options import AXIS_SIDE_HELP, FORMAT_HELP, FORMATS, add_controller_options
from .simulate_cross import CROSS_PRESET, is_cross, run_cross


def parse_positions(text: str) -> np.ndarray:
    """``START:STOP:COUNT`` (mm, inclusive) → positions (m)."""
    parts = text.split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise ValueError(
            f"--positions must be START:STOP:COUNT in mm (e.g. -350:350:71), got {text!r}"
        ) from None
    if count < 2 or not np.isfinite(start) or not np.isfinite(stop) or stop <= start:
        raise ValueError(f"--positions needs STOP > START and COUNT >= 2, got {text!r}")
    check_range(count, 2, MAX_POSITIONS, f"--positions {text}: COUNT",
                "about 10 kB of memory and 20 ms per position")
    return np.linspace(start, stop, count) * 1e-3


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


def default_positions(cfg: dict, count: int = 71) -> np.ndarray:
    """``count`` positions (m) over the whole stroke of the machine configuration ``cfg``."""
    half = cfg["machine"]["stroke_mm"] / 2e3
    return np.linspace(-half, half, count)


def parse_mesh(text: str) -> tuple[int, int]:
    try:
        nx, ny = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--mesh must be NXxNY (e.g. 20x10), got {text!r}") from None
    if not (1 <= nx <= MAX_MESH_DIVISIONS and 1 <= ny <= MAX_MESH_DIVISIONS):
        raise ValueError(f"--mesh divisions must be in 1..{MAX_MESH_DIVISIONS}, got {text!r}")
    return nx, ny


def _positions(args, cfg) -> np.ndarray:
    """The swept positions (m): ``--positions`` or the whole stroke; within the stroke, and
    ``--field-at`` within them."""
    positions = (
        default_positions(cfg) if args.positions is None else parse_positions(args.positions)
    )
    half_stroke = cfg["machine"]["stroke_mm"] / 2
    if np.max(np.abs(positions)) * 1e3 > half_stroke + 1e-9:
        raise ValueError(
            f"--positions must lie within the ±{half_stroke:g} mm stroke, got {args.positions!r}"
        )
    if args.field_at is not None and not (
        positions.min() * 1e3 - 1e-9 <= args.field_at <= positions.max() * 1e3 + 1e-9
    ):
        raise ValueError(
            f"--field-at must lie within the swept positions [{positions.min() * 1e3:g}, "
            f"{positions.max() * 1e3:g}] mm, got {args.field_at:g}"
        )
    return positions


def _sweep(machine, rails, positions):
    """:func:`~diffguide.machine.kinematics.joint_errors` at every position, stored as an
    exported program in the cache folder: a second run does not trace it; it runs once per
    process, so compiled at XLA's optimisation level 0 (the compile time dominates, the sweep's
    run time stays in the milliseconds)."""
    from .._core.aot import cached_program
    from ..machine.kinematics import joint_errors

    sweep = cached_program(
        joint_errors,
        "machine.kinematics.joint_errors",
        compiler_options={"xla_backend_optimization_level": 0},
    )
    return sweep(machine, rails, np.asarray(positions, dtype=float))


def _field_plot(args, name, machine, je, positions, say) -> None:
    """``--field-plot``: EZX, roll and pitch over the table top at the position nearest
    ``--field-at`` (default the last)."""
    from ..io.atomic import atomic_savefig
    from ..machine.kinematics import error_field
    from ..plotting import figure_of
    from ..plotting.errors import plot_error_field

    k = len(positions) - 1
    if args.field_at is not None:
        k = int(np.argmin(np.abs(positions * 1e3 - args.field_at)))
    xy, field = error_field(machine, je, k)
    fig = figure_of(
        plot_error_field(
            xy,
            np.asarray(field) * 1e6,
            f"{name}: errors over the table at x = {positions[k] * 1e3:g} mm",
        )
    )
    atomic_savefig(fig, args.field_plot, dpi=100)
    say(f"wrote {args.field_plot}")


def _compensation(args, cfg, name, je, errs, positions, say) -> None:
    """``--export-compensation``: the table of ``--at`` in ``--format``, and a warning where
    another point departs from the rigid-body prediction from it."""
    import sys
    from pathlib import Path

    from ..io.atomic import atomic_write_text
    from ..studies.compensation import location_warnings
    from ..studies.exports import export_compensation

    what = f"rails {args.rails}" if args.rails else f"variant {args.variant}"
    j = list(je.point_names).index(args.at)
    base = Path(args.export_compensation)
    spec = export_spec(args, cfg)
    files = export_compensation(
        spec,
        positions * 1e3,
        np.asarray(je.errors)[:, j, :],
        None,
        x0_mm=args.machine_x0_mm,
        point=args.at,
        source=f"simulated, {name}, {what}",
        exx_includes_lead=False,  # a simulation: ideal drive, no lead error
    )
    for suffix, text in files.items():
        path = base if not suffix else base.with_name(base.stem + suffix)
        atomic_write_text(path, text)
        say(f"wrote {path}")
    warnings = location_warnings(
        errs, je.point_names, np.asarray(je.points_xy), args.at, args.tol_um, args.tol_urad
    )
    for w in warnings:
        print(f"diffguide simulate: warning: {w}", file=sys.stderr)


def _plot(args, name, je, errs, positions, say) -> None:
    """``--plot``: the six errors against position."""
    from ..io.atomic import atomic_savefig
    from ..plotting import figure_of
    from ..plotting.errors import plot_joint_errors

    what = f"rails from {args.rails}" if args.rails else f"variant {args.variant}"
    table = "rigid table" if args.rigid_table else "elastic table"
    fig = figure_of(
        plot_joint_errors(positions * 1e3, errs, je.point_names, f"{name}, {what}, {table}")
    )
    atomic_savefig(fig, args.plot, dpi=110)
    say(f"wrote {args.plot}")


def run(args) -> int:
    import sys

    from ..io.atomic import atomic_write_text  # here: --help imports no JAX
    from ..io.errors_csv import joint_errors_csv
    from ..io.rails_csv import read_rails_csv
    from ..jobs.machine import config_machine
    from ..machine.majda2012 import paper_variant

    if is_cross(args):
        return run_cross(args)
    cfg = machine_config(args)
    positions = _positions(args, cfg)
    check_tolerances(args)
    if args.export_compensation:  # every refusal of the export, before any work
        check_export(args, cfg, positions * 1e3, args.machine_x0_mm)
    nx, ny = parse_mesh(args.mesh) if args.mesh else (None, None)
    rails = read_rails_csv(args.rails) if args.rails else paper_variant(args.variant)
    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    name = args.config or args.preset
    say(f"building the {name} machine ...")
    machine = config_machine(cfg, nx=nx, ny=ny)
    if args.rigid_table:
        machine = machine.with_rigid_table()
    say(f"solving the equilibrium at {len(positions)} positions ...")
    je = _sweep(machine, rails, positions)
    ok = np.asarray(je.converged)
    if not ok.all():
        bad = ", ".join(f"{x * 1e3:g} mm" for x in positions[~ok])
        print(
            f"diffguide simulate: error: the equilibrium did not converge at {bad}; "
            "nothing written",
            file=sys.stderr,
        )
        return 3
    errs = je.user_units()
    if args.export_compensation and args.at not in je.point_names:
        raise ValueError(
            f"--at must be one of the points {', '.join(je.point_names)}, got {args.at!r}"
        )
    atomic_write_text(args.out, joint_errors_csv(positions, je.point_names, je.points_xy, errs))
    say(f"wrote {args.out}")
    if args.field_plot:
        _field_plot(args, name, machine, je, positions, say)
    if args.export_compensation:
        _compensation(args, cfg, name, je, errs, positions, say)
    if args.plot:
        _plot(args, name, je, errs, positions, say)
    for w in _validity(args, machine, rails, positions, je):
        print(f"diffguide simulate: warning: {w}", file=sys.stderr)
    return 0


def _validity(args, machine, rails, positions, je) -> list:
    """The model's validity checks of this sweep (:mod:`diffguide.machine.validity`): rails
    extrapolated beyond their samples, rails or contacts beyond the small-deflection range,
    carriages lifted off, rotations beyond the small-angle bound."""
    from ..io.rails_csv import sampled_ranges
    from ..machine import validity

    out = []
    if args.rails:
        out += validity.rail_extrapolation(machine, positions, sampled_ranges(args.rails))
    out += validity.rail_range(machine, rails, positions)
    out += validity.contact_range(machine, rails, je)
    out += validity.large_rotations(np.asarray(je.errors)[..., 3:], "the joint errors")
    return list(dict.fromkeys(out))
