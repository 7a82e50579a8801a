"""``diffguide fit``: rail straightness profiles from measured pitch, yaw, roll."""

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .._core.atomic import usual_mode
from ._common import check_tolerances, say

PRESETS = ("majda2012",)
_S_STEP_MM = 2.0
#: Exit code when the results are written but the elastic fit did not converge.
EXIT_NOT_CONVERGED = 3


def add_parser(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "fit",
        help="identify rail straightness profiles (µm) from measured joint errors (CSV)",
        description="Fit the vertical and horizontal straightness profiles of both rails - and "
        "the table's equivalent thickness and the preload, which nobody knows - to measured "
        "joint kinematic errors (levels, interferometers) through the elastic machine model, by "
        "regularised Levenberg-Marquardt (marginal-likelihood weight), with posterior ±σ bands "
        "that include the structure's uncertainty and an identifiability report (with --rigid, "
        "the classical rigid-table inversion side by side). Input CSV: position_mm,point,x_mm,"
        "y_mm,quantity,"
        "value,unit[,sigma][,run][,direction][,instrument][,z_mm] (positions and points in mm; "
        "values in µm, mm, nm, in, µm/m, mm/m, µrad, mrad, arcsec, arcmin or deg). Output "
        "folder (written atomically): rails.csv (and rails_rigid.csv with --rigid) "
        "(rail,s_mm,vertical_um,vertical_sigma_um,horizontal_um,horizontal_sigma_um), fit.csv "
        "(every input row with fitted and residual, in its unit), layout.csv (the measured "
        "layout, for 'diffguide plan --start'), report.json, profiles.png, "
        "curves.png. Exit codes: 0 converged; 3 results written but the fit did not converge "
        "(flagged in report.json); 2 bad input or options (nothing written).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--preset", default="majda2012", choices=PRESETS,
                   help="machine model (majda2012: 1000 x 500 mm table, rails 340 mm apart)")
    p.add_argument("--measurements", required=True, metavar="FILE.csv",
                   help="measurement CSV (see above)")
    p.add_argument("--measurements-format", dest="layout", choices=("auto", "long", "wide"),
                   default="auto",
                   help="layout of --measurements: long (one reading per row), wide (targets x "
                   "runs, ISO 230-2 style) or auto (detected; see 'diffguide import')")
    p.add_argument("--x0-mm", type=float, default=None,
                   help="machine coordinate (mm) of the table position x = 0, subtracted from "
                   "the file's positions and from the compensation table's; default: 0 for the "
                   "long layout, the middle of the measured targets for the wide one")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (replaced)")
    p.add_argument("--knot-spacing-mm", type=float, default=None,
                   help="B-spline knot spacing of the profiles (mm); default: the carriage's "
                   "loaded length (48 mm for majda2012)")
    p.add_argument("--lambda", dest="lam", type=float, default=None,
                   help="fixed smoothness weight instead of the chosen one (whitened units, as "
                   "report.json's 'lambda')")
    p.add_argument("--max-steps", type=int, default=60,
                   help="Levenberg-Marquardt step limit per pass (default 60); when it is reached "
                   "the best estimate so far is written, flagged as not converged (exit 3)")
    p.add_argument("--criterion", choices=("ml", "gcv"), default=None,
                   help="how the smoothness weight is chosen: marginal likelihood (default) or "
                   "generalised cross-validation; default: the config's [fit] criterion, else ml")
    p.add_argument("--structure", choices=("estimate", "fixed"), default=None,
                   help="estimate the table's equivalent thickness and the preload with the rails "
                   "(default), or hold them at the machine's values; default: the config's "
                   "[fit] structure, else estimate")
    p.add_argument("--thickness-prior-mm", metavar="VALUE,LO,HI", default=None,
                   help="prior of the equivalent plate thickness (mm): a value and a plausible "
                   "range (read as ±2σ of a log-normal prior); default: the config's [fit] "
                   "thickness_prior_mm, else the machine's thickness and [0.5, 2] times it")
    p.add_argument("--preload-prior", metavar="VALUE,LO,HI", default=None,
                   help="prior of the preload (fraction of C), as for the thickness; default: the "
                   "config's [fit] preload_prior, else the machine's preload and [0.25, 2] "
                   "times it")
    p.add_argument("--rail-waviness-um", type=float, default=None, metavar="RMS",
                   help="RMS (µm) of the rails' short-wave content, shorter than about two knot "
                   "spacings, which the carriages average out and the data cannot show (state "
                   "it from the rails' grade): added in quadrature to every profile σ; default: "
                   "the config's [fit] rail_waviness_um, else 0 (the bands cover only what the "
                   "knots resolve)")
    p.add_argument("--rigid", dest="rigid", action="store_const", const=True, default=None,
                   help="also run the classical rigid-table inversion (rails_rigid.csv, its "
                   "columns in fit.csv and report.json, a dashed curve in the plots); it costs "
                   "a second compilation, 3-6 s; default: the config's [fit] rigid, else off")
    p.add_argument("--no-rigid", dest="rigid", action="store_const", const=False,
                   help="no rigid-table inversion (the default; overrides [fit] rigid = true)")
    p.add_argument("--no-plots", action="store_true", help="do not write the PNG figures")
    p.add_argument("--truth", metavar="FILE.csv", default=None,
                   help="known profiles (rail,s_mm,vertical_um,horizontal_um) to score the "
                   "fits against, e.g. data/majda2012_truth.csv")
    p.add_argument("--config", metavar="MACHINE.toml",
                   help="machine configuration file (TOML; see 'diffguide config'); overrides "
                   "--preset")
    p.add_argument("--export-compensation", metavar="FILE",
                   help="write a compensation table predicted by the fitted model for the point "
                   "--at over the stroke, in machine coordinates (X = x + --x0-mm), with σ (a "
                   "column, or FILE's companion .sigma.csv); see --format")
    p.add_argument("--format", dest="comp_format", default="csv",
                   choices=("csv", "isg", "siemens-cec", "heidenhain", "fanuc"),
                   help="format of --export-compensation: csv (errors and σ, µm/µrad), isg "
                   "(TwinCAT/ISG CSV: X EXX ... ECX, mm and rad, errors), siemens-cec (840D "
                   "$AN_CEC tables for EYX/EZX, mm, -error), heidenhain (.COM table, ISO 230-1 "
                   "columns, mm and degrees, -error), fanuc (incremental pitch/straightness list "
                   "in detection units, -error); README 'Compensation exports'")
    p.add_argument("--comp-points", type=int, default=71,
                   help="equidistant positions of the compensation table over the stroke "
                   "(default 71)")
    p.add_argument("--at", default="P5",
                   help="point of the compensation table: a measured point or a machine "
                   "control point (P1..P5 for majda2012)")
    p.add_argument("--tol-um", type=float, default=2.0,
                   help="warn where another point's EXX/EYX/EZX depart from the rigid-body "
                   "prediction from --at by more than this (µm)")
    p.add_argument("--tol-urad", type=float, default=5.0,
                   help="warn where another point's EAX/EBX/ECX depart from --at's by more (µrad)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=run, figure_worker=True)
    return p


def _check_inputs(meas, args, cfg):
    """Points, positions and options checked against the machine actually used."""
    name = args.config or args.preset
    half_l, half_w = cfg["table"]["length_mm"] / 2e3, cfg["table"]["width_mm"] / 2e3
    for pname, (x, y) in zip(meas.point_names, meas.points_xy):
        if abs(x) > half_l or abs(y) > half_w:
            raise ValueError(
                f"{meas.source}: point {pname!r} at ({x * 1e3:g}, {y * 1e3:g}) mm is off the "
                f"{name} table (|x| <= {half_l * 1e3:g}, |y| <= {half_w * 1e3:g} mm)")
    stroke = cfg["machine"]["stroke_mm"] * 1e-3
    bad = np.abs(meas.position) > stroke / 2 + 1e-9
    if bad.any():
        x = meas.position[bad][0]
        raise ValueError(f"{meas.source}: position {x * 1e3:g} mm is outside the {name} "
                         f"stroke (±{stroke / 2 * 1e3:g} mm)")
    if len(np.unique(np.round(meas.position, 9))) < 4:
        raise ValueError(f"{meas.source}: at least 4 distinct positions are needed for a fit")
    if args.knot_spacing_mm is not None and not (1.0 <= args.knot_spacing_mm <= 1000.0):
        raise ValueError(f"--knot-spacing-mm must be in [1, 1000] mm, got {args.knot_spacing_mm}")
    if not 0 <= args.max_steps <= 10000:
        raise ValueError(f"--max-steps must be an integer in [0, 10000], got {args.max_steps}")
    if args.lam is not None and not (np.isfinite(args.lam) and args.lam > 0):
        raise ValueError(f"--lambda must be a finite number > 0, got {args.lam}")
    w = args.rail_waviness_um
    if w is not None and not (np.isfinite(w) and 0.0 <= w <= 100.0):
        raise ValueError(f"--rail-waviness-um must be an RMS in [0, 100] µm, got {w}")
    for name in ("nx", "ny"):
        v = getattr(args, name)
        if v is not None and not 1 <= v <= 200:
            raise ValueError(f"--{name} must be an integer in [1, 200], got {v}")
    if args.export_compensation:  # checked here: a refusal after the fit would follow output
        points = list(dict.fromkeys([*cfg["points"], *meas.point_names]))
        if args.at not in points:
            raise ValueError(f"--at must be one of the points {', '.join(points)}, "
                             f"got {args.at!r}")
        if not 2 <= args.comp_points <= 10000:
            raise ValueError(f"--comp-points must be in [2, 10000], got {args.comp_points}")
        check_tolerances(args)


def read_truth(path, s_m):
    """Truth profiles ``(2, 2, len(s))`` (m) at ``s`` (m) from a rails CSV
    (:func:`diffguide.io.rails_csv.rails_at`: the reader of ``simulate --rails``)."""
    from ..io.rails_csv import rails_at

    return rails_at(path, s_m)


def _rails_csv(s_m, val, sig) -> str:
    lines = ["rail,s_mm,vertical_um,vertical_sigma_um,horizontal_um,horizontal_sigma_um"]
    for r in range(2):
        for i, s in enumerate(s_m):
            lines.append(f"{r + 1},{s * 1e3:.3f},{val[r, 0, i] * 1e6:.5f},"
                         f"{sig[r, 0, i] * 1e6:.5f},{val[r, 1, i] * 1e6:.5f},"
                         f"{sig[r, 1, i] * 1e6:.5f}")
    return "\n".join(lines) + "\n"


def _fit_csv(meas, fits) -> str:
    from ..io.measurements import ANGULAR_UNITS, LINEAR_UNITS, format_csv

    cols = ["line", "position_mm", "point", "x_mm", "y_mm", "quantity", "value", "unit", "run",
            "direction", "instrument", "status"]
    for label in fits:
        cols += [f"fitted{label}", f"residual{label}"]
    outlier_rows = set(int(i) for i in fits[""].outliers)
    rows = []
    for r, k in zip(meas.readings, meas.row_of_reading):
        f = {**LINEAR_UNITS, **ANGULAR_UNITS}[r.unit]
        status = ("outlier reading (not used)" if k < 0 else
                  "outlier value (zero weight)" if int(k) in outlier_rows else "used")
        row = {"line": r.line, "position_mm": float(r.position * 1e3), "point": r.point,
               "x_mm": float(r.xy[0] * 1e3), "y_mm": float(r.xy[1] * 1e3),
               "quantity": r.quantity, "value": float(r.value / f), "unit": r.unit,
               "run": r.run, "direction": r.direction, "instrument": r.instrument,
               "status": status}
        for label, fit in fits.items():
            row[f"fitted{label}"] = "" if k < 0 else float(fit.fitted[k] / f)
            row[f"residual{label}"] = "" if k < 0 else float((r.value - fit.fitted[k]) / f)
        rows.append(row)
    return format_csv(rows, tuple(cols))


def _summary(fit, meas, seconds) -> dict:
    from ..io.measurements import QUANTITIES

    chan = meas.channel_index()
    channels = []
    for c in range(len(meas.channels)):
        sel = chan == c
        p, q, inst = meas.channels[c]
        used = sel & ~np.isin(np.arange(meas.n), fit.outliers)
        z = fit.residual[used] / meas.sigma[used]
        channels.append({
            "channel": meas.channel_label(c), "point": meas.point_names[p],
            "quantity": QUANTITIES[q], "instrument": inst,
            "rms_residual_user": float(np.sqrt(np.mean(fit.residual[sel] ** 2)) * 1e6),
            "chi2": float(z @ z), "n": int(sel.sum()),
            "zero_offset_user": (None if not np.isfinite(fit.offsets[c])
                                 else float(fit.offsets[c] * 1e6)),
        })
    structure = {}
    for name, v in fit.structure.items():
        unit, f = ("mm", 1e3) if name == "thickness" else ("fraction of C", 1.0)
        structure[name] = {
            "unit": unit, "value": v["value"] * f, "sigma": v["sigma"] * f,
            "prior_value": v["prior_value"] * f,
            "prior_range": [x * f for x in v["prior_range"]],
            "determined_by_data": v["determined"], "at_interpolation_bound": v["at_bound"],
            "note": ("determined by the data" if v["determined"] else
                     "not determined by the data: the value is the prior's and its "
                     "uncertainty widens the rails' bands"),
        }
    return {
        "model": "rigid table" if fit.rigid else "elastic table",
        "method": ("classical linear inversion (rigid-body model linearised at straight "
                   "rails, same gauge, penalty and weight choice)" if fit.rigid else
                   "Levenberg-Marquardt through the elastic model"),
        "converged": bool(fit.converged), "status": fit.message, "lm_steps": int(fit.steps),
        "lambda": fit.lam, "lambda_criterion": fit.weight.criterion,
        "lambda_score": None if not np.isfinite(fit.weight.score) else fit.weight.score,
        "lambda_at_search_bound": bool(fit.weight.at_bound),
        "chi2": fit.chi2, "dof": fit.dof,
        "chi2_per_dof": None if not np.isfinite(fit.chi2_dof) else fit.chi2_dof,
        "sigma_scale": fit.sigma_scale, "effective_parameters": fit.edf,
        "resolution": {
            "knot_spacing_mm": fit.basis.spacing * 1e3,
            "rail_waviness_um": fit.waviness * 1e6,
            "note": (f"content shorter than about {2 * fit.basis.spacing * 1e3:.0f} mm (two knot "
                     "spacings) is not resolved; "
                     + (f"a stated waviness of {fit.waviness * 1e6:.3g} µm RMS is in every σ"
                        if fit.waviness > 0 else
                        "the bands do not include it (state --rail-waviness-um)")),
        },
        "structure": structure,
        "outlier_rows": [{"position_mm": float(meas.position[i] * 1e3),
                          "channel": meas.channel_label(int(chan[i])),
                          "residual_user": float(fit.residual[i] * 1e6)}
                         for i in fit.outliers],
        "lead_error_term": bool(len(fit.lead)),
        "alignment_slopes_um_per_m": {meas.channel_label(c): float(a * 1e6) for c, a in
                                      zip(fit.alignment_channels, fit.alignment)},
        "knot_spacing_mm": fit.basis.spacing * 1e3, "coefficients_per_profile": fit.basis.n_coeffs,
        "s_range_mm": [fit.basis.start * 1e3, fit.basis.end * 1e3],
        "gauge": list(fit.gauge), "channels": channels, "fit_seconds": seconds,
        "units": "user units: µm for EXX/EYX/EZX, µm/m (µrad) for EAX/EBX/ECX",
    }


def _parse_prior(text, flag, scale):
    try:
        v = [float(t) for t in text.split(",")]
        if len(v) != 3:
            raise ValueError
    except ValueError:
        raise ValueError(f"{flag} must be VALUE,LO,HI (three numbers), got {text!r}") from None
    if not (0 < v[1] <= v[0] <= v[2]) or not all(np.isfinite(v)):
        raise ValueError(f"{flag} needs 0 < LO <= VALUE <= HI, got {text!r}")
    return [x * scale for x in v]


def fit_settings(args, cfg) -> tuple[str, str]:
    """``(structure, criterion)``: the flags, else the configuration's ``[fit]`` section."""
    fit = cfg.get("fit", {})
    structure = args.structure or fit.get("structure") or "estimate"
    criterion = args.criterion or fit.get("criterion") or "ml"
    return structure, criterion


def rail_waviness(args, cfg) -> float:
    """The stated short-wave rail waviness (m RMS): ``--rail-waviness-um``, else the
    configuration's ``[fit] rail_waviness_um``, else 0."""
    um = args.rail_waviness_um
    if um is None:
        um = cfg.get("fit", {}).get("rail_waviness_um", 0.0)
    return float(um) * 1e-6


def rigid_wanted(args, cfg) -> bool:
    """Whether to run the rigid-table inversion too: ``--rigid`` / ``--no-rigid``, else the
    configuration's ``[fit] rigid``, else no (it costs a compilation of its own)."""
    if args.rigid is not None:
        return bool(args.rigid)
    return bool(cfg.get("fit", {}).get("rigid", False))


def structure_priors(args, cfg):
    """The structural priors: the flags, else the configuration's ``[fit]`` section, else the
    machine's own values with the ranges [1/2, 2]× (thickness) and [1/4, 2]× (preload)."""
    from ..inverse import Prior, StructurePriors

    if fit_settings(args, cfg)[0] == "fixed":
        return StructurePriors()
    fit = cfg.get("fit", {})
    t0 = cfg["table"]["thickness_mm"] * 1e-3
    p0 = cfg["carriage"]["preload_fraction"]
    if args.thickness_prior_mm:
        t = _parse_prior(args.thickness_prior_mm, "--thickness-prior-mm", 1e-3)
    elif fit.get("thickness_prior_mm") is not None:
        t = [v * 1e-3 for v in fit["thickness_prior_mm"]]
    else:
        t = (t0, 0.5 * t0, 2.0 * t0)
    if args.preload_prior:
        p = _parse_prior(args.preload_prior, "--preload-prior", 1.0)
    elif fit.get("preload_prior") is not None:
        p = list(fit["preload_prior"])
    else:
        p = (p0, 0.25 * p0, 2.0 * p0)
    return StructurePriors(Prior(*t), Prior(*p))


def _check_out(out: Path) -> Path:
    """``out`` resolved; refuse to replace a folder that is not an earlier fit output."""
    out = out.resolve()
    if out.exists() and (not out.is_dir() or (any(out.iterdir())
                                              and not (out / "report.json").exists())):
        raise ValueError(f"--out {out}: exists and is not an earlier fit output folder; "
                         "refusing to replace it")
    return out


class _Staging:
    """The output folder, written into a temporary folder next to ``out`` and renamed into
    place by :meth:`commit` (an earlier output folder is replaced only then); on an exception
    inside the ``with`` block the temporary folder is removed."""

    def __init__(self, out: Path):
        self.out = _check_out(out)
        self.out.parent.mkdir(parents=True, exist_ok=True)
        self.tmp = Path(tempfile.mkdtemp(prefix=f".{self.out.name}.", suffix=".tmp",
                                         dir=self.out.parent))

    def __enter__(self) -> "_Staging":
        return self

    def __exit__(self, kind, *exc) -> None:
        if kind is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)

    def write(self, files: dict[str, object]) -> None:
        """``files``: {name: text or matplotlib figure}."""
        for name, content in files.items():
            if isinstance(content, str):
                (self.tmp / name).write_text(content, encoding="utf-8")
            else:
                content.savefig(self.tmp / name, dpi=110)

    def commit(self) -> None:
        old = None
        if self.out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{self.out.name}.", suffix=".old",
                                        dir=self.out.parent))
            os.replace(self.out, old / self.out.name)
        os.chmod(self.tmp, usual_mode(0o777))  # mkdtemp makes 0700
        os.replace(self.tmp, self.out)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


