"""The predict job: the six joint errors, with σ from the fit's posterior, at any points of
the table over table positions, every output of ``diffguide predict`` (:func:`predict_job`).

:class:`PredictSettings` holds every option (points and heights in mm, as the options);
:func:`predict_job` reads the fit's ``posterior.json``, checks the machine against the one
fitted, predicts at the points (or over a grid of the whole table top) and returns a
:class:`PredictResult` holding the prediction and the text of the CSV (and the grid's figure);
:meth:`PredictResult.write` writes them, each file atomically. Nothing heavy is imported
until the job runs.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path

from .outputs import Figure, renamed, write_files


@dataclasses.dataclass(frozen=True)
class PredictSettings:
    """Every option of ``diffguide predict``, with the command line's defaults: ``fit`` a
    ``diffguide fit --out`` folder; ``point`` ``NAME:X_MM,Y_MM`` texts and ``points`` a points
    CSV, or ``grid`` ``NXxNY`` over the whole table top (``grid_plot`` its figure);
    ``positions_mm`` ``START:STOP:N`` (mm) or ``positions_file`` a positions CSV (default: the
    measured range at 71 positions); ``z_mm`` the points' height above the table top (mm).
    Checked at construction (``ValueError`` naming the option); the checks that need the fit
    run in :func:`predict_job`, before any work."""

    fit: str
    point: tuple[str, ...] = ()
    points: str | None = None
    grid: str | None = None
    grid_plot: str | None = None
    positions_mm: str | None = None
    positions_file: str | None = None
    extrapolate: bool = False
    z_mm: float = 0.0
    accept_machine_change: bool = False
    out: str | None = None

    def __post_init__(self):
        for name in ("fit", "points", "grid_plot", "positions_file", "out"):
            v = getattr(self, name)
            object.__setattr__(self, name, None if v is None else str(v))
        object.__setattr__(self, "point", (self.point,) if isinstance(self.point, str)
                           else tuple(self.point))
        if not (math.isfinite(self.z_mm) and -500.0 <= self.z_mm <= 2000.0):
            raise ValueError(f"--z-mm must be in [-500, 2000] mm, got {self.z_mm:g}")

    @classmethod
    def fields(cls) -> tuple[str, ...]:
        """The settings' names (the options' destinations)."""
        return tuple(f.name for f in dataclasses.fields(cls))


@dataclasses.dataclass
class PredictResult:
    """What :func:`predict_job` computed: the prediction
    (:class:`~diffguide.inverse.predict.Prediction`, SI), the files (``{path: text or
    Figure}``: the CSV first, then ``grid_plot``), the warnings (the posterior's, a changed
    machine) and the note of what changed in the machine since the fit (``None``: nothing)."""

    settings: PredictSettings
    prediction: object
    files: dict
    warnings: list
    machine_change: str | None

    def write(self, out: str | Path | None = None) -> list[str]:
        """Write the CSV to ``out`` (default: the settings' ``out``) and the grid's figure,
        each atomically; returns the paths."""
        if out is None and self.settings.out is None:
            raise ValueError("no output file: give write() a path or PredictSettings(out=...)")
        return write_files(renamed(self.files, out))


def predict_job(settings: PredictSettings, *,
                warn: Callable[[str], None] | None = None) -> PredictResult:
    """Run ``diffguide predict``'s work for ``settings``: read the fit's posterior, check the
    machine, predict at the points or over the grid, and compute the CSV's text and the
    grid's figure. ``warn`` receives each warning as it arises (they are also in the result).
    ``ValueError`` for bad input, before any work."""
    from ..inverse.error_map import error_map
    from ..inverse.predict import check_size, predict
    from ..io.fit_posterior import read_fit_posterior
    from ..io.prediction_csv import prediction_csv_text

    s, warnings = settings, []

    def warned(line: str) -> None:
        warnings.append(line)
        if warn is not None:
            warn(line)

    post, meta = read_fit_posterior(s.fit)
    for line in meta["warnings"]:
        warned(line)
    points = _points(s)
    x = _positions(s, post)
    check_size(len(x), len(set(points) | set(meta["points_m"])), post.cov.shape[0],
               _positions_option(s))
    spec, make_machine, changed = _machine_spec(s, meta, warned)
    m = meta["machine"]
    kw = dict(measured_points=meta["points_m"], nx=m.get("nx"), ny=m.get("ny"),
              extrapolate=s.extrapolate, z=s.z_mm * 1e-3)
    if s.grid_plot and not s.grid:
        raise ValueError("--grid-plot needs --grid NXxNY")
    if s.grid:
        if make_machine is not None:
            raise ValueError("--grid: the table is imported (a reduced matrix): it knows only "
                             "its retained nodes; predict there with --point/--points")
        pred = error_map(post, spec, parse_grid(s.grid, len(x)), x, **kw)
    else:
        pred = predict(post, spec, points, x, make_machine=make_machine, **kw)
    src = f"from the fit in {Path(s.fit).resolve()}" + (
        f"; WARNING: {changed} (--accept-machine-change)" if changed else "")
    files: dict = {s.out: prediction_csv_text(pred, src, meta.get("x0_mm"))}
    if s.grid_plot:
        files[s.grid_plot] = _grid_figure(pred)
    return PredictResult(s, pred, files, warnings, changed)


def _points(s: PredictSettings) -> dict:
    """The points ``{name: (x, y)}`` (m) of ``point`` and ``points``."""
    from ..io.prediction_csv import parse_point, read_points_file

    pts: dict = {}
    for text in s.point:
        name, xy = parse_point(text)
        if name in pts:
            raise ValueError(f"--point {name!r} given twice")
        pts[name] = xy
    if s.points:
        for name, xy in read_points_file(s.points).items():
            if name in pts:
                raise ValueError(f"{s.points}: point {name!r} is also given by --point")
            pts[name] = xy
    if not pts and not s.grid:
        raise ValueError("give at least one point: --point NAME:X_MM,Y_MM or --points FILE.csv "
                         "(or --grid NXxNY)")
    if pts and s.grid:
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


def _positions(s: PredictSettings, post):
    """The table positions (m): ``positions_mm``, ``positions_file`` or the measured range."""
    import numpy as np

    from ..io.prediction_csv import read_positions_file
    from .positions import parse_positions

    if s.positions_mm and s.positions_file:
        raise ValueError("give --positions-mm or --positions, not both")
    if s.positions_file:
        return read_positions_file(s.positions_file)
    if s.positions_mm:
        try:
            return parse_positions(s.positions_mm)
        except ValueError as exc:
            raise ValueError(str(exc).replace("--positions", "--positions-mm")) from None
    return np.linspace(*post.position_range, 71)


def _positions_option(s: PredictSettings) -> str:
    """The option that gave the positions, with its value, for a message."""
    if s.positions_file:
        return f"--positions {s.positions_file}"
    return f"--positions-mm {s.positions_mm}" if s.positions_mm else "the measured range"


def _machine_spec(s: PredictSettings, meta: dict, warn):
    """The fitted machine's specification, its builder for ``predict`` (``None`` for the
    plate; :func:`diffguide.jobs.machine.machine_builder`) and a note of what changed in
    it since the fit (None: nothing): the fit's machine file or preset, refused where it
    changed unless ``accept_machine_change``."""
    from ..io.config import default_config, load_config, spec_from_config
    from ..io.fit_posterior import machine_changes
    from .machine import machine_builder

    m = meta["machine"]
    what = f"machine file {m['config']}" if m.get("config") else f"preset {m['preset']}"
    cfg = load_config(m["config"]) if m.get("config") else default_config()
    changes = machine_changes(meta, cfg)
    note = None
    if changes:
        note = f"the {what} changed since the fit: " + "; ".join(changes)
        if not s.accept_machine_change:
            raise ValueError(f"{note}. The fit's posterior belongs to the machine it was fitted "
                             "with: fit again, or give --accept-machine-change to predict "
                             "with the changed machine anyway")
        warn(f"{note} (predicting anyway: --accept-machine-change)")
    return spec_from_config(cfg), machine_builder(cfg, m.get("nx"), m.get("ny")), note


def _grid_figure(pred) -> Figure:
    """``grid_plot``: the errors and σ over the table top at the last position."""
    from ..plotting import figure_of
    from ..plotting.errors import plot_error_map

    err, sig = pred.user_units()
    return Figure(figure_of(plot_error_map(
        pred.points_xy, pred.grid_shape, err[-1], sig[-1],
        f"errors over the table top at x = {pred.positions[-1] * 1e3:g} mm (1σ below)")), 100)
