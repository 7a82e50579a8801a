"""A fit's ``report.json`` content (user units: mm, µm, µrad): the sections assembled from the
fit, the measurements and the machine (the console's lines read from it and the JSON text:
:mod:`diffguide.io.report_text`)."""

import numpy as np

from ..inverse.identify import identifiability
from ..inverse.data import QUANTITIES
from ..inverse.diagnose import MISFIT_CHI2, diagnose_fit
from ..inverse.file_chi2 import file_chi2
from ..inverse.validity import fit_checks
from ..machine.validity import rail_range
from ..studies.iso230_2 import channel_figures


def fit_report(meas, fits: dict, profiles: dict, seconds: dict, machine, *, source: dict,
               exit_code: int, truth=None, truth_file=None) -> dict:
    """``report.json``'s content (without ``total_seconds``; user units).

    Arguments:
        meas: the merged measurements. fits: ``{label: RailFit}`` (``""`` elastic,
            ``"_rigid"`` the rigid-table inversion if run). profiles: ``{label: (val, sig)}``
            on a common ``s`` grid (m). seconds: ``{label: s}``. machine: the base machine (for
            the rigid-table blind wavelengths). source: ``{"preset", "config",
            "measurements"}`` as given. exit_code: the command's exit code. truth: known
            profiles on the same grid (m) and truth_file their file, to score the fits.
    """
    elastic = fits[""]
    report = {
        "command": "diffguide fit", "preset": source["preset"], "config": source["config"],
        "status": {"converged": bool(elastic.converged), "message": elastic.message,
                   "exit_code": exit_code},
        "measurements": {
            "file": str(source["measurements"]), "readings": len(meas.readings),
            "merged_rows": meas.n,
            "points": {n: [float(x * 1e3), float(y * 1e3)] for n, (x, y) in
                       zip(meas.point_names, meas.points_xy)},
            "sigma_sources": sorted(set(meas.sigma_source)),
            "rejected_reading_lines": list(meas.rejected),
        },
        "iso230_2": channel_figures(meas),  # per channel where the runs allow
        "elastic": fit_summary(elastic, meas, seconds[""]),
        "identifiability": identifiability(elastic, machine),
    }
    if "_rigid" in fits:
        report["rigid_table"] = fit_summary(fits["_rigid"], meas, seconds["_rigid"])
        dv = profiles[""][0] - profiles["_rigid"][0]
        report["elastic_vs_rigid_profile_rms_difference_um"] = {
            f"rail {r + 1} {pl}": float(np.sqrt(np.mean(dv[r, p] ** 2)) * 1e6)
            for r in range(2) for p, pl in enumerate(("vertical", "horizontal"))}
    if truth is not None:
        report["truth"] = _truth_section(profiles, truth, truth_file)
    report["validity"] = [w.as_dict() for w in fit_validity(elastic, meas, machine)]
    report["misfit"] = misfit_section(elastic, meas, machine)
    return report


def misfit_section(fit, meas, machine) -> dict:
    """``report.json``'s ``misfit``: when ``χ²/dof`` exceeds :data:`~diffguide.inverse.diagnose.
    MISFIT_CHI2`, the likely causes found in the residuals (:mod:`diffguide.inverse.diagnose`;
    the default knot spacing, the carriage's loaded length, is the finest suggested), each with
    its channels named, what to do and its numbers (mm where a length)."""
    findings = diagnose_fit(fit, meas, default_spacing=float(machine.carriage.length))
    return {"chi2_dof": float(fit.chi2_dof), "threshold": MISFIT_CHI2,
            "findings": [{**f.as_dict(), "channels": [meas.channel_label(c) for c in f.channels]}
                         for f in findings]}


