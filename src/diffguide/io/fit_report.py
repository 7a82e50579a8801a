"""A fit's ``report.json`` (user units: mm, µm, µrad) and its console summary of what the data
do not determine."""

import numpy as np

from ..inverse import identifiability
from ..inverse.data import QUANTITIES
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
    return report


def fit_validity(fit, meas, machine) -> list:
    """The validity warnings of the elastic fit (:mod:`diffguide.inverse.validity`: null data,
    χ²/dof, measured rotations; :func:`diffguide.machine.validity.rail_range`: the fitted rails
    under the carriages at the measured positions)."""
    return [*fit_checks(fit, meas),
            *rail_range(machine, fit.rails(), np.unique(np.asarray(meas.position)))]


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


def _structure_rows(fit) -> dict:
    """Per structural unknown, in mm (thickness) or as a fraction of C (preload)."""
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
        "s_range_mm": [fit.basis.start * 1e3, fit.basis.end * 1e3],
        "gauge": list(fit.gauge), "channels": channels, "fit_seconds": seconds,
        "units": "user units: µm for EXX/EYX/EZX, µm/m (µrad) for EAX/EBX/ECX",
    }


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
        lines.append("not determined by the data (there the σ bands are the prior's, its scale "
                     "not below a floor between its extrapolation and the visible content's), "
                     "wavelengths in mm: " + "; ".join(bands))
    if waviness == 0.0:
        shortest = min((r["wavelength_mm"] for c in ident["wavelengths"] for r in c["transfer"]),
                       default=None)
        if shortest is not None:
            lines.append(f"rail content shorter than {shortest:.0f} mm (two knot spacings: the "
                         "profiles cannot hold it and the carriages average it out) is not in the "
                         "σ bands: state its RMS with --rail-waviness-um")
    return lines


def jsonable(obj):
    """Plain JSON types; non-finite numbers become null (never NaN in the file)."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    return obj
