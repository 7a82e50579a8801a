"""The fit job: measured joint errors -> rail straightness profiles, every output of
``diffguide fit`` (:func:`fit_job`; the command line and a notebook run the same code).

``FitSettings`` holds every option of ``diffguide fit`` (its attribute names are the options'
destinations, so the command line's helpers read either); :func:`fit_job` reads the files,
builds the machine family, fits, computes the report and the figures, and returns a
:class:`FitResult` holding them and the text of every file; :meth:`FitResult.write` writes the
output folder (atomically, :class:`diffguide.io.outdir.OutputFolder`) and the compensation
table. Nothing heavy is imported until the job runs.
"""

from __future__ import annotations

import dataclasses
import json
import math
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

#: Exit status of ``diffguide fit`` when the results are written but the fit did not converge.
EXIT_NOT_CONVERGED = 3
#: The output folder the report's planner command names when the settings give none.
DEFAULT_OUT = "FIT_DIR"


@dataclasses.dataclass(frozen=True)
class FitSettings:
    """Every option of ``diffguide fit``, with the command line's defaults (lengths in mm,
    straightness in µm, as the options; ``None``: the configuration's ``[fit]`` value, else the
    built-in one). Checked at construction (``ValueError`` naming the option and its range);
    the checks that need the machine or the data run in :func:`fit_job`, before any work.

    ``out`` is the output folder the report's planner command names (``report.json``'s
    ``plan_suggestion``); :meth:`FitResult.write` writes there by default.
    """

    measurements: tuple[str, ...]
    preset: str = "majda2012"
    config: str | None = None
    layout: str = "auto"  # measurements' layout: auto, long or wide
    profile: tuple[str, ...] | None = None
    profile_set: tuple[str, ...] | None = None
    accept_file_conflicts: bool = False
    encoding: str | None = None
    x0_mm: float | str | None = None  # mm, or "middle"
    machine_x0_mm: float | None = None
    allow_many_positions: bool = False
    knot_spacing_mm: float | None = None
    lam: float | None = None  # fixed smoothness weight (whitened units)
    max_steps: int = 60
    criterion: str | None = None  # ml or gcv
    structure: str | None = None  # estimate or fixed
    thickness_prior_mm: str | None = None  # "VALUE,LO,HI" (mm)
    preload_prior: str | None = None  # "VALUE,LO,HI" (fraction of C)
    stiffness_prior: str | None = None  # "VALUE,LO,HI"
    rail_waviness_um: float | None = None
    rail_joints_mm: tuple[float, ...] | None = None
    rigid: bool | None = None
    no_plots: bool = False
    tolerance_um: float | None = None
    truth: str | None = None
    export_compensation: str | None = None
    comp_format: str = "csv"
    axis_side: str | None = None
    export_cec_axis_names: str | None = None
    export_fanuc_detection_unit: str | None = None
    export_isg_axis_numbers: str | None = None
    export_isg_max_records: str | None = None
    export_heidenhain_values: str | None = None
    export_isg_cross_values: str | None = None
    comp_points: int = 71
    at: str = "P5"
    at_z_mm: float = 0.0
    tol_um: float = 2.0
    tol_urad: float = 5.0
    nx: int | None = None
    ny: int | None = None
    mesh: str | None = None  # the mesh as given ("20x10"), for the planner command
    out: str | None = None

    def __post_init__(self):
        text = (lambda v: None if v is None else str(v))
        set_ = (lambda k, v: object.__setattr__(self, k, v))
        ms = self.measurements
        set_("measurements", (str(ms),) if isinstance(ms, (str, Path)) else tuple(map(str, ms)))
        for name in ("config", "truth", "export_compensation", "out"):
            set_(name, text(getattr(self, name)))
        for name in ("profile", "profile_set", "rail_joints_mm"):
            if getattr(self, name) is not None:
                set_(name, tuple(getattr(self, name)))
        self._check()

    def _check(self) -> None:
        from .export import check_tolerances
        from .fit_report import check_tolerance

        if not self.measurements:
            raise ValueError("--measurements: at least one file is needed")
        k = self.knot_spacing_mm
        if k is not None and not (1.0 <= k <= 1000.0):
            raise ValueError(f"--knot-spacing-mm must be in [1, 1000] mm, got {k}")
        if not 0 <= self.max_steps <= 10000:
            raise ValueError(f"--max-steps must be an integer in [0, 10000], got {self.max_steps}")
        if self.lam is not None and not (math.isfinite(self.lam) and self.lam > 0):
            raise ValueError(f"--lambda must be a finite number > 0, got {self.lam}")
        w = self.rail_waviness_um
        if w is not None and not (math.isfinite(w) and 0.0 <= w <= 100.0):
            raise ValueError(f"--rail-waviness-um must be an RMS in [0, 100] µm, got {w}")
        for name in ("nx", "ny"):
            v = getattr(self, name)
            if v is not None and not 1 <= v <= 200:
                raise ValueError(f"--{name} must be an integer in [1, 200], got {v}")
        if self.export_compensation:
            if not 2 <= self.comp_points <= 10000:
                raise ValueError(f"--comp-points must be in [2, 10000], got {self.comp_points}")
            if not (math.isfinite(self.at_z_mm) and -500.0 <= self.at_z_mm <= 2000.0):
                raise ValueError(f"--at-z-mm must be in [-500, 2000] mm, got {self.at_z_mm:g}")
            check_tolerances(self)
        check_tolerance(self)

    @classmethod
    def fields(cls) -> tuple[str, ...]:
        """The settings' names (the options' destinations)."""
        return tuple(f.name for f in dataclasses.fields(cls))