def _write_dir(out: Path, files: dict[str, object]) -> None:
    """Write ``files`` ({name: text or figure}) into ``out`` at once (:class:`_Staging`)."""
    with _Staging(out) as staged:
        staged.write(files)
        staged.commit()


def run(args) -> int:
    from ..inverse import MachineFamily, fit_rails
    from ..io.config import spec_from_config
    from ..io.importers import read_any
    from ..machine.build import build_machine
    from ..plotting.render import FigureWorker
    from ._common import machine_config

    t_start = time.perf_counter()
    _check_out(Path(args.out))
    cfg = machine_config(args)
    spec = spec_from_config(cfg)
    notes: list[str] = []
    info: dict = {}
    meas = read_any(args.measurements, args.layout, args.x0_mm, notes, info)
    for n in notes:
        say(args, f"note: {n}")
    _check_inputs(meas, args, cfg)
    priors = structure_priors(args, cfg)
    lines = ", ".join(map(str, meas.rejected[:10])) + (" ..." if len(meas.rejected) > 10 else "")
    say(args, f"{args.measurements}: {len(meas.readings)} readings -> {meas.n} merged rows in "
               f"{len(meas.channels)} channels at {len(np.unique(meas.position))} positions"
               + (f"; {len(meas.rejected)} outlying readings set aside (lines {lines})"
                  if meas.rejected else ""))
    points = {n: tuple(map(float, xy)) for n, xy in zip(meas.point_names, meas.points_xy)}

    def make_machine(**kw):
        return build_machine(spec, nx=args.nx, ny=args.ny, points=points, **kw)

    family = MachineFamily.build(make_machine, priors, progress=lambda t: say(args, t))
    machine = family.base
    spacing = None if args.knot_spacing_mm is None else args.knot_spacing_mm * 1e-3
    fits, seconds = {}, {}
    rigid = [("_rigid", machine.with_rigid_table())] if rigid_wanted(args, cfg) else []
    models = [("", family)] + rigid
    for label, m in models:
        t = time.perf_counter()
        say(args, f"{'rigid-table' if label else 'elastic'} fit: compiling and solving ...")
        fits[label] = fit_rails(m, meas, knot_spacing=spacing, lam=args.lam,
                                criterion=fit_settings(args, cfg)[1], max_steps=args.max_steps,
                                waviness=rail_waviness(args, cfg),
                                method="linear" if label else "lm")
        seconds[label] = time.perf_counter() - t
        f = fits[label]
        say(args, f"{'rigid-table' if label else 'elastic'} fit: chi2/dof = {f.chi2_dof:.3f} "
                   f"(dof {f.dof:.1f}), lambda {f.lam:.3g} ({f.weight.criterion}), "
                   f"{f.edf:.1f} effective parameters, {f.steps} LM steps, {f.message}, "
                   f"{seconds[label]:.1f} s")
        for name, v in f.structure.items():
            val, sd = ((v["value"] * 1e3, v["sigma"] * 1e3) if name == "thickness"
                       else (v["value"] * 100, v["sigma"] * 100))
            unit = "mm" if name == "thickness" else "% of C"
            say(args, f"  {name}: {val:.3g} ± {sd:.2g} {unit}"
                       + ("" if v["determined"] else " (not determined by the data: prior)"))
        for c, a in zip(f.alignment_channels, f.alignment):
            say(args, f"  alignment slope of {meas.channel_label(c)}: {a * 1e6:.3g} µm/m "
                       "(fitted, as ISO 230-1 removes it)")
    elastic = fits[""]
    basis = elastic.basis
    s0 = np.ceil(basis.start * 1e3 / _S_STEP_MM - 1e-9) * _S_STEP_MM
    s_m = np.arange(s0, basis.end * 1e3 + 1e-9, _S_STEP_MM) * 1e-3
    s_m = np.unique(np.clip(np.concatenate([[basis.start], s_m, [basis.end]]), basis.start,
                            basis.end))
    profiles = {label: f.profiles(s_m) for label, f in fits.items()}
    truth = None
    if args.truth:
        raw = read_truth(args.truth, s_m)
        flat = basis.gauge_fix(s_m, raw.reshape(4, -1), elastic.fix_slope)
        truth = flat.reshape(2, 2, -1)
    with _Staging(Path(args.out)) as staged:
        figures = getattr(args, "figures", None) or FigureWorker()
        plots = {} if args.no_plots else _figures(meas, fits, profiles, s_m, truth)
        try:
            if plots:  # drawn by the figures' process while the rest is computed
                figures.submit(staged.tmp, list(plots.items()), dpi=110)
            report = _report(args, meas, fits, profiles, truth, seconds, machine)
            files = {"rails.csv": _rails_csv(s_m, *profiles[""])}
            if "_rigid" in fits:
                files["rails_rigid.csv"] = _rails_csv(s_m, *profiles["_rigid"])
            files["fit.csv"] = _fit_csv(meas, fits)
            files["layout.csv"] = layout_csv(meas)
            report["total_seconds"] = time.perf_counter() - t_start
            files["report.json"] = json.dumps(_jsonable(report), indent=1, allow_nan=False) + "\n"
            staged.write(files)
            figures.wait()
        except BaseException:
            figures.close(kill=True)  # stop drawing into the staging folder before it goes
            raise
        staged.commit()
    files.update(plots)
    if args.export_compensation:
        _export_compensation(args, cfg, points, elastic, family, info.get("x0_mm", 0.0))
    if args.truth:
        e = report["truth"]["rms_error_um"]
        say(args, "profile rms error vs truth: elastic {:.3f} µm".format(e["elastic"]["all"])
             + (", rigid table {:.3f} µm".format(e["rigid_table"]["all"]) if "_rigid" in fits
                else ""))
    blind = undetermined_lines(report["identifiability"], elastic.waviness)
    for line in blind:
        say(args, line)
    if blind:
        import shlex

        plan = (["--config", args.config] if args.config else ["--preset", args.preset]) + (
            ["--mesh", args.mesh] if getattr(args, "mesh", None) else [])
        plan += ["--start", str(Path(args.out) / "layout.csv")]
        say(args, "what more instruments would determine there: diffguide plan "
                  f"{shlex.join(plan)} --out PLAN_DIR")
    say(args, f"wrote {args.out}/ ({', '.join(files)}) in {time.perf_counter() - t_start:.1f} s")
    if not elastic.converged:
        print(f"diffguide fit: warning: the fit did not converge ({elastic.message}); the results "
              f"in {args.out}/ are the best estimate so far and are flagged in report.json",
              file=sys.stderr)
    sys.stdout.flush()
    return 0 if elastic.converged else EXIT_NOT_CONVERGED