def fit_validity(fit, meas, machine) -> list:
    """The validity warnings of the elastic fit (:mod:`diffguide.inverse.validity`: null data,
    χ²/dof, measured rotations; :func:`diffguide.machine.validity.rail_range`: the fitted rails
    under the carriages at the measured positions)."""
    def sample(r, s):  # the fitted rails from their basis (NumPy: nothing to compile)
        B = fit.basis.matrix(np.ravel(s))
        return tuple((B @ fit.coeffs[r, p]).reshape(np.shape(s)) for p in (1, 0))  # e_y, e_z

    return [*fit_checks(fit, meas),
            *rail_range(machine, fit.rails(), np.unique(np.asarray(meas.position)),
                        sample=sample)]


def _truth_section(profiles, truth, truth_file) -> dict:
    """The fits scored against known profiles ``truth`` (m, on the profiles' grid): RMS error
    per profile and overall (µm), the fraction inside ±2σ, and the truth's own RMS (µm)."""
    out = {"file": str(truth_file), "rms_error_um": {}, "coverage_2sigma": {}}
    for label, (val, sig) in profiles.items():
        name = "rigid_table" if label else "elastic"
        err = val - truth
        out["rms_error_um"][name] = {
            f"rail {r + 1} {pl}": float(np.sqrt(np.mean(err[r, p] ** 2)) * 1e6)
            for r in range(2) for p, pl in enumerate(("vertical", "horizontal"))}
        out["rms_error_um"][name]["all"] = float(np.sqrt(np.mean(err**2)) * 1e6)
        out["coverage_2sigma"][name] = float(np.mean(np.abs(err) <= 2 * sig))
    out["rms_truth_um"] = float(np.sqrt(np.mean(truth**2)) * 1e6)
    return out


def _channel_rows(fit, meas) -> list[dict]:
    """Per channel: residual RMS (µm or µrad), χ² of the used rows, count, zero offset."""
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
    return channels


#: Each structural unknown's unit in the report and the factor from SI to it.
STRUCTURE_UNITS = {"thickness": ("mm", 1e3), "preload": ("fraction of C", 1.0),
                   "stiffness": ("", 1.0)}
#: Each structural unknown in words (the console, report.json, report.html).
STRUCTURE_LABELS = {"thickness": "table equivalent thickness", "preload": "preload",
                    "stiffness": "table stiffness scale"}


def _structure_rows(fit) -> dict:
    """Per structural unknown, in mm (thickness), as a fraction of C (preload) or as a scale
    on an imported table's stiffness (stiffness), with its label in words."""
    structure = {}
    for name, v in fit.structure.items():
        unit, f = STRUCTURE_UNITS.get(name, ("fraction of C", 1.0))
        structure[name] = {
            "label": STRUCTURE_LABELS.get(name, name),
            "unit": unit, "value": v["value"] * f, "sigma": v["sigma"] * f,
            "prior_value": v["prior_value"] * f,
            "prior_range": [x * f for x in v["prior_range"]],
            "determined_by_data": v["determined"], "at_interpolation_bound": v["at_bound"],
            "note": ("determined by the data" if v["determined"] else
                     "not determined by the data: the value is the prior's and its "
                     "uncertainty widens the rails' bands"),
        }
    return structure


def fit_summary(fit, meas, seconds: float) -> dict:
    """A fit's section of ``report.json`` (user units: mm, µm, µrad; ``seconds`` the fit's
    time, s): the method, status, weight, χ² account, resolution, structure, outliers,
    nuisances, knot grid and one row per channel."""
    chan = meas.channel_index()
    channels = _channel_rows(fit, meas)
    structure = _structure_rows(fit)
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
        "rail_joint_steps_um": [{"s_mm": d["s"] * 1e3, "rail": d["rail"], "plane": d["plane"],
                                 "value": d["value"] * 1e6, "sigma": d["sigma"] * 1e6}
                                for d in fit.joint_steps()],
        "s_range_mm": [fit.basis.start * 1e3, fit.basis.end * 1e3],
        "gauge": list(fit.gauge), "channels": channels,
        # several files: each one's χ² against the fit of all (a reversed file accepted with
        # --accept-file-conflicts shows as the one the model does not explain)
        "files": file_chi2(meas, fit.fitted, fit.outliers, fit.dof), "fit_seconds": seconds,
        "units": "user units: µm for EXX/EYX/EZX, µm/m (µrad) for EAX/EBX/ECX",
    }