@dataclasses.dataclass
class FitResult:
    """What :func:`fit_job` computed: the fits (``{"": elastic, "_rigid": rigid table}``,
    :class:`~diffguide.inverse.RailFit`), their seconds, the profiles (m) on the grid ``s_m``
    (m), the measurements, the report (``report.json``'s dict), the output folder's files
    (``{name: text or PNG bytes}``, in the order written), the compensation table's files
    (``{path: text}``), and the warnings for the console."""

    settings: FitSettings
    fits: dict
    seconds: dict
    measurements: object
    s_m: object
    profiles: dict
    truth: object
    report: dict
    files: dict
    report_figures: dict
    compensation: dict
    compensation_warnings: list
    validity_warnings: list
    t_start: float

    @property
    def converged(self) -> bool:
        return bool(self.fits[""].converged)

    @property
    def exit_code(self) -> int:
        """``diffguide fit``'s exit status: 0 converged, 3 not (the results written)."""
        return 0 if self.converged else EXIT_NOT_CONVERGED

    def folder_files(self, out: str | Path) -> dict:
        """The output folder's files for the folder ``out``: those of :attr:`files`, with the
        report's planner command naming ``out`` where the settings named another folder."""
        files = dict(self.files)
        if self.report.get("plan_suggestion") and str(out) != (self.settings.out or DEFAULT_OUT):
            from .fit_report import html_text, plan_command

            report = dict(self.report, plan_suggestion=plan_command(
                dataclasses.replace(self.settings, out=str(out))))
            files["report.json"] = report_json_text(report)
            files["report.html"] = html_text(files["report.json"], self.report_figures)
        return files

    def write(self, out: str | Path | None = None, *, replace: bool = True,
              checkpoint: Callable[[], None] = lambda: None, flag: str = "--out") -> list[str]:
        """Write the output folder ``out`` (default: the settings' ``out``) as ``diffguide fit
        --out`` does: staged and swapped into place with its marker
        (:class:`diffguide.io.outdir.OutputFolder`; an earlier output of ``fit`` there is
        replaced unless ``replace`` is false, any other non-empty folder refused), then the
        compensation table's files (atomically). Returns the names written in the folder."""
        from ..io.atomic import atomic_write_text
        from ..io.outdir import OutputFolder

        out = self.settings.out if out is None else out
        if out is None:
            raise ValueError("no output folder: give write() a folder or FitSettings(out=...)")
        if not replace and Path(out).is_dir() and any(Path(out).iterdir()):
            raise ValueError(f"{flag} {out}: not empty (replace=False); nothing done")
        files = self.folder_files(out)
        with OutputFolder(Path(out), "fit", flag, checkpoint=checkpoint) as staged:
            staged.write(files)
            staged.commit()
        for path, text in self.compensation.items():
            atomic_write_text(path, text)
        return list(files)


