"""The design job: the machine layout that minimises an error statistic over random rails (or the
fit's predicted σ for a measurement plan), every output of ``diffguide design``
(:func:`design_job`; the command line and a notebook run the same code).

``DesignSettings`` holds every option of ``diffguide design`` (its attribute names are the
options' destinations); :func:`design_job` reads the machine, parses the objective, the
constraints and the plan, runs :func:`diffguide.studies.design.design` and returns a
:class:`DesignJobResult` holding the study's :class:`~diffguide.studies.DesignResult` and the
files' text; :meth:`DesignJobResult.write` writes them (each atomically) and the convergence
figure. Nothing heavy is imported until the job runs.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from .._core.limits import MAX_MESH_DIVISIONS
from .study import check_study

# diffguide.studies.design_space.VARIABLES / CONSTRAINTS, named here so that the settings import
# no JAX (tests/test_design.py checks they agree): name -> (user unit, SI per user unit)
VARIABLE_UNITS = {"thickness": ("mm", 1e-3), "carriage_spacing": ("mm", 1e-3),
                  "rail_spacing": ("mm", 1e-3), "preload_fraction": ("%", 1e-2),
                  "E": ("GPa", 1e9)}
CONSTRAINT_UNITS = {"mass": "kg", "preload": "N", "spacing": "mm", "rail_length": "mm"}


@dataclasses.dataclass(frozen=True)
class DesignSettings:
    """Every option of ``diffguide design``, with the command line's defaults (user units, as
    the options: mm, %, GPa, µm). Checked at construction (``ValueError`` naming the option and
    its range); the objective, the constraints and what needs the machine are checked in
    :func:`design_job`, before any work. ``mesh`` (``"NXxNY"``) sets ``nx``/``ny`` where they
    are not given. ``out``, ``json``, ``plot``: the files :meth:`DesignJobResult.write`
    writes by default (``plot`` None: no figure)."""

    vary: tuple[str, ...]  # NAME[=LO:HI] (user units)
    preset: str = "majda2012"
    config: str | None = None
    objective: str = "roll-difference:mean"
    plan: str = "bundled"  # placements CSV or "bundled" (a plan: objective)
    plan_runs: int = 5
    work_point: str | None = None  # "X,Y" (mm), with plan:work
    work_reads: str = "EAX,EBX"
    constraint: tuple[str, ...] | None = None  # "Q<=V", ">=V", "=V"
    rail_rms_um: float = 1.0
    samples: int = 64
    check_samples: int = 64
    max_iter: int = 30
    corr_mm: float = 200.0
    kernel: str = "se"
    planes: str = "both"
    mounting: str = "none"
    positions: str | None = None  # START:STOP:COUNT (mm); default the stroke at 71
    rigid_table: bool = False
    mesh: str | None = None
    chunk: int | None = None
    seed: int = 0
    cpu_devices: int | None = None
    out: str = "design.csv"
    json: str = "design.json"
    plot: str | None = None
    nx: int | None = None
    ny: int | None = None

    def __post_init__(self):
        set_ = (lambda k, v: object.__setattr__(self, k, v))
        set_("vary", (self.vary,) if isinstance(self.vary, str) else tuple(self.vary))
        if self.constraint is not None:
            c = self.constraint
            set_("constraint", (c,) if isinstance(c, str) else tuple(c))
        for name in ("config", "out", "json", "plot"):
            v = getattr(self, name)
            set_(name, None if v is None else str(v))
        if self.mesh is not None and self.nx is None and self.ny is None:
            nx, ny = parse_mesh(self.mesh)
            set_("nx", nx)
            set_("ny", ny)
        self._check()

    def _check(self) -> None:
        if not 8 <= self.samples <= 1_000_000:
            raise ValueError(f"--samples must be in 8..1000000, got {self.samples}")
        if not 0 <= self.check_samples <= 1_000_000:
            raise ValueError(f"--check-samples must be in 0..1000000, got {self.check_samples}")
        if not (math.isfinite(self.rail_rms_um) and 0 < self.rail_rms_um <= 1e4):
            raise ValueError(f"--rail-rms-um must be in (0, 10000] µm, got {self.rail_rms_um}")
        if not 1 <= self.max_iter <= 1000:
            raise ValueError(f"--max-iter must be in 1..1000, got {self.max_iter}")
        if self.rigid_table:
            raise ValueError("--rigid-table: a design varies the elastic table; not supported here")
        check_study(self)
        if not 1 <= self.plan_runs <= 1000:
            raise ValueError(f"--plan-runs must be in 1..1000, got {self.plan_runs}")
        if self.objective == "plan:work" and self.work_point is None:
            raise ValueError("--objective plan:work needs --work-point X,Y (mm)")
        if not self.vary:
            raise ValueError("--vary: at least one design variable is needed")
        names = [parse_vary(v)[0] for v in self.vary]
        if len(set(names)) != len(names):
            raise ValueError(f"--vary: each variable once, got {', '.join(names)}")
        for name in ("nx", "ny"):
            v = getattr(self, name)
            if v is not None and not 1 <= v <= MAX_MESH_DIVISIONS:
                raise ValueError(f"--mesh divisions must be in 1..{MAX_MESH_DIVISIONS}, "
                                 f"got {name} = {v}")

    @classmethod
    def fields(cls) -> tuple[str, ...]:
        """The settings' names (the options' destinations)."""
        return tuple(f.name for f in dataclasses.fields(cls))


@dataclasses.dataclass
class DesignJobResult:
    """What :func:`design_job` computed: the study's result
    (:class:`~diffguide.studies.DesignResult`, SI), its history CSV and JSON text (user
    units), and the convergence figure's title."""

    settings: DesignSettings
    result: object
    history_csv: str
    json_text: str
    title: str

    def write(self, out: str | None = None, *, json: str | None = None,
              plot: str | None = None) -> list[str]:
        """Write the history CSV to ``out``, the result to ``json`` and, where ``plot`` is
        given, the convergence figure (PNG): each file atomically, as ``diffguide design``
        does; the defaults are the settings'. Returns the paths written."""
        from ..io.atomic import atomic_savefig, atomic_write_text

        s = self.settings
        out, json, plot = out or s.out, json or s.json, plot or s.plot
        atomic_write_text(out, self.history_csv)
        atomic_write_text(json, self.json_text)
        if not plot:
            return [out, json]
        from ..plotting import figure_of
        from ..plotting.design import plot_design_convergence

        atomic_savefig(figure_of(plot_design_convergence(self.result, self.title)), plot,
                       dpi=110)
        return [out, json, plot]


