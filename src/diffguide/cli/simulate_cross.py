"""``diffguide simulate --preset majda2012-cross`` (or ``--config`` a cross machine file,
:mod:`diffguide.io.cross_config`): the cross table's errors relative to the bed at the table's
control points over an (X, Y) grid (:mod:`diffguide.machine.volumetric`)."""

import numpy as np

from .._core.limits import MAX_POSITIONS, check_range

#: The preset this path serves.
CROSS_PRESET = "majda2012-cross"
#: Options of ``simulate`` that the cross table does not take (yet), with their flags.
_ONE_AXIS_ONLY = (("rails", "--rails"), ("rigid_table", "--rigid-table"), ("plot", "--plot"),
                  ("export_compensation", "--export-compensation"),
                  ("field_plot", "--field-plot"), ("positions", "--positions"),
                  ("mesh", "--mesh"))


def parse_grid(text: str) -> tuple[int, int]:
    """``NXxNY`` → the numbers of X and Y positions (each 2 .. :data:`MAX_POSITIONS`)."""
    try:
        nx, ny = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--grid-xy must be NXxNY (e.g. 9x9), got {text!r}") from None
    for name, n in (("NX", nx), ("NY", ny)):
        check_range(n, 2, MAX_POSITIONS, f"--grid-xy {text}: {name}", "one solve per position")
    return nx, ny


def is_cross(args) -> bool:
    """Whether ``simulate`` runs the cross table: ``--preset majda2012-cross``, or a
    ``--config`` file with a saddle (:func:`~diffguide.io.cross_config.is_cross_config`)."""
    if args.config:
        from ..io.cross_config import is_cross_config

        return is_cross_config(args.config)
    return args.preset == CROSS_PRESET


def run_cross(args) -> int:
    """The cross table (``--config`` file, else the preset) over ``--grid-xy`` positions
    spanning both strokes, the paper's rail error ``--variant`` on the X rails and, the same,
    on the Y rails; writes ``--out``."""
    import sys

    from .._core.aot import cached_program
    from ..io.atomic import atomic_write_text
    from ..io.cross_config import load_cross_config
    from ..io.cross_csv import cross_errors_csv
    from ..machine.cross import build_cross
    from ..machine.majda2012 import paper_variant
    from ..machine.paper_cross import majda2012_cross_spec
    from ..machine.volumetric import cross_errors

    for attr, flag in _ONE_AXIS_ONLY:
        if getattr(args, attr, None):
            raise ValueError(f"{flag} is not available with --preset {CROSS_PRESET} (it "
                             "writes the errors at the control points over --grid-xy)")
    nx, ny = parse_grid(args.grid_xy)
    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    spec = load_cross_config(args.config) if args.config else majda2012_cross_spec()
    say(f"building the {args.config or CROSS_PRESET} machine ...")
    cross = build_cross(spec)
    X = np.linspace(-0.5, 0.5, nx) * cross.x_stroke
    Y = np.linspace(-0.5, 0.5, ny) * cross.y_stroke
    say(f"solving the equilibrium at {nx} x {ny} positions ...")
    run = cached_program(cross_errors, "machine.volumetric.cross_errors",
                         compiler_options={"xla_backend_optimization_level": 0})
    rails = paper_variant(args.variant)
    e = run(cross, rails, rails, X, Y)
    ok = np.asarray(e.converged)
    if not ok.all():
        print(f"diffguide simulate: error: the equilibrium did not converge at {int((~ok).sum())}"
              " of the (X, Y) positions; nothing written", file=sys.stderr)
        return 3
    atomic_write_text(args.out, cross_errors_csv(e))
    say(f"wrote {args.out}")
    return 0