def report_json_text(report: dict) -> str:
    """report.json's text (plain JSON types, :func:`diffguide.io.report_text.jsonable`)."""
    from ..io.report_text import jsonable

    return json.dumps(jsonable(report), indent=1, allow_nan=False) + "\n"


def fit_job(settings: FitSettings, *, progress: Callable[[str], None] | None = None,
            figures=None) -> FitResult:
    """Run ``diffguide fit``'s work for ``settings``: read and merge the measurements, build the
    machine family, fit (and the rigid-table inversion where asked), compute the report, its
    figures and every file's text, and the compensation table. ``progress`` receives the
    console's progress lines; ``figures`` is a :class:`diffguide.plotting.render.FigureWorker`
    (started: the figures drawn in a second process meanwhile; default: drawn here).
    ``ValueError`` for bad input, before any work."""
    from ..inverse import MachineFamily
    from ..io.config import default_config, load_config, spec_from_config
    from ..io.fit_files import profile_grid
    from .machine import config_machine
    from ..plotting.render import FigureWorker

    s, say = settings, progress or (lambda text: None)
    t_start = time.perf_counter()
    cfg = load_config(s.config) if s.config else default_config()
    spec = spec_from_config(cfg)
    info: dict = {}
    meas, priors = _read(s, cfg, info, say)
    points = {n: tuple(map(float, xy)) for n, xy in zip(meas.point_names, meas.points_xy)}

    def make_machine(**kw):
        return config_machine(cfg, nx=s.nx, ny=s.ny, points=points, **kw)

    family = MachineFamily.build(make_machine, priors, progress=say)
    fits, seconds = _fit_all(s, cfg, family, meas, say)
    elastic = fits[""]
    s_m = profile_grid(elastic.basis)
    profiles = {label: f.profiles(s_m) for label, f in fits.items()}
    truth = None
    if s.truth:
        from ..io.rails_csv import rails_at

        raw = rails_at(s.truth, s_m)
        truth = elastic.basis.gauge_fix(s_m, raw.reshape(4, -1), elastic.fix_slope)
        truth = truth.reshape(2, 2, -1)
    figures = figures or FigureWorker()
    with tempfile.TemporaryDirectory(prefix="diffguide-fit-figures-") as tmp:
        try:
            report, files, report_pngs = _outputs(s, meas, fits, profiles, s_m, truth, seconds,
                                                  family.base, t_start, cfg, info, figures,
                                                  Path(tmp))
        except BaseException:
            figures.close(kill=True)  # stop drawing into the folder before it goes
            raise
    compensation, comp_warnings = {}, []
    if s.export_compensation:
        compensation, comp_warnings = _compensation(s, cfg, spec, points, elastic,
                                                    _machine_x0(s, info))
    return FitResult(s, fits, seconds, meas, s_m, profiles, truth, report, files, report_pngs,
                     compensation, comp_warnings, _validity(s, report, meas, cfg), t_start)