def layout_csv(meas) -> str:
    """The measured layout in ``diffguide plan``'s plan format (``--start``/``--compare``):
    ``instrument,point,x_mm,y_mm,reads`` — one row per point and instrument kind (``level``,
    ``interferometer`` for angular optics, ``straightness`` for straightness optics; what the
    planner does not model — positioning, an interferometer reading roll — is left out),
    ``reads`` the quantities read there, ``+``-joined."""
    from ..inverse.data import QUANTITIES
    from ..inverse.plan import KINDS
    from ..io.measurements import format_csv

    reads: dict[tuple[int, str], list[str]] = {}
    for p, q, inst in meas.channels:
        quantity = QUANTITIES[q]
        # a level is a level; an interferometer's optics are the planner's angular
        # interferometer or its straightness optics, by what they read
        kinds = ("level",) if inst == "level" else ("interferometer", "straightness")
        kind = next((k for k in kinds if quantity in KINDS[k]), None)
        if kind is not None and quantity not in reads.setdefault((p, kind), []):
            reads[(p, kind)].append(quantity)
    rows = [{"instrument": kind, "point": meas.point_names[p],
             "x_mm": float(meas.points_xy[p][0] * 1e3), "y_mm": float(meas.points_xy[p][1] * 1e3),
             "reads": "+".join(qs)} for (p, kind), qs in sorted(reads.items())]
    return format_csv(rows, ("instrument", "point", "x_mm", "y_mm", "reads"))


