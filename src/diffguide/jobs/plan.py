"""The plan job: where to put the instruments so that the data determine the rails, every output
of ``diffguide plan`` (:func:`plan_job`; the command line and a notebook run the same code).

``PlanSettings`` holds every option of ``diffguide plan`` (its attribute names are the options'
destinations, so a parsed command line maps onto it field for field); :func:`plan_job` reads the
machine, the sites and the plans to start from and compare with, builds the machine family over
the sites, runs the greedy search (:func:`diffguide.planning.plan`) and returns a
:class:`PlanResult` holding the plan and every file of the output folder;
:meth:`PlanResult.write` writes the folder (atomically, :class:`diffguide.io.outdir.
OutputFolder`). Nothing heavy is imported until the job runs.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Callable
from pathlib import Path

from .._core.limits import MAX_MESH_DIVISIONS

#: What each instrument kind reads (:data:`diffguide.planning.KINDS`), restated so that the
#: settings are checked without importing JAX (tests/test_plan.py asserts they agree).
KIND_READS = {
    "level": ("EBX", "EAX"),
    "interferometer": ("EBX", "ECX"),
    "straightness": ("EYX", "EZX"),
}
CRITERIA = ("worst", "A", "D", "work")
#: What a work point's predicted errors may be (``--work-reads``).
WORK_QUANTITIES = ("EYX", "EZX", "EAX", "EBX", "ECX")
#: Candidate sites of a ``--grid`` at most.
MAX_GRID_SITES = 400


@dataclasses.dataclass(frozen=True)
class PlanSettings:
    """Every option of ``diffguide plan``, with the command line's defaults (lengths in mm,
    reading σ in µm/m or µm, as the options; ``None``: the configuration's ``[fit]`` value,
    else the built-in one). Checked at construction (``ValueError`` naming the option and its
    range); the checks that need the machine (sites on the table, the plans' files) run in
    :func:`plan_job`, before any work. ``out``: the output folder :meth:`PlanResult.write`
    writes by default."""

    preset: str = "majda2012"
    config: str | None = None
    out: str | None = None
    levels: int = 4
    level_sigma_urad: float = 4.0
    level_reads: str = "EBX,EAX"
    interferometers: int = 1
    interferometer_sigma_urad: float = 2.0
    interferometer_reads: str = "EBX,ECX"
    straightness: int = 0
    straightness_sigma_um: float = 1.0
    straightness_reads: str = "EYX,EZX"
    grid: str = "7x3"  # NXxNY candidate sites (unless sites)
    sites: str | None = None  # candidate sites CSV
    start: str | None = None  # placements CSV or "bundled"
    compare: str | None = None  # placements CSV, "bundled" or "none"; default start, else bundled
    positions: int = 36
    runs: int = 5
    unidirectional: bool = False
    rail_rms_um: float = 1.0
    criterion: str = "worst"
    work_point: str | None = None  # "X,Y" (mm)
    work_reads: str = "EAX,EBX,ECX"
    structure: str | None = None  # estimate or fixed
    thickness_prior_mm: str | None = None  # "VALUE,LO,HI" (mm)
    preload_prior: str | None = None  # "VALUE,LO,HI" (fraction of C)
    stiffness_prior: str | None = None  # "VALUE,LO,HI"
    draws: int = 8
    no_plots: bool = False
    nx: int | None = None
    ny: int | None = None
    mesh: str | None = None  # the mesh as given ("20x10"), for report.json

    def __post_init__(self):
        for name in ("config", "out", "sites", "start", "compare"):
            v = getattr(self, name)
            object.__setattr__(self, name, None if v is None else str(v))
        self._check()

    def _check(self) -> None:
        if not 4 <= self.positions <= 1000:
            raise ValueError(f"--positions must be in [4, 1000], got {self.positions}")
        if not 1 <= self.runs <= 1000:
            raise ValueError(f"--runs must be in [1, 1000], got {self.runs}")
        if not (math.isfinite(self.rail_rms_um) and 0 < self.rail_rms_um <= 1000):
            raise ValueError(f"--rail-rms-um must be in (0, 1000] µm, got {self.rail_rms_um}")
        if not 1 <= self.draws <= 100:
            raise ValueError(f"--draws must be in [1, 100], got {self.draws}")
        if self.criterion not in CRITERIA:
            raise ValueError(f"--criterion must be one of {', '.join(CRITERIA)}, "
                             f"got {self.criterion!r}")
        if self.criterion == "work" and self.work_point is None:
            raise ValueError("--criterion work needs --work-point X,Y (mm)")
        for name in ("nx", "ny"):
            v = getattr(self, name)
            if v is not None and not 1 <= v <= MAX_MESH_DIVISIONS:
                raise ValueError(f"--{name} must be an integer in [1, {MAX_MESH_DIVISIONS}], "
                                 f"got {v}")
        for kind, count, sig, reads in self.instrument_options():
            if not 0 <= count <= 50:
                raise ValueError(f"the number of {kind}s must be in [0, 50], got {count}")
            if not (math.isfinite(sig) and sig > 0):
                raise ValueError(f"the {kind} reading σ must be > 0, got {sig * 1e6:g}")
            q = _quantities(reads)
            if not q or any(x not in KIND_READS[kind] for x in q):
                raise ValueError(f"--{kind}-reads: a {kind} reads "
                                 f"{' and/or '.join(KIND_READS[kind])}, got {reads!r}")
        if self.levels + self.interferometers + self.straightness == 0:
            raise ValueError(
                "no instruments to place (--levels, --interferometers, --straightness are all 0)")

    def instrument_options(self) -> tuple[tuple[str, int, float, str], ...]:
        """``(kind, count, σ of one reading in SI, reads)`` of every instrument kind."""
        return (("level", self.levels, self.level_sigma_urad * 1e-6, self.level_reads),
                ("interferometer", self.interferometers, self.interferometer_sigma_urad * 1e-6,
                 self.interferometer_reads),
                ("straightness", self.straightness, self.straightness_sigma_um * 1e-6,
                 self.straightness_reads))

    @classmethod
    def fields(cls) -> tuple[str, ...]:
        """The settings' names (the options' destinations)."""
        return tuple(f.name for f in dataclasses.fields(cls))


@dataclasses.dataclass
class PlanResult:
    """What :func:`plan_job` computed: the plan (:class:`diffguide.planning.Plan`), the sites
    ``{name: (x, y)}`` (m), the placements started from and compared with, the report
    (``report.json``'s dict) and the output folder's files (``{name: text or figure}``, in the
    order written)."""

    settings: PlanSettings
    plan: object
    sites: dict
    start: list
    compare: list | None
    report: dict
    files: dict

    def write(self, out: str | Path | None = None, *,
              checkpoint: Callable[[], None] = lambda: None, flag: str = "--out") -> list[str]:
        """Write the output folder ``out`` (default: the settings' ``out``) as ``diffguide plan
        --out`` does: staged and swapped into place with its marker
        (:class:`diffguide.io.outdir.OutputFolder`; an earlier output of ``plan`` there is
        replaced, any other non-empty folder refused). Returns the names written."""
        from ..io.outdir import OutputFolder

        out = self.settings.out if out is None else out
        if out is None:
            raise ValueError("no output folder: give write() a folder or PlanSettings(out=...)")
        with OutputFolder(Path(out), "plan", flag, checkpoint=checkpoint) as staged:
            staged.write(self.files)
            staged.commit()
        return list(self.files)


def plan_job(settings: PlanSettings, *,
             progress: Callable[[str], None] | None = None) -> PlanResult:
    """Run ``diffguide plan``'s work for ``settings``: the machine, the candidate sites, the
    placements to start from and to compare with, the machine family over the sites, the
    greedy plan (:func:`diffguide.planning.plan`), the report and the figures. ``progress``
    receives the console's progress lines. ``ValueError`` for bad input, before any work."""
    import numpy as np

    from ..io.config import default_config, load_config
    from ..io.report_text import jsonable
    from ..io.plan_files import plan_csv, plan_report
    from ..planning import plan

    s, say = settings, progress or (lambda text: None)
    t_start = time.perf_counter()
    cfg = load_config(s.config) if s.config else default_config()
    instruments = _instruments(s)
    sites = _sites(s, cfg)
    candidates = tuple(sites)
    start, compare = _start_and_compare(s, cfg, sites)
    used = {k for k, _ in (compare or []) + start}
    instruments = [i for i in instruments if i.count > 0 or i.kind in used]
    work = _work_point(s, cfg, sites)
    family, priors = _family(s, cfg, sites, len(candidates), instruments, say)
    half = cfg["machine"]["stroke_mm"] / 2
    result = plan(family, np.linspace(-half, half, s.positions) * 1e-3, instruments=instruments,
                  criterion=s.criterion, compare=compare, start=start,
                  rail_rms=s.rail_rms_um * 1e-6, runs=s.runs, bidirectional=not s.unidirectional,
                  candidates=candidates, work_point=work, progress=say, n_draws=s.draws)
    say(f"plan: worst profile σ {result.best.worst * 1e6:.3f} µm"
        + (f" (your plan: {result.compare.worst * 1e6:.3f} µm)" if compare else "")
        + f", prior only {result.prior.worst * 1e6:.3f} µm; {result.seconds:.1f} s")
    report = plan_report(result, sites, start, compare, {
        "command": "diffguide plan",
        "preset": None if s.config else s.preset,
        "config": s.config,
        "mesh": s.mesh,  # None: the machine's default table mesh
        "rail_rms_um": s.rail_rms_um,
        "positions": s.positions,
        "runs": s.runs,
        "directions": 1 if s.unidirectional else 2,
        "structure": "estimate" if priors.active() else "fixed",
        "draws": s.draws,
    })
    files = {"plan.csv": plan_csv(result)}
    if not s.no_plots:
        files.update(_figures(result, cfg, compare))
    report["total_seconds"] = time.perf_counter() - t_start
    files["report.json"] = json.dumps(jsonable(report), indent=1, allow_nan=False) + "\n"
    return PlanResult(s, result, sites, start, compare, report, files)


def _quantities(reads: str) -> tuple[str, ...]:
    return tuple(q.strip().upper() for q in reads.split(",") if q.strip())


def _table_mm(cfg) -> tuple[float, float]:
    return cfg["table"]["length_mm"], cfg["table"]["width_mm"]


def _instruments(s: PlanSettings) -> list:
    """The :class:`~diffguide.planning.Instrument` of every kind (checked by the settings)."""
    from ..planning import Instrument

    return [Instrument(kind, count, _quantities(reads), sig)
            for kind, count, sig, reads in s.instrument_options()]


def parse_grid(text: str) -> tuple[int, int]:
    """``--grid NXxNY`` → ``(nx, ny)``, at most :data:`MAX_GRID_SITES` sites."""
    parts = str(text).lower().replace("×", "x").split("x")
    try:
        nx, ny = (int(v) for v in parts)
    except ValueError:
        nx = ny = 0
    if not (1 <= nx <= MAX_GRID_SITES and 1 <= ny <= MAX_GRID_SITES):
        raise ValueError(f"--grid must be NXxNY with integers >= 1, e.g. 7x3, got {text!r}")
    if nx * ny > MAX_GRID_SITES:
        raise ValueError(f"--grid {text}: at most {MAX_GRID_SITES} sites")
    return nx, ny


def _sites(s: PlanSettings, cfg) -> dict:
    """Candidate sites ``{name: (x, y)}`` (m): ``sites`` or the ``grid``."""
    from ..io.plan_files import read_sites
    from ..planning.instruments import grid_sites

    if s.sites:
        return read_sites(s.sites, _table_mm(cfg))
    if cfg.get("table_source"):  # an imported table knows only its retained points
        from ..io.table_source import retained_points

        return retained_points(cfg)
    nx, ny = parse_grid(s.grid)
    return grid_sites(cfg["table"]["length_mm"] * 1e-3, cfg["table"]["width_mm"] * 1e-3, nx, ny)


def _start_and_compare(s: PlanSettings, cfg, sites):
    """``start`` and the plan to compare with (``compare``; by default the ``start`` plan
    where given, else the bundled layout) as ``(kind, site)``, adding their sites to ``sites``
    where new."""
    from ..io.plan_files import read_placements

    table = _table_mm(cfg)
    start = [] if s.start is None else read_placements(s.start, "--start", table, sites)
    which = s.compare if s.compare is not None else (s.start or "bundled")
    compare = None if which == "none" else read_placements(which, "--compare", table, sites)
    return start, compare


def parse_work_point(text: str, table_mm) -> tuple[float, float]:
    """``--work-point X,Y`` (mm), checked to lie on the ``table_mm = (length, width)`` top."""
    from ..planning.instruments import check_on_table

    try:
        wx, wy = (float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--work-point must be X,Y (mm), got {text!r}") from None
    check_on_table("work point", wx, wy, table_mm, "--work-point")
    return wx, wy


def _work_point(s: PlanSettings, cfg, sites):
    """``("WORK", quantities)`` from ``work_point``/``work_reads`` (the site added to
    ``sites``), or None."""
    if s.work_point is None:
        return None
    wx, wy = parse_work_point(s.work_point, _table_mm(cfg))
    wq = tuple(q.strip().upper() for q in s.work_reads.split(","))
    if not wq or any(q not in WORK_QUANTITIES for q in wq):
        raise ValueError(f"--work-reads must be among {','.join(WORK_QUANTITIES)}, "
                         f"got {s.work_reads!r}")
    sites["WORK"] = (wx * 1e-3, wy * 1e-3)
    return ("WORK", wq)


def _family(s: PlanSettings, cfg, sites, n_candidates, instruments, say):
    """The machine family over ``sites`` (structure unknown as ``diffguide fit`` has it, or as
    the settings say) and its priors, after a line saying what is planned."""
    from ..inverse import MachineFamily
    from .machine import config_machine
    from .fit import structure_priors

    priors = structure_priors(s, cfg)

    def make_machine(**kw):
        return config_machine(cfg, nx=s.nx, ny=s.ny, points=sites, **kw)

    kinds = ", ".join(f"{i.count} {i.kind}(s) reading {'+'.join(i.quantities)}"
                      for i in instruments if i.count)
    say(f"plan: {n_candidates} candidate sites, {kinds}; {s.positions} positions x {s.runs} runs"
        + ("" if s.unidirectional else " x 2 directions"))
    return MachineFamily.build(make_machine, priors, progress=say), priors


def _figures(result, cfg, compare) -> dict:
    """``plan.png`` (the table top) and ``sigma.png`` (the profiles' σ along the rails)."""
    from ..plotting import figure_of
    from ..plotting.plan import plot_plan_sigma, plot_plan_sites

    ax = plot_plan_sites(
        result.sites, result.candidates, result.placements, compare=compare or (),
        table_mm=_table_mm(cfg), rails_y_mm=cfg["guideway"]["rail_y_mm"],
        carriages_x_mm=cfg["guideway"]["carriage_x_mm"],
        title=f"measurement plan ({result.criterion}): worst profile σ "
        f"{result.best.worst * 1e6:.2f} µm"
        + (f", your plan {result.compare.worst * 1e6:.2f} µm" if compare else ""))
    sig = {"plan": result.best.sigma}
    if compare:
        sig["your plan"] = result.compare.sigma
    sig["prior only"] = result.prior.sigma
    axes = plot_plan_sigma(result.best.s, sig, background=("prior only",),
                           title="predicted σ of the rail profiles (mean and common slope "
                           "removed)")
    return {"plan.png": figure_of(ax), "sigma.png": figure_of(axes)}
