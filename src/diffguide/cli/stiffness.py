"""``diffguide stiffness``: a carriage's deflection against load (the paper's Fig. 3)."""

import numpy as np

PRESETS = ("majda2012", "majda2012-rivin", "roller25")


def add_parser(sub) -> None:
    p = sub.add_parser(
        "stiffness",
        help="static characteristic of one carriage: deflection (µm) vs load (N)",
        description="Deflection of one runner block on a straight rail under downward, upward "
        "and lateral loads applied at the centre of its top face (rotations held, as in "
        "catalogue stiffness measurements). Writes CSV columns direction,load_N,deflection_um.",
    )
    p.add_argument(
        "--preset",
        default="majda2012",
        choices=PRESETS,
        help="carriage: majda2012 (size-25 ball block, Hertz), majda2012-rivin (same block, "
        "the paper's Rivin contact law), roller25 (size-25 roller block)",
    )
    p.add_argument(
        "--config",
        metavar="MACHINE.toml",
        help="take the carriage from a machine configuration file (overrides --preset)",
    )
    p.add_argument("--max-load", type=float, default=10000.0, metavar="N", help="largest load (N)")
    p.add_argument(
        "--steps", type=int, default=41, metavar="K", help="number of loads from 0 to --max-load"
    )
    p.add_argument("--out", required=True, metavar="FILE.csv", help="output CSV file")
    p.add_argument("--plot", metavar="FILE.png", help="output figure (PNG)")
    p.set_defaults(func=run)


def carriage_for(preset: str):
    from ..guideway.blocks import majda2012_carriage, roller25_carriage

    if preset == "majda2012":
        return majda2012_carriage("hertz")
    if preset == "majda2012-rivin":
        return majda2012_carriage("rivin")
    if preset == "roller25":
        return roller25_carriage()
    raise ValueError(f"--preset must be one of {PRESETS}, got {preset!r}")


def run(args) -> int:
    from ..guideway.solve import static_characteristics
    from ..io.atomic import atomic_savefig, atomic_write_text  # here: --help imports no JAX

    if not args.max_load > 0:
        raise ValueError(f"--max-load must be > 0 N, got {args.max_load}")
    if args.steps < 2:
        raise ValueError(f"--steps must be >= 2, got {args.steps}")
    if args.config:
        from ..guideway.carriage import carriage_from_spec
        from ..io.config import load_config, spec_from_config

        carriage = carriage_from_spec(spec_from_config(load_config(args.config)).carriage)
    else:
        carriage = carriage_for(args.preset)
    label = args.config or args.preset  # what the console line and the plot title call it
    loads = np.linspace(0.0, args.max_load, args.steps)
    out = static_characteristics(carriage, loads)
    failed = [
        f"{name} {load:g} N"
        for name, (_, sols) in out.items()
        for load, ok in zip(loads, np.asarray(sols.converged))
        if not ok
    ]
    if failed:
        raise ValueError("the equilibrium did not converge at: " + ", ".join(failed))
    lines = ["direction,load_N,deflection_um"]
    curves = {}
    for name, (defl, _) in out.items():
        defl_um = np.asarray(defl) * 1e6 + 0.0  # no "-0.000000"
        curves[name] = (loads, defl_um)
        lines += [f"{name},{f:.6g},{d:.6f}" for f, d in zip(loads, defl_um)]
    atomic_write_text(args.out, "\n".join(lines) + "\n")
    stiff = {n: loads[1] / d[1] for n, (_, d) in curves.items()}
    say = (lambda *a: None) if args.quiet else print
    say(
        f"{label}: preload approach g0 = {float(carriage.preload_approach) * 1e6:.3f} µm, "
        f"initial stiffness "
        + ", ".join(f"{n} {s:.0f} N/µm" for n, s in stiff.items())
        + f"; wrote {args.out}"
    )
    if args.plot:
        from ..plotting import figure_of
        from ..plotting.guideway import plot_static_characteristic

        fig = figure_of(
            plot_static_characteristic(curves, title=f"{label}: static characteristic")
        )
        atomic_savefig(fig, args.plot, dpi=120)
        say(f"wrote {args.plot}")
    return 0