def undetermined_lines(ident: dict, waviness: float) -> list[str]:
    """What the data do not determine, for the console: per combination of the two rails, the
    wavelength bands (mm) whose transfer is below the report's threshold — there the profiles
    are the prior's guess and their σ the prior's — and, when no waviness (m RMS) is stated,
    that content shorter than the shortest analysed wavelength is outside the σ bands."""
    bands = []
    for c in ident["wavelengths"]:
        if c["undetermined_wavelengths_mm"]:
            spans = ", ".join(f"{lo:.0f}–{hi:.0f}" for lo, hi in c["undetermined_wavelengths_mm"])
            bands.append(f"{c['combination'].split(' (')[0]} {spans}")
    lines = []
    if bands:
        lines.append("not determined by the data (there the σ bands are the prior's), "
                     "wavelengths in mm: " + "; ".join(bands))
    if waviness == 0.0:
        shortest = min((r["wavelength_mm"] for c in ident["wavelengths"] for r in c["transfer"]),
                       default=None)
        if shortest is not None:
            lines.append(f"rail content shorter than {shortest:.0f} mm (two knot spacings: the "
                         "profiles cannot hold it and the carriages average it out) is not in the "
                         "σ bands: state its RMS with --rail-waviness-um")
    return lines


def _report(args, meas, fits, profiles, truth, seconds, machine) -> dict:
    """report.json's content (without ``total_seconds``)."""
    from ..inverse import identifiability
    from ..studies.iso230_2 import channel_figures

    elastic = fits[""]
    report = {
        "command": "diffguide fit", "preset": None if args.config else args.preset,
        "config": args.config,
        "status": {"converged": bool(elastic.converged), "message": elastic.message,
                   "exit_code": 0 if elastic.converged else EXIT_NOT_CONVERGED},
        "measurements": {
            "file": str(args.measurements), "readings": len(meas.readings),
            "merged_rows": meas.n,
            "points": {n: [float(x * 1e3), float(y * 1e3)] for n, (x, y) in
                       zip(meas.point_names, meas.points_xy)},
            "sigma_sources": sorted(set(meas.sigma_source)),
            "rejected_reading_lines": list(meas.rejected),
        },
        "iso230_2": channel_figures(meas),  # per channel where the runs allow
        "elastic": _summary(elastic, meas, seconds[""]),
        "identifiability": identifiability(elastic, machine),
    }
    if "_rigid" in fits:
        report["rigid_table"] = _summary(fits["_rigid"], meas, seconds["_rigid"])
        dv = profiles[""][0] - profiles["_rigid"][0]
        report["elastic_vs_rigid_profile_rms_difference_um"] = {
            f"rail {r + 1} {pl}": float(np.sqrt(np.mean(dv[r, p] ** 2)) * 1e6)
            for r in range(2) for p, pl in enumerate(("vertical", "horizontal"))}
    if args.truth:
        report["truth"] = {"file": str(args.truth), "rms_error_um": {}, "coverage_2sigma": {}}
        for label, (val, sig) in profiles.items():
            name = "rigid_table" if label else "elastic"
            err = val - truth
            report["truth"]["rms_error_um"][name] = {
                f"rail {r + 1} {pl}": float(np.sqrt(np.mean(err[r, p] ** 2)) * 1e6)
                for r in range(2) for p, pl in enumerate(("vertical", "horizontal"))}
            report["truth"]["rms_error_um"][name]["all"] = float(np.sqrt(np.mean(err**2)) * 1e6)
            report["truth"]["coverage_2sigma"][name] = float(np.mean(np.abs(err) <= 2 * sig))
        report["truth"]["rms_truth_um"] = float(np.sqrt(np.mean(truth**2)) * 1e6)
    return report


