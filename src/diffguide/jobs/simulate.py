"""The simulate job: the table's equilibrium on its carriages at every position and the six
joint kinematic errors at the control points, every output of ``diffguide simulate``
(:func:`simulate_job`). A cross table (``preset="majda2012-cross"`` or a machine file with a
saddle) runs :func:`diffguide.jobs.simulate_cross.cross_sweep` instead: the same settings and
result, the preset or the file deciding.

:class:`SimulateSettings` holds every option (lengths in mm, errors in µm and µrad, as the
options); :func:`simulate_job` returns a :class:`SimulateResult` holding the errors, the text
of the CSV and the compensation table, the figures and the warnings; its
:meth:`~SimulateResult.write` writes them (each file atomically). Nothing heavy is imported
until the job runs.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

from .outputs import Figure, renamed, write_files
from .simulate_cross import CROSS_PRESET, check_cross, cross_sweep
#: Exit status when the equilibrium did not converge (nothing written).
EXIT_NOT_CONVERGED = 3


@dataclasses.dataclass(frozen=True)
class SimulateSettings:
    """Every option of ``diffguide simulate``, with the command line's defaults. ``variant``
    the paper's rail error 1..3 (unless ``rails``, a rails CSV); ``positions``
    ``START:STOP:COUNT`` (mm; default the whole stroke at 71); ``nx``/``ny`` the mesh's
    divisions (``None``: the machine's; ``mesh`` its text as given); ``out``, ``plot``,
    ``field_plot``, ``export_compensation`` the files; ``grid_xy`` the cross table's
    ``NXxNY`` positions. Checked at construction (``ValueError`` naming the option); the checks
    that need the machine run in :func:`simulate_job`, before any work."""

    preset: str = "majda2012"
    config: str | None = None
    grid_xy: str = "9x9"
    variant: int = 1
    rails: str | None = None
    positions: str | None = None
    rigid_table: bool = False
    mesh: str | None = None
    nx: int | None = None
    ny: int | None = None
    out: str | None = None
    plot: str | None = None
    export_compensation: str | None = None
    at: str = "P5"
    comp_format: str = "csv"
    axis_side: str | None = None
    export_cec_axis_names: str | None = None
    export_fanuc_detection_unit: str | None = None
    export_isg_axis_numbers: str | None = None
    export_isg_max_records: str | None = None
    export_heidenhain_values: str | None = None
    export_isg_cross_values: str | None = None
    machine_x0_mm: float = 0.0
    tol_um: float = 2.0
    tol_urad: float = 5.0
    field_plot: str | None = None
    field_at: float | None = None

    def __post_init__(self):
        for name in ("config", "rails", "out", "plot", "export_compensation", "field_plot"):
            v = getattr(self, name)
            object.__setattr__(self, name, None if v is None else str(v))
        self._check()

    def _check(self) -> None:
        from .export import check_tolerances
        from .positions import parse_positions, settle_mesh

        if self.variant not in (1, 2, 3):
            raise ValueError(f"--variant must be 1, 2 or 3, got {self.variant!r}")
        if self.preset == CROSS_PRESET and not self.config:
            check_cross(self)
            return
        if self.positions is not None:
            parse_positions(self.positions)
        if self.field_at is not None and not math.isfinite(self.field_at):
            raise ValueError(f"--field-at must be a finite position (mm), got {self.field_at}")
        if not math.isfinite(self.machine_x0_mm):
            raise ValueError(f"--machine-x0-mm must be finite, got {self.machine_x0_mm}")
        settle_mesh(self)
        check_tolerances(self)

    @classmethod
    def fields(cls) -> tuple[str, ...]:
        """The settings' names (the options' destinations)."""
        return tuple(f.name for f in dataclasses.fields(cls))


@dataclasses.dataclass
class SimulateResult:
    """What :func:`simulate_job` computed: the positions (m; for a cross table the X and Y
    positions), the errors (:class:`~diffguide.machine.kinematics.JointErrors`, or the cross
    table's), whether every equilibrium converged (``failure``: the message where not), the
    files (``{path: text or Figure}``, in the order written: the CSV first), and the warnings
    (the compensation table's, the model's validity)."""

    settings: SimulateSettings
    positions: object
    errors: object
    converged: bool
    failure: str | None
    files: dict
    compensation_warnings: list
    validity_warnings: list

    @property
    def exit_code(self) -> int:
        """``diffguide simulate``'s exit status: 0, or 3 where a solve did not converge."""
        return 0 if self.converged else EXIT_NOT_CONVERGED

    def write(self, out: str | None = None) -> list[str]:
        """Write the CSV to ``out`` (default: the settings' ``out``) and the other files
        (figures, compensation table) to their paths, each atomically; returns the paths.
        ``ValueError`` where the sweep did not converge (nothing written)."""
        if not self.converged:
            raise ValueError(f"{self.failure}; nothing written")
        if out is None and self.settings.out is None:
            raise ValueError("no output file: give write() a path or SimulateSettings(out=...)")
        return write_files(renamed(self.files, out))


def is_cross(s: SimulateSettings) -> bool:
    """Whether ``s`` runs the cross table: the cross preset, or a machine file with a saddle
    (:func:`~diffguide.io.cross_config.is_cross_config`)."""
    if s.config:
        from ..io.cross_config import is_cross_config

        return is_cross_config(s.config)
    return s.preset == CROSS_PRESET


def simulate_job(settings: SimulateSettings, *,
                 progress: Callable[[str], None] | None = None) -> SimulateResult:
    """Run ``diffguide simulate``'s work for ``settings``: build the machine, solve the
    equilibrium at every position, and compute the CSV, the figures, the compensation table
    and the warnings. ``progress`` receives the console's progress lines. ``ValueError`` for
    bad input, before any work."""
    import numpy as np

    from ..io.errors_csv import joint_errors_csv
    from ..io.rails_csv import read_rails_csv
    from .machine import config_machine
    from ..machine.majda2012 import paper_variant
    from .export import check_export
    from .positions import stroke_positions
    from .study import machine_config

    s, say = settings, progress or (lambda text: None)
    if is_cross(s):
        xy, e, failure, text = cross_sweep(s, progress)
        return SimulateResult(s, xy, e, failure is None, failure,
                              {} if failure else {s.out: text}, [], [])
    cfg = machine_config(s)
    positions = _positions(s, cfg, stroke_positions(cfg, s.positions))
    if s.export_compensation:  # every refusal of the export, before any work
        check_export(s, cfg, positions * 1e3, s.machine_x0_mm)
    rails = read_rails_csv(s.rails) if s.rails else paper_variant(s.variant)
    name = s.config or s.preset
    say(f"building the {name} machine ...")
    machine = config_machine(cfg, nx=s.nx, ny=s.ny)
    if s.rigid_table:
        machine = machine.with_rigid_table()
    say(f"solving the equilibrium at {len(positions)} positions ...")
    je = _sweep(machine, rails, positions)
    ok = np.asarray(je.converged)
    if not ok.all():
        bad = ", ".join(f"{x * 1e3:g} mm" for x in positions[~ok])
        return SimulateResult(s, positions, je, False,
                              f"the equilibrium did not converge at {bad}", {}, [], [])
    errs = je.user_units()
    if s.export_compensation and s.at not in je.point_names:
        raise ValueError(
            f"--at must be one of the points {', '.join(je.point_names)}, got {s.at!r}")
    files: dict = {s.out: joint_errors_csv(positions, je.point_names, je.points_xy, errs)}
    if s.field_plot:
        files[s.field_plot] = _field_figure(s, name, machine, je, positions)
    comp_warnings: list = []
    if s.export_compensation:
        comp, comp_warnings = _compensation(s, cfg, name, je, errs, positions)
        files.update(comp)
    if s.plot:
        files[s.plot] = _figure(s, name, je, errs, positions)
    return SimulateResult(s, positions, je, True, None, files, comp_warnings,
                          _validity(s, machine, rails, positions, je))


def _positions(s: SimulateSettings, cfg: dict, positions):
    """``positions`` (m), with ``field_at`` checked within them."""
    lo, hi = positions.min() * 1e3, positions.max() * 1e3
    if s.field_at is not None and not (lo - 1e-9 <= s.field_at <= hi + 1e-9):
        raise ValueError(f"--field-at must lie within the swept positions [{lo:g}, {hi:g}] mm, "
                         f"got {s.field_at:g}")
    return positions


def _sweep(machine, rails, positions):
    """:func:`~diffguide.machine.kinematics.joint_errors` at every position, stored as an
    exported program in the cache folder: a second run does not trace it; it runs once per
    process, so compiled at XLA's optimisation level 0 (the compile time dominates, the sweep's
    run time stays in the milliseconds)."""
    import numpy as np

    from .._core.aot import cached_program
    from ..machine.kinematics import joint_errors

    sweep = cached_program(joint_errors, "machine.kinematics.joint_errors",
                           compiler_options={"xla_backend_optimization_level": 0})
    return sweep(machine, rails, np.asarray(positions, dtype=float))


def _field_figure(s, name, machine, je, positions) -> Figure:
    """``field_plot``: EZX, roll and pitch over the table top at the position nearest
    ``field_at`` (default the last)."""
    import numpy as np

    from ..machine.kinematics import error_field
    from ..plotting import figure_of
    from ..plotting.errors import plot_error_field

    k = len(positions) - 1
    if s.field_at is not None:
        k = int(np.argmin(np.abs(positions * 1e3 - s.field_at)))
    xy, field = error_field(machine, je, k)
    return Figure(figure_of(plot_error_field(
        xy, np.asarray(field) * 1e6,
        f"{name}: errors over the table at x = {positions[k] * 1e3:g} mm")), 100)


def _compensation(s, cfg, name, je, errs, positions):
    """``export_compensation``: the table of ``at`` in ``comp_format`` (``{path: text}``), and
    a warning where another point departs from the rigid-body prediction from it."""
    from pathlib import Path

    import numpy as np

    from ..studies.compensation import location_warnings
    from ..studies.exports import export_compensation
    from .export import export_spec

    what = f"rails {s.rails}" if s.rails else f"variant {s.variant}"
    j = list(je.point_names).index(s.at)
    base = Path(s.export_compensation)
    files = export_compensation(
        export_spec(s, cfg), positions * 1e3, np.asarray(je.errors)[:, j, :], None,
        x0_mm=s.machine_x0_mm, point=s.at, source=f"simulated, {name}, {what}",
        exx_includes_lead=False)  # a simulation: ideal drive, no lead error
    paths = {str(base if not suffix else base.with_name(base.stem + suffix)): text
             for suffix, text in files.items()}
    warnings = location_warnings(errs, je.point_names, np.asarray(je.points_xy), s.at,
                                 s.tol_um, s.tol_urad)
    return paths, [str(w) for w in warnings]


def _figure(s, name, je, errs, positions) -> Figure:
    """``plot``: the six errors against position."""
    from ..plotting import figure_of
    from ..plotting.errors import plot_joint_errors

    what = f"rails from {s.rails}" if s.rails else f"variant {s.variant}"
    table = "rigid table" if s.rigid_table else "elastic table"
    return Figure(figure_of(plot_joint_errors(positions * 1e3, errs, je.point_names,
                                              f"{name}, {what}, {table}")), 110)


def _validity(s, machine, rails, positions, je) -> list:
    """The model's validity checks of this sweep (:mod:`diffguide.machine.validity`): rails
    extrapolated beyond their samples, rails or contacts beyond the small-deflection range,
    carriages lifted off, rotations beyond the small-angle bound."""
    import numpy as np

    from ..io.rails_csv import sampled_ranges
    from ..machine import validity

    out = []
    if s.rails:
        out += validity.rail_extrapolation(machine, positions, sampled_ranges(s.rails))
    out += validity.rail_range(machine, rails, positions)
    out += validity.contact_range(machine, rails, je)
    out += validity.large_rotations(np.asarray(je.errors)[..., 3:], "the joint errors")
    return list(dict.fromkeys(out))