def _outputs(s, meas, fits, profiles, s_m, truth, seconds, machine, t_start, cfg, info,
             figures, tmp: Path):
    """The report and every file's text (figures drawn by the figures' process meanwhile, into
    ``tmp``): ``(report, {name: text or PNG bytes}, {name: report figure PNG bytes})``."""
    from ..io.fit_files import fit_csv_text, layout_csv_text, rails_csv_text
    from ..io.fit_posterior import NAME as POSTERIOR
    from ..io.fit_posterior import posterior_json_text
    from .fit_summary import fit_report
    from . import fit_report as rep

    plots = {} if s.no_plots else rep.plot_jobs(meas, fits, profiles, s_m, truth)
    if plots:  # drawn by the figures' process while the rest is computed
        figures.submit(tmp, list(plots.items()), dpi=110)
    elastic = fits[""]
    report = fit_report(
        meas, fits, profiles, seconds, machine, truth=truth, truth_file=s.truth,
        source={"preset": None if s.config else s.preset, "config": s.config,
                "measurements": ", ".join(s.measurements)},
        exit_code=0 if elastic.converged else EXIT_NOT_CONVERGED)
    report["measurements"].update(_coordinates(s, info))
    named = s if s.out else dataclasses.replace(s, out=DEFAULT_OUT)
    report.update(rep.sections(named, report, meas, elastic, s_m, cfg, info))
    report_figures = None if s.no_plots else rep.submit_figures(
        figures, tmp, rep.figure_jobs(report, meas, elastic, s_m))
    files = {"rails.csv": rails_csv_text(s_m, *profiles[""])}
    if "_rigid" in fits:
        files["rails_rigid.csv"] = rails_csv_text(s_m, *profiles["_rigid"])
    files["fit.csv"] = fit_csv_text(meas, fits)
    files["layout.csv"] = layout_csv_text(meas)
    files[POSTERIOR] = posterior_json_text(  # for diffguide predict
        elastic, meas, preset=None if s.config else s.preset, config=s.config, nx=s.nx,
        ny=s.ny, x0_mm=_machine_x0(s, info), machine_cfg=cfg)
    report["total_seconds"] = time.perf_counter() - t_start
    files["report.json"] = report_json_text(report)
    figures.wait()
    pngs = rep.read_figures(report_figures)
    files["report.html"] = rep.html_text(files["report.json"], pngs)
    files.update({name: (tmp / name).read_bytes() for name in plots})
    return report, files, pngs


def _read(s: FitSettings, cfg: dict, info: dict, say):
    """The measurements (checked against the machine) and the structural priors."""
    import numpy as np

    from ..io.importers import read_any
    from .inputs import load_profile_args

    notes: list[str] = []
    meas = read_any(list(s.measurements), s.layout, s.x0_mm, notes, info,
                    allow_many_positions=s.allow_many_positions,
                    allow_conflicts=s.accept_file_conflicts,
                    profile=load_profile_args(s, s.measurements), encoding=s.encoding)
    if s.machine_x0_mm is not None and not s.export_compensation:
        notes.append("--machine-x0-mm places the compensation table: without "
                     "--export-compensation it is only stated in report.json")
    for n in notes:
        say(f"note: {n}")
    check_inputs(meas, s, cfg, info.get("x0_mm", 0.0), _machine_x0(s, info))
    priors = structure_priors(s, cfg)
    lines = ", ".join(map(str, meas.rejected[:10])) + (" ..." if len(meas.rejected) > 10 else "")
    say(f"{meas.source}: {len(meas.readings)} readings -> {meas.n} merged rows in "
        f"{len(meas.channels)} channels at {len(np.unique(meas.position))} positions"
        + (f"; {len(meas.rejected)} outlying readings set aside (lines {lines})"
           if meas.rejected else ""))
    return meas, priors