def _jsonable(obj):
    """Plain JSON types; non-finite numbers become null (never NaN in the file)."""
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    return obj


def _figures(meas, fits, profiles, s_m, truth):
    """The two figures, as jobs for :func:`_write_dir` (drawn on bare ``Figure`` objects with
    fixed margins: :mod:`diffguide.plotting.fit`)."""
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


def _error_sigma(machine, fit, x_m, j):
    """σ of the joint errors at point ``j`` (m, rad), ``(n_pos, 6)``: the rails' posterior
    covariance pushed through the model's Jacobian (one forward-mode pass over the spline
    coefficients; the structure's own uncertainty enters only through the rails' covariance)."""
    import jax
    import jax.numpy as jnp

    from ..guideway.rails import SplineRail
    from ..machine.kinematics import joint_errors

    n = fit.basis.n_coeffs
    start, spacing = fit.basis.start, fit.basis.spacing

    def errors(c):
        c = c.reshape(2, 2, n)
        rails = tuple(SplineRail(start, spacing, c[r, 0], c[r, 1]) for r in range(2))
        return joint_errors(machine, rails, x_m).errors[:, j, :]

    J = np.asarray(jax.jacfwd(errors)(jnp.asarray(np.asarray(fit.coeffs).reshape(-1))))
    return np.sqrt(np.maximum(np.einsum("pek,kl,pel->pe", J, np.asarray(fit.cov), J), 0.0))