# --- the metrologist's sections: straightness, its interval and verdict; compensation ---

#: The reference line of report.json's straightness (ISO 230-1).
STRAIGHTNESS_REFERENCE = "least-squares"


def metrologist_sections(fit, meas, s_m, *, rail_y_mm=None, tolerance_um=None,
                         export=None) -> dict:
    """``report.json``'s ``straightness`` and ``compensation`` sections (user units: mm, µm,
    µrad), the numbers that ``report.html`` and the console show.

    Arguments:
        fit: the elastic :class:`~diffguide.inverse.RailFit`. meas: its measurements.
        s_m: the evaluation grid (m; ``rails.csv``'s). rail_y_mm: the rails' Y (mm), rail 1
            first. tolerance_um: the straightness tolerance (µm) of the verdict, or None.
        export: ``{"file", "format", "point"}`` of a requested compensation table, or None.
    """
    from ..inverse.validity import null_data
    from ..studies.straightness import COVERAGE, INFORMATIVE_RATIO, N_SAMPLES, rail_straightness

    tol = None if tolerance_um is None else tolerance_um * 1e-6
    y = None if rail_y_mm is None else [v * 1e-3 for v in rail_y_mm]
    rows = rail_straightness(fit, s_m, rail_y=y, tolerance=tol, informative=not null_data(meas),
                             reference=STRAIGHTNESS_REFERENCE)
    step = float(np.median(np.diff(s_m))) * 1e3
    straight = {
        "reference_line": "least-squares reference line (ISO 230-1)",
        "definition": "peak-to-valley of the profile's deviations from its least-squares "
                      "reference line over the evaluated length",
        "uncertainty_method": (
            f"Monte Carlo (GUM Supplement 1): {N_SAMPLES} draws per profile from the fit's "
            "posterior (spline coefficients ~ N(fitted, covariance), structure uncertainty "
            "included); straightness_um = the draws' median, u_um = their standard deviation, "
            f"interval_95_um = their {(1 - COVERAGE) / 2:.1%} and {(1 + COVERAGE) / 2:.1%} "
            "quantiles (probabilistically symmetric, asymmetric about the estimate)"),
        "estimate_bias": (
            "mean_profile_um is the fitted (mean) profile's peak-to-valley; bias_um = "
            "straightness_um − mean_profile_um: the draws are rougher than the mean profile "
            "(the fit smooths it), so they lie above its peak-to-valley. interval_95_basic_um "
            "= [2 mean_profile_um − q97.5, 2 mean_profile_um − q2.5] (the basic bootstrap "
            "interval, the draws reflected about mean_profile_um) is reported for comparison, "
            "not used: it would hold for an unregularised fit, but the mean profile is "
            "smoothed and its peak-to-valley low: on the identification battery it lay "
            "wholly below the truth's straightness in 13 of 80 rows (the draws' interval in "
            "none)"),
        "coverage_probability": COVERAGE, "samples_per_profile": N_SAMPLES, "seed": 0,
        "evaluated_s_mm": [float(s_m[0] * 1e3), float(s_m[-1] * 1e3)],
        "grid_step_mm": step,
        "tolerance_um": tolerance_um,
        "decision_rule": "ISO 14253-1 on the 95 % interval: pass if its upper end <= "
                         "tolerance, fail if its lower end > tolerance, otherwise not "
                         "decidable; not decidable as well where the data carry no "
                         "information beyond the prior (every channel constant, or the draws' "
                         f"spread at least {INFORMATIVE_RATIO * 100:g} % of the prior's)",
        "not_in_interval": (f"rail content shorter than about {2 * fit.basis.spacing * 1e3:.0f}"
                            " mm (two knot spacings) is not resolved and not in the interval"
                            + (f" (stated waviness {fit.waviness * 1e6:.3g} µm RMS)"
                               if fit.waviness > 0 else "")),
        "rails": [{"rail": r["rail"], "side": r["side"],
                   "y_mm": None if r["y"] is None else r["y"] * 1e3,
                   "plane": r["plane"], "straightness_um": r["value"] * 1e6,
                   "mean_profile_um": r["mean_profile"] * 1e6, "bias_um": r["bias"] * 1e6,
                   "u_um": r["u"] * 1e6,
                   "interval_95_um": [v * 1e6 for v in r["interval_95"]],
                   "interval_95_basic_um": [v * 1e6 for v in r["interval_95_basic"]],
                   "prior_ratio": r["prior_ratio"], "informative": r["informative"],
                   "verdict": r["verdict"], "verdict_reason": r["verdict_reason"]}
                  for r in rows],
    }
    return {"straightness": straight, "compensation": _compensation_section(fit, meas, export)}


