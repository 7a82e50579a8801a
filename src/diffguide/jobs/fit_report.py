"""``fit``'s report for a metrologist: the straightness, compensation and stamp sections of
``report.json`` (:func:`diffguide.jobs.fit_summary.metrologist_sections`), the figures of
``report.html`` (drawn by the figures' process), and the page itself
(:func:`diffguide.io.report_html.report_html`, from ``report.json``'s text: one set of
numbers)."""

import json
import shlex
import shutil
from pathlib import Path

import numpy as np

#: Staging subfolder of the report's figures (embedded in report.html, then removed).
FIGURES_DIR = "_report_figures"


def plan_command(args) -> str:
    """The planner's command for what the data do not determine (from the fit's layout)."""
    plan = (["--config", args.config] if args.config else ["--preset", args.preset]) + (
        ["--mesh", args.mesh] if getattr(args, "mesh", None) else [])
    plan += ["--start", str(Path(args.out) / "layout.csv")]
    return f"diffguide plan {shlex.join(plan)} --out PLAN_DIR"


def sections(args, report, meas, fit, s_m, cfg, info) -> dict:
    """report.json's ``straightness``, ``compensation``, ``stamp`` and ``plan_suggestion``
    (the planner's command where the data leave wavelengths undetermined, else None), for
    ``report`` (its ``identifiability`` section read)."""
    from ..io.report_text import undetermined_lines
    from .fit_summary import metrologist_sections, stamp_section

    export = (None if not args.export_compensation else
              {"file": str(args.export_compensation), "format": args.comp_format,
               "point": args.at})
    out = metrologist_sections(fit, meas, s_m, rail_y_mm=cfg["guideway"]["rail_y_mm"],
                               tolerance_um=args.tolerance_um, export=export)
    out["stamp"] = stamp_section(meas, {"preset": None if args.config else args.preset,
                                        "config": args.config,
                                        "measurements": args.measurements}, info)
    blind = undetermined_lines(report["identifiability"], fit.waviness)
    out["plan_suggestion"] = plan_command(args) if blind else None
    return out


def figure_jobs(report, meas, fit, s_m) -> list:
    """``[(file name, FigureJob)]``: the straightness, residual and measured-vs-fitted figures
    of report.html, from ``report``'s straightness rows and the fit."""
    from ..io.measurements import QUANTITIES
    from ..io.report_html import named
    from ..plotting.render import FigureJob
    from ..studies.straightness import deviation_bands

    dev, sig = deviation_bands(fit, s_m)
    rows = report["straightness"]["rails"]
    chan = meas.channel_index()
    residuals, curves = [], []
    for c, (_, q, _) in enumerate(meas.channels):
        sel = chan == c
        unit = "µm" if QUANTITIES[q] in ("EXX", "EYX", "EZX") else "µrad"
        label = named(meas.channel_label(c))
        x, y, s = meas.position[sel] * 1e3, meas.value[sel] * 1e6, meas.sigma[sel] * 1e6
        residuals.append((label, unit, x, fit.residual[sel] * 1e6, s))
        curves.append((label, unit, x, y, s, fit.fitted[sel] * 1e6, None))
    return [
        ("straightness.png", FigureJob("diffguide.plotting.report:straightness_figure",
                                       (s_m * 1e3, dev * 1e6, sig * 1e6, rows))),
        ("residuals.png", FigureJob("diffguide.plotting.report:residuals_figure", (residuals,))),
        ("curves.png", FigureJob("diffguide.plotting.report:measured_fitted_figure", (curves,))),
    ]


def submit_figures(figures, folder: Path, jobs) -> Path:
    """Send ``jobs`` to the figures' process, drawing into ``folder / FIGURES_DIR``."""
    sub = Path(folder) / FIGURES_DIR
    sub.mkdir(exist_ok=True)
    figures.submit(sub, jobs, dpi=90)
    return sub


def read_figures(folder: Path | None) -> dict[str, bytes]:
    """The report's figures drawn into ``folder`` (:func:`submit_figures`), ``{name: PNG
    bytes}``; the folder is removed (None: no figures)."""
    if folder is None:
        return {}
    pngs = {p.name: p.read_bytes() for p in Path(folder).glob("*.png")}
    shutil.rmtree(folder, ignore_errors=True)
    return pngs


def html_text(report_json: str, pngs: dict[str, bytes]) -> str:
    """report.html from report.json's text and the report's figures ``{name: PNG bytes}``."""
    from ..io.report_html import report_html

    return report_html(json.loads(report_json), pngs)


def check_tolerance(args) -> None:
    """``--tolerance-um``: a finite straightness tolerance in (0, 10000] µm."""
    t = args.tolerance_um
    if t is not None and not (np.isfinite(t) and 0.0 < t <= 1e4):
        raise ValueError(f"--tolerance-um must be a straightness tolerance in (0, 10000] µm, "
                         f"got {t}")


def plot_jobs(meas, fits, profiles, s_m, truth) -> dict:
    """The folder's two figures, profiles.png and curves.png, as jobs for the figures' process
    (drawn on bare ``Figure`` objects with fixed margins: :mod:`diffguide.plotting.fit`)."""
    from ..io.measurements import QUANTITIES
    from ..plotting.render import FigureJob

    labels = {"": "elastic", "_rigid": "rigid table"}
    fig1 = FigureJob("diffguide.plotting.fit:profiles_figure",
                     (s_m, {labels[k]: v for k, v in profiles.items()}), {"truth": truth})
    chan = meas.channel_index()
    channels = []
    for c, (_, q, _) in enumerate(meas.channels):
        sel = chan == c
        unit = "µm" if QUANTITIES[q] in ("EXX", "EYX", "EZX") else "µm/m"
        rigid = fits["_rigid"].fitted[sel] * 1e6 if "_rigid" in fits else None
        channels.append((meas.channel_label(c), unit,
                         meas.position[sel] * 1e3, meas.value[sel] * 1e6,
                         meas.sigma[sel] * 1e6, fits[""].fitted[sel] * 1e6, rigid))
    return {"profiles.png": fig1,
            "curves.png": FigureJob("diffguide.plotting.fit:curves_figure", (channels,))}
