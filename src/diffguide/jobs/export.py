"""The compensation export's settings of the jobs (``fit`` and ``simulate``): the controller
settings of the command line over the machine file's ``[export]`` table
(:mod:`diffguide.studies.exports.settings`), and every refusal of the export before the work.
``args`` is any object with the options' attributes (the command line's namespace, or
:class:`diffguide.jobs.FitSettings`)."""

import math

def check_tolerances(args) -> None:
    """``--tol-um`` / ``--tol-urad`` (the compensation export's location warnings) must be
    finite and > 0."""
    for flag, tol in (("--tol-um", args.tol_um), ("--tol-urad", args.tol_urad)):
        if not (math.isfinite(tol) and tol > 0):
            raise ValueError(f"{flag} must be a finite number > 0, got {tol:g}")


def export_spec(args, cfg):
    """The :class:`~diffguide.studies.exports.ExportSpec` of ``--export-compensation`` in
    ``--format`` with ``--axis-side`` and the controller settings: the command line's over the
    machine file's ``[export]`` (``cfg``, validated) over the defaults. ``ValueError`` naming
    the option where one is not allowed."""
    from ..studies.exports import file_spec
    from ..studies.exports.settings import SETTINGS, merged, parse_option

    given = {k: getattr(args, "export_" + k, None) for k in SETTINGS}
    options = {k: parse_option(k, v) for k, v in given.items() if v is not None}
    return file_spec(args.comp_format, args.export_compensation, args.axis_side,
                     merged(cfg.get("export"), options))


def check_export(args, cfg, x_mm, x0_mm) -> None:
    """Everything the export will refuse, refused now, before any work: the export written
    (and dropped) once from zero errors at the table's positions ``x_mm`` (mm)."""
    import numpy as np

    from ..studies.exports import export_compensation

    spec = export_spec(args, cfg)
    if args.comp_format in ("siemens-cec", "isg-cross") and not spec.axis_side:
        raise ValueError(f"--format {args.comp_format} needs --axis-side (tool, workpiece or "
                         "Y=...,Z=...): the sign of the EYX/EZX tables depends on it")
    x_mm = np.asarray(x_mm, float)
    export_compensation(spec, x_mm, np.zeros((len(x_mm), 6)), x0_mm=x0_mm,
                        exx_includes_lead=True)
