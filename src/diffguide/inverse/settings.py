"""The fit's settings from the command line's flags and a machine configuration's ``[fit]``
section: the structure mode, the weight criterion, the structural priors, the stated rail
waviness and whether the rigid-table inversion runs too. A flag (given, not None) wins over the
configuration, the configuration over the defaults."""

import numpy as np

from .structure import Prior, StructurePriors

#: The default prior ranges, as factors of the machine's own value: (low, high).
THICKNESS_RANGE = (0.5, 2.0)
PRELOAD_RANGE = (0.25, 2.0)
#: The default prior of an imported table's stiffness scale ``[value, lo, hi]``: the FE model's
#: stiffness, within a factor 2 either way at ±2σ (σ of ``ln s`` = ln 2 / 2 ≈ 0.35).
STIFFNESS_PRIOR = (1.0, 0.5, 2.0)


def parse_prior(text: str, flag: str, scale: float) -> list[float]:
    """``VALUE,LO,HI`` as three numbers times ``scale`` (e.g. 1e-3 for mm → m); ``ValueError``
    naming ``flag`` unless ``0 < LO <= VALUE <= HI``, all finite."""
    try:
        v = [float(t) for t in text.split(",")]
        if len(v) != 3:
            raise ValueError
    except ValueError:
        raise ValueError(f"{flag} must be VALUE,LO,HI (three numbers), got {text!r}") from None
    if not (0 < v[1] <= v[0] <= v[2]) or not all(np.isfinite(v)):
        raise ValueError(f"{flag} needs 0 < LO <= VALUE <= HI, got {text!r}")
    return [x * scale for x in v]


def fit_modes(cfg: dict, structure: str | None = None,
              criterion: str | None = None) -> tuple[str, str]:
    """``(structure, criterion)``: ``"estimate"``/``"fixed"`` and ``"ml"``/``"gcv"`` — the
    arguments, else the configuration's ``[fit]`` section, else ``("estimate", "ml")``."""
    fit = cfg.get("fit", {})
    return (structure or fit.get("structure") or "estimate",
            criterion or fit.get("criterion") or "ml")


def rail_waviness(cfg: dict, waviness_um: float | None = None) -> float:
    """The stated short-wave rail waviness (m RMS): ``waviness_um`` (µm), else the
    configuration's ``[fit] rail_waviness_um``, else 0."""
    um = waviness_um
    if um is None:
        um = cfg.get("fit", {}).get("rail_waviness_um", 0.0)
    return float(um) * 1e-6


def rail_joints(cfg: dict, joints_mm=None) -> tuple[float, ...]:
    """The stated rail joints (m, increasing): ``joints_mm`` (mm), else the configuration's
    ``[fit] rail_joints_mm``, else none."""
    mm = joints_mm
    if mm is None:
        mm = cfg.get("fit", {}).get("rail_joints_mm", ())
    return tuple(sorted(float(v) * 1e-3 for v in mm))


def rigid_wanted(cfg: dict, rigid: bool | None = None) -> bool:
    """Whether to run the rigid-table inversion too: ``rigid``, else the configuration's
    ``[fit] rigid``, else no (it costs a compilation of its own)."""
    if rigid is not None:
        return bool(rigid)
    return bool(cfg.get("fit", {}).get("rigid", False))


def structure_priors(cfg: dict, *, structure: str | None = None,
                     thickness_prior_mm: str | None = None,
                     preload_prior: str | None = None,
                     stiffness_prior: str | None = None) -> StructurePriors:
    """The structural priors (:class:`.structure.StructurePriors`, thickness in m, preload as a
    fraction of C, stiffness as a scale): none when the structure is ``"fixed"``
    (:func:`fit_modes`); else the ``VALUE,LO,HI`` texts (thickness in mm,
    ``--thickness-prior-mm``/``--preload-prior``/``--stiffness-prior``), else the
    configuration's ``[fit] thickness_prior_mm``/``preload_prior``/``stiffness_prior``, else the
    machine's own values (``[table] thickness_mm``, ``[carriage] preload_fraction``) with the
    ranges :data:`THICKNESS_RANGE` and :data:`PRELOAD_RANGE` times them. A table imported from
    an FE model (``[table] source = "superelement"``) has no thickness: its structural unknown
    is the scale on its stiffness, prior :data:`STIFFNESS_PRIOR` by default."""
    if fit_modes(cfg, structure)[0] == "fixed":
        return StructurePriors()
    fit = cfg.get("fit", {})
    imported = cfg.get("table_source") is not None
    p0 = cfg["carriage"]["preload_fraction"]
    if preload_prior:
        p = parse_prior(preload_prior, "--preload-prior", 1.0)
    elif fit.get("preload_prior") is not None:
        p = list(fit["preload_prior"])
    else:
        p = (p0, PRELOAD_RANGE[0] * p0, PRELOAD_RANGE[1] * p0)
    if imported:
        if thickness_prior_mm:
            raise ValueError("--thickness-prior-mm: the table is imported from an FE model "
                             '(source = "superelement") and has no thickness; give '
                             "--stiffness-prior VALUE,LO,HI (a scale on its stiffness)")
        if stiffness_prior:
            k = parse_prior(stiffness_prior, "--stiffness-prior", 1.0)
        elif fit.get("stiffness_prior") is not None:
            k = list(fit["stiffness_prior"])
        else:
            k = STIFFNESS_PRIOR
        return StructurePriors(None, Prior(*p), Prior(*k))
    if stiffness_prior:
        raise ValueError("--stiffness-prior applies to a table imported from an FE model "
                         '([table] source = "superelement"); the plate has a thickness '
                         "(--thickness-prior-mm)")
    t0 = cfg["table"]["thickness_mm"] * 1e-3
    if thickness_prior_mm:
        t = parse_prior(thickness_prior_mm, "--thickness-prior-mm", 1e-3)
    elif fit.get("thickness_prior_mm") is not None:
        t = [v * 1e-3 for v in fit["thickness_prior_mm"]]
    else:
        t = (t0, THICKNESS_RANGE[0] * t0, THICKNESS_RANGE[1] * t0)
    return StructurePriors(Prior(*t), Prior(*p))