def check_inputs(meas, s, cfg: dict, x0_mm: float = 0.0, machine_x0_mm: float = 0.0) -> None:
    """Points, positions and the export checked against the machine actually used (``x0_mm``:
    the measurements' x0, named in the message; ``machine_x0_mm``: the export's)."""
    import numpy as np

    from ..inverse.merge import POSITION_TOL

    name = s.config or s.preset
    half_l, half_w = cfg["table"]["length_mm"] / 2e3, cfg["table"]["width_mm"] / 2e3
    for pname, (x, y) in zip(meas.point_names, meas.points_xy):
        if abs(x) > half_l or abs(y) > half_w:
            raise ValueError(
                f"{meas.source}: point {pname!r} at ({x * 1e3:g}, {y * 1e3:g}) mm is off the "
                f"{name} table (|x| <= {half_l * 1e3:g}, |y| <= {half_w * 1e3:g} mm)")
    stroke = cfg["machine"]["stroke_mm"] * 1e-3
    bad = np.abs(meas.position) > stroke / 2 + POSITION_TOL
    if bad.any():
        x = meas.position[bad][0]
        raise ValueError(f"{meas.source}: position {x * 1e3:.4f} mm is outside the {name} "
                         f"stroke (±{stroke / 2 * 1e3:g} mm, to {POSITION_TOL * 1e6:g} µm; "
                         f"x = X − x0 with x0 = {x0_mm:g} mm: "
                         "for positions in machine coordinates give --x0-mm, the machine "
                         "coordinate of mid-stroke, or --x0-mm middle)")
    if len(np.unique(np.round(meas.position, 9))) < 4:
        raise ValueError(f"{meas.source}: at least 4 distinct positions are needed for a fit")
    if s.export_compensation:  # checked here: a refusal after the fit would follow output
        from ..inverse.data import QUANTITIES
        from .export import check_export

        points = list(dict.fromkeys([*cfg["points"], *meas.point_names]))
        if s.at not in points:
            raise ValueError(f"--at must be one of the points {', '.join(points)}, "
                             f"got {s.at!r}")
        half = cfg["machine"]["stroke_mm"] / 2
        check_export(s, cfg, np.linspace(-half, half, s.comp_points), machine_x0_mm)
        if s.comp_format == "fanuc" and QUANTITIES.index("EXX") not in set(
                np.asarray(meas.quantity).tolist()):
            raise ValueError(  # FANUC's pitch table holds the positioning error, lead included
                f"--format fanuc: {', '.join(s.measurements)} hold no EXX (positioning) "
                "readings, so the fit has no lead error of the drive, and a FANUC pitch error "
                "compensation table holds the positioning error with it; measure EXX (a linear "
                "interferometer), or export another --format")


def structure_priors(s, cfg: dict):
    """The structural priors of ``structure``, ``thickness_prior_mm``, ``preload_prior``,
    ``stiffness_prior`` and the configuration (:func:`diffguide.inverse.settings.
    structure_priors`)."""
    from ..inverse.settings import structure_priors as priors

    return priors(cfg, structure=s.structure, thickness_prior_mm=s.thickness_prior_mm,
                  preload_prior=s.preload_prior,
                  stiffness_prior=getattr(s, "stiffness_prior", None))


def _fit_all(s: FitSettings, cfg: dict, family, meas, say):
    """The elastic fit, and the rigid-table inversion when asked for: ``({label: RailFit},
    {label: seconds})``, each summarised through ``say``."""
    from ..inverse import fit_rails, settings

    _, criterion = settings.fit_modes(cfg, s.structure, s.criterion)
    waviness = settings.rail_waviness(cfg, s.rail_waviness_um)
    rigid = settings.rigid_wanted(cfg, s.rigid)
    spacing = None if s.knot_spacing_mm is None else s.knot_spacing_mm * 1e-3
    fits, seconds = {}, {}
    models = [("", family)] + ([("_rigid", family.base.with_rigid_table())] if rigid else [])
    for label, m in models:
        t = time.perf_counter()
        say(f"{'rigid-table' if label else 'elastic'} fit: compiling and solving ...")
        fits[label] = fit_rails(m, meas, knot_spacing=spacing, lam=s.lam,
                                criterion=criterion, max_steps=s.max_steps,
                                waviness=waviness, method="linear" if label else "lm",
                                joints=settings.rail_joints(cfg, s.rail_joints_mm))
        seconds[label] = time.perf_counter() - t
        for line in fit_lines(label, fits[label], meas, seconds[label]):
            say(line)
    return fits, seconds