def _compensation_section(fit, meas, export) -> dict:
    """Per channel: the fitted error's range over the measured positions (what a compensation
    from the model removes) and the residual RMS (what stays if the model is right); user
    units (µm or µrad)."""
    chan = meas.channel_index()
    rows = []
    for c in range(len(meas.channels)):
        sel = chan == c
        f = fit.fitted[sel] * 1e6
        rms = float(np.sqrt(np.mean(fit.residual[sel] ** 2)) * 1e6)
        q = QUANTITIES[meas.channels[c][1]]
        rows.append({"channel": meas.channel_label(c), "quantity": q,
                     "unit": "µm" if q in ("EXX", "EYX", "EZX") else "µrad",
                     "fitted_range_user": float(f.max() - f.min()),
                     "residual_rms_user": rms})
    return {
        "channels": rows, "export": export,
        "note": "a compensation from the fitted model removes about the fitted range and "
                "leaves about the residual RMS (more where the stroke goes beyond the "
                "measured positions); it helps where the range is well above the residual",
    }


def stamp_section(meas, source: dict, info: dict | None = None) -> dict:
    """``report.json``'s ``stamp``: the machine, the measurement files with the metadata of
    their header (``#`` comment lines at the top, and ``key: value`` or ``key = value`` lines
    there), the readings' notes where they carry any, the layout and x0 read, the date (UTC)
    and the diffguide version."""
    import datetime
    import os

    from .._core.version import __version__

    files = source["measurements"]
    files = [files] if isinstance(files, (str, os.PathLike)) else list(files)
    notes: dict[str, None] = {}
    for r in meas.readings:
        n = getattr(r, "notes", None)
        items = n.items() if isinstance(n, dict) else [n] if isinstance(n, str) else (n or ())
        for item in items:
            notes.setdefault(" = ".join(map(str, item)) if isinstance(item, tuple)
                             else str(item))
    return {
        "machine": source["config"] or f"preset {source['preset']}",
        "files": [{"file": str(f), "header": _file_header(f)} for f in files],
        "reading_notes": list(notes)[:50],
        "layout": (info or {}).get("layout"), "x0_mm": (info or {}).get("x0_mm"),
        "date_utc": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "diffguide": __version__,
    }


def _file_header(path, max_lines: int = 30) -> list[str]:
    """The leading comment lines of a measurement file (``#``, ``//`` or ``;``), stripped of
    the marker (a file that cannot be read gives none)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(8192)
    except OSError:
        return []
    lines = []
    for raw in head.decode("utf-8", errors="replace").lstrip("\ufeff").splitlines()[:max_lines]:
        line = raw.strip()
        marker = next((m for m in ("#", "//", ";") if line.startswith(m)), None)
        if marker is None:
            if line:
                break
            continue
        lines.append(line[len(marker):].strip())
    return [ln for ln in lines if ln]
