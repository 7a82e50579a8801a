"""The simulate job of a cross table (``preset="majda2012-cross"``, or a machine file with a
saddle, :mod:`diffguide.io.cross_config`): the table's errors relative to the bed at its
control points over an (X, Y) grid (:mod:`diffguide.machine.volumetric`).
:func:`diffguide.jobs.simulate_job` runs it for such settings (:func:`cross_sweep`)."""

from __future__ import annotations

from collections.abc import Callable

#: The preset of the cross table (the table on a saddle).
CROSS_PRESET = "majda2012-cross"
#: Options of ``simulate`` that the cross table does not take (yet), with their flags.
ONE_AXIS_ONLY = (("rails", "--rails"), ("rigid_table", "--rigid-table"), ("plot", "--plot"),
                 ("export_compensation", "--export-compensation"),
                 ("field_plot", "--field-plot"), ("positions", "--positions"),
                 ("mesh", "--mesh"))


def parse_grid(text: str) -> tuple[int, int]:
    """``NXxNY`` → the numbers of X and Y positions (each 2 .. ``MAX_POSITIONS``)."""
    from .._core.limits import MAX_POSITIONS, check_range

    try:
        nx, ny = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--grid-xy must be NXxNY (e.g. 9x9), got {text!r}") from None
    for name, n in (("NX", nx), ("NY", ny)):
        check_range(n, 2, MAX_POSITIONS, f"--grid-xy {text}: {name}", "one solve per position")
    return nx, ny


def check_cross(s) -> tuple[int, int]:
    """The one-axis options refused, and the grid ``(NX, NY)`` of ``s.grid_xy``."""
    for attr, flag in ONE_AXIS_ONLY:
        if getattr(s, attr, None):
            raise ValueError(f"{flag} is not available with --preset {CROSS_PRESET} (it "
                             "writes the errors at the control points over --grid-xy)")
    return parse_grid(s.grid_xy)


def cross_sweep(s, progress: Callable[[str], None] | None = None):
    """The cross table (``s.config`` file, else the preset) over ``s.grid_xy`` positions
    spanning both strokes, the paper's rail error ``s.variant`` on the X rails and, the same,
    on the Y rails: ``((X, Y) positions (m), the errors, the failure's message or None, the
    CSV's text or None)``."""
    import numpy as np

    from .._core.aot import cached_program
    from ..io.cross_config import load_cross_config
    from ..io.cross_csv import cross_errors_csv
    from ..machine.cross import build_cross
    from ..machine.majda2012 import paper_variant
    from ..machine.paper_cross import majda2012_cross_spec
    from ..machine.volumetric import cross_errors

    say = progress or (lambda text: None)
    nx, ny = check_cross(s)
    spec = load_cross_config(s.config) if s.config else majda2012_cross_spec()
    say(f"building the {s.config or CROSS_PRESET} machine ...")
    cross = build_cross(spec)
    X = np.linspace(-0.5, 0.5, nx) * cross.x_stroke
    Y = np.linspace(-0.5, 0.5, ny) * cross.y_stroke
    say(f"solving the equilibrium at {nx} x {ny} positions ...")
    run = cached_program(cross_errors, "machine.volumetric.cross_errors",
                         compiler_options={"xla_backend_optimization_level": 0})
    rails = paper_variant(s.variant)
    e = run(cross, rails, rails, X, Y)
    ok = np.asarray(e.converged)
    if not ok.all():
        return (X, Y), e, ("the equilibrium did not converge at "
                           f"{int((~ok).sum())} of the (X, Y) positions"), None
    return (X, Y), e, None, cross_errors_csv(e)
