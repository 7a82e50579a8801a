"""What a fit's report says on the console, and its JSON text's plain types: read from
``report.json``'s content (:mod:`diffguide.jobs.fit_summary` assembles it)."""

import numpy as np


def misfit_lines(report: dict) -> list[str]:
    """The console lines of ``report["misfit"]``: one per likely cause, with what to do."""
    section = report.get("misfit") or {}
    return [f"misfit (chi2/dof {section['chi2_dof']:.3g}): {f['message']}; {f['action']}"
            for f in section.get("findings", [])]


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