def parse_vary(text: str) -> tuple[str, tuple[float, float] | None]:
    """``NAME=LO:HI`` (user units) → ``(NAME, (lo, hi) SI)``; ``NAME`` → ``(NAME, None)``."""
    name, _, rng = text.partition("=")
    name = name.strip()
    if name not in VARIABLE_UNITS:
        raise ValueError(f"--vary {text!r}: NAME must be one of {', '.join(VARIABLE_UNITS)}")
    unit, scale = VARIABLE_UNITS[name]
    if not rng:
        return name, None
    try:
        lo, hi = (float(v) for v in rng.split(":"))
    except ValueError:
        raise ValueError(f"--vary {text!r}: bounds must be LO:HI in {unit}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
        raise ValueError(f"--vary {text!r}: bounds must be finite with 0 < LO < HI ({unit})")
    return name, (lo * scale, hi * scale)


def parse_mesh(text: str) -> tuple[int, int]:
    """``"20x10"`` → ``(20, 10)``, each in ``1..MAX_MESH_DIVISIONS``."""
    parts = str(text).lower().replace("×", "x").split("x")
    try:
        nx, ny = (int(v) for v in parts)
    except ValueError:
        raise ValueError(f"--mesh must be NXxNY with integers, e.g. 20x10, got {text!r}") from None
    if not (1 <= nx <= MAX_MESH_DIVISIONS and 1 <= ny <= MAX_MESH_DIVISIONS):
        raise ValueError(f"--mesh: both divisions must be in 1..{MAX_MESH_DIVISIONS}, "
                         f"got {text!r}")
    return nx, ny


def design_job(settings: DesignSettings, *,
               progress: Callable[[str], None] | None = None) -> DesignJobResult:
    """Run ``diffguide design``'s work for ``settings``: the objective, the constraints and
    the bounds parsed, the machine read (an imported table refused: a design varies the plate),
    the positions, the measurement plan of a ``plan:`` objective, then
    :func:`diffguide.studies.design.design` and the files' text. ``progress`` receives the
    console's progress lines. ``ValueError`` for bad input, before any work."""
    from ..io.config import default_config, load_config, spec_from_config
    from ..io.design_files import design_json_text, history_csv
    from ..machine.build import with_overrides
    from ..studies.design import design, parse_objective
    from ..studies.design_space import parse_constraint
    from .study import KERNELS, PLANES

    s, say = settings, progress or (lambda text: None)
    objective = parse_objective(s.objective)  # malformed input fails before any solve
    if objective.measure != "plan" and s.work_point is not None:
        raise ValueError("--work-point is read only with --objective plan:work")
    constraints = [parse_constraint(c) for c in s.constraint or ()]
    varied = [parse_vary(v) for v in s.vary]
    cfg = load_config(s.config) if s.config else default_config()
    if cfg.get("table_source"):
        raise ValueError(f"{s.config}: the table is imported from "
                         f"{cfg['table_source']['given']} (source = \"superelement\"): a design "
                         "varies the plate and the layout, which an imported matrix fixes; "
                         "design on the plate model, then reduce the chosen design in your FE code")
    positions = _positions(s, cfg)
    spec = with_overrides(spec_from_config(cfg), nx=s.nx, ny=s.ny)
    say(f"design of {s.config or s.preset} (mesh {s.mesh or 'of the machine file'}): "
        f"{objective.text()} over "
        f"{', '.join(n for n, _ in varied)}; "
        + (f"the {s.plan} plan" if objective.measure == "plan" else f"{s.samples} samples")
        + f" x {len(positions)} positions per evaluation (the first compiles)")
    res = design(
        spec, positions, variables=[n for n, _ in varied], bounds=[b for _, b in varied],
        objective=objective, constraints=constraints, rail_rms=s.rail_rms_um * 1e-6,
        correlation_length=s.corr_mm * 1e-3, kernel=KERNELS[s.kernel], planes=PLANES[s.planes],
        mounting=None if s.mounting == "none" else s.mounting, n_samples=s.samples,
        check_samples=s.check_samples, seed=s.seed, chunk_size=s.chunk,
        max_iterations=s.max_iter, progress=say,
        plan=measurement_plan(s, cfg, positions) if objective.measure == "plan" else None)
    return DesignJobResult(s, res, history_csv(res), design_json_text(res),
                           f"{s.config or s.preset}: {objective.text()}")


def _positions(s: DesignSettings, cfg) -> np.ndarray:
    """The swept positions (m): ``positions`` or the whole stroke at 71, within the stroke."""
    from .positions import default_positions, parse_positions

    positions = default_positions(cfg) if s.positions is None else parse_positions(s.positions)
    half = cfg["machine"]["stroke_mm"] / 2
    if np.max(np.abs(positions)) * 1e3 > half + 1e-9:
        raise ValueError(f"--positions must lie within the ±{half:g} mm stroke of "
                         f"{s.config or s.preset}, got {s.positions!r}")
    return positions


def measurement_plan(s: DesignSettings, cfg, positions):
    """The :class:`~diffguide.studies.design_plan.MeasurementPlan` of ``plan``, ``plan_runs``,
    ``work_point``/``work_reads``, ``rail_rms_um`` at ``positions`` (m)."""
    from ..io.plan_files import read_placement_rows
    from ..planning.instruments import bundled_layout_mm
    from ..studies.design_plan import MeasurementPlan
    from .plan import parse_work_point

    table = (cfg["table"]["length_mm"], cfg["table"]["width_mm"])
    rows = bundled_layout_mm(*table) if s.plan == "bundled" else read_placement_rows(
        s.plan, table)
    work = None
    if s.work_point is not None:
        wx, wy = parse_work_point(s.work_point, table)
        wq = tuple(q.strip().upper() for q in s.work_reads.split(","))
        work = (wx * 1e-3, wy * 1e-3, wq)
    try:
        return MeasurementPlan(tuple((k, x * 1e-3, y * 1e-3) for k, x, y in rows), positions,
                               runs=s.plan_runs, rail_rms=s.rail_rms_um * 1e-6,
                               work_point=work)
    except ValueError as exc:
        raise ValueError(f"--plan {s.plan}: {exc}") from None