def fit_lines(label: str, f, meas, seconds: float) -> list[str]:
    """The console's summary of one fit: χ², weight, structure, alignment, joint steps."""
    out = [f"{'rigid-table' if label else 'elastic'} fit: chi2/dof = {f.chi2_dof:.3f} "
           f"(dof {f.dof:.1f}), lambda {f.lam:.3g} ({f.weight.criterion}), "
           f"{f.edf:.1f} effective parameters, {f.steps} LM steps, {f.message}, "
           f"{seconds:.1f} s"]
    for name, v in f.structure.items():
        val, sd = ((v["value"] * 1e3, v["sigma"] * 1e3) if name == "thickness"
                   else (v["value"], v["sigma"]) if name == "stiffness"
                   else (v["value"] * 100, v["sigma"] * 100))
        unit = {"thickness": " mm", "stiffness": ""}.get(name, " % of C")
        what = "table stiffness scale" if name == "stiffness" else name
        out.append(f"  {what}: {val:.3g} ± {sd:.2g}{unit}"
                   + ("" if v["determined"] else " (not determined by the data: prior)"))
    for c, a in zip(f.alignment_channels, f.alignment):
        out.append(f"  alignment slope of {meas.channel_label(c)}: {a * 1e6:.3g} µm/m "
                   "(fitted, as ISO 230-1 removes it)")
    for d in f.joint_steps():
        out.append(f"  step at the rail joint s = {d['s'] * 1e3:g} mm, rail {d['rail']} "
                   f"{d['plane']}: {d['value'] * 1e6:+.3g} ± {d['sigma'] * 1e6:.2g} µm")
    return out


def _validity(s: FitSettings, report: dict, meas, cfg: dict) -> list[str]:
    """Each validity warning once (report.json's ``validity``; and a compensation table over
    positions the data do not cover)."""
    from ..inverse.validity import outside_measured

    lines = [f"{w['message']}; {w['action']}" for w in report.get("validity", [])]
    if s.export_compensation:
        half = cfg["machine"]["stroke_mm"] / 2e3
        lines += [str(w) for w in outside_measured(meas, [-half, half],
                                                   "the compensation table")]
    return list(dict.fromkeys(lines))


def _machine_x0(s: FitSettings, info: dict) -> float:
    """The export's x0: ``machine_x0_mm``, else the measurements' (the first file's)."""
    return s.machine_x0_mm if s.machine_x0_mm is not None else info.get("x0_mm", 0.0)


def _coordinates(s: FitSettings, info: dict) -> dict:
    """report.json's statement of the coordinates: every file's x0 and its source, and the
    compensation table's."""
    return {"files": [{"file": i["file"], "layout": i.get("layout"),
                       "encoding": i.get("encoding"), "x0_mm": i.get("x0_mm"),
                       "x0_source": i.get("x0_source"), "metadata": i.get("metadata", {})}
                      for i in info.get("files", [])],
            "x0_mm": info.get("x0_mm"), "machine_x0_mm": _machine_x0(s, info),
            "coordinates": "x = X - x0: X the file's position (machine coordinate), x the table "
                           "position (0 mid-stroke); the compensation table is written at "
                           "X = x + machine_x0_mm"}


def _compensation(s: FitSettings, cfg: dict, spec, measured_points, fit, x0_mm: float):
    """The fitted model's errors at ``at`` over the stroke in ``comp_format``
    (:func:`diffguide.studies.compensation.fitted_compensation`): ``({path: text},
    [warning per point where a rigid-body compensation would not hold])``."""
    import numpy as np

    from .machine import machine_builder
    from ..studies.compensation import fitted_compensation
    from .export import export_spec

    points = {k: (v[0] * 1e-3, v[1] * 1e-3) for k, v in cfg["points"].items()}
    points.update(measured_points)  # the point and the counts were checked before the fit
    half = cfg["machine"]["stroke_mm"] / 2
    files, warnings = fitted_compensation(
        spec, fit, np.linspace(-half, half, s.comp_points), s.at, export_spec(s, cfg),
        points=points, nx=s.nx, ny=s.ny, x0_mm=x0_mm,
        source=f"predicted by the elastic model fitted to {', '.join(s.measurements)}",
        tol_um=s.tol_um, tol_urad=s.tol_urad, z=s.at_z_mm * 1e-3,
        make_machine=machine_builder(cfg, s.nx, s.ny))
    base = Path(s.export_compensation)
    paths = {(base if not suffix else base.with_name(base.stem + suffix)): text
             for suffix, text in files.items()}
    return paths, [str(w) for w in warnings]