def _export_compensation(args, cfg, measured_points, fit, family, x0_mm=0.0) -> None:
    """The fitted model's errors at ``--at`` over the stroke, as a compensation table in
    ``--format`` (machine coordinates ``X = x + x0``; σ from the posterior), with a warning
    for each point where a rigid-body compensation from ``--at`` would not hold."""
    from ..io.atomic import atomic_write_text
    from ..io.config import spec_from_config
    from ..machine.build import build_machine
    from ..machine.kinematics import joint_errors
    from ..studies.compensation import location_warnings
    from ..studies.exports import export_compensation

    points = {k: (v[0] * 1e-3, v[1] * 1e-3) for k, v in cfg["points"].items()}
    points.update(measured_points)  # --at and the counts were checked before the fit
    kw = {}  # the fitted structure
    if "thickness" in fit.structure:
        kw["thickness"] = fit.structure["thickness"]["value"]
    if "preload" in fit.structure:
        kw["preload_fraction"] = fit.structure["preload"]["value"]
    machine = build_machine(spec_from_config(cfg), nx=args.nx, ny=args.ny, points=points, **kw)
    half = cfg["machine"]["stroke_mm"] / 2
    x_mm = np.linspace(-half, half, args.comp_points)
    je = joint_errors(machine, fit.rails(), x_mm * 1e-3)
    if not bool(np.all(np.asarray(je.converged))):
        raise ValueError("the equilibrium of the fitted model did not converge over the stroke; "
                         "no compensation table written")
    j = list(je.point_names).index(args.at)
    errs = je.user_units()
    sigma = _error_sigma(machine, fit, x_mm * 1e-3, j)
    files = export_compensation(
        args.comp_format, x_mm, np.asarray(je.errors)[:, j, :], sigma, x0_mm=x0_mm,
        point=args.at, source=f"predicted by the elastic model fitted to {args.measurements}")
    base = Path(args.export_compensation)
    for suffix, text in files.items():
        path = base if not suffix else base.with_name(base.stem + suffix)
        atomic_write_text(path, text)
        say(args, f"wrote {path} (point {args.at}, {args.comp_format})")
    for w in location_warnings(errs, je.point_names, np.asarray(je.points_xy), args.at,
                               args.tol_um, args.tol_urad):
        print(f"diffguide fit: warning: {w}", file=sys.stderr)
