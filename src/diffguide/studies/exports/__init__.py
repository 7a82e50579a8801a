r"""Compensation tables for real controllers, from the joint errors predicted at one point.

Input everywhere: table positions ``x`` (mm, relative to the reference position x = 0), the six
joint errors at the chosen point ``(n, 6)`` in SI (m, rad; ISO 230-1 signs, relative to x = 0)
and their standard uncertainties (same shape, or ``None``). ``x0_mm`` is the machine coordinate
of x = 0: every table is written in machine coordinates ``X = x + x0``.

**Sign** (:mod:`._common`): a controller adds a compensation value to the compensated axis. X
carries the workpiece (diffguide's table), so pitch is ``−EXX``; a cross-axis table is
``−E`` on a workpiece-side axis and ``+E`` on a tool-side axis: the side of Y and Z is an
explicit option (``axis_side``), never guessed. ``isg`` and ``csv`` hold the errors themselves
(ISG computes the correction, given ``workpiece_axes``).

**EXX and the lead error.** ``exx_includes_lead`` says what EXX holds: ``True`` (a fit's EXX
with the fitted lead error), ``False`` (a simulation: ideal drive, no lead error), ``None``
(unknown): then EXX is left out of every file, with the reason in its header, and the pitch-only
``fanuc`` export is refused.

Formats (``FORMATS``; sources in each module and in docs/compensation-exports.md):

- ``csv`` — ``X_machine_mm,x_mm,EXX_um,EXX_sigma_um,...,ECX_urad,ECX_sigma_urad``.
- ``isg`` — ISG CSV (``X EXX ... ECX``, mm and rad, errors) + ``.lis`` configuration lines
  (axis numbers ``x y z``, ``chain``, ``workpiece_axes``) + ``.startup.lis`` start-up lines
  (``vol_comp[0].file_name``, ``max_records``) (:mod:`.isg`).
- ``isg-cross`` — ISG cross compensation lists ``kw.crosscomp.*``, one per compensated axis
  (``.Y.lis``, ``.Z.lis``; 0.1 µm), EYX on Y, EZX on Z (:mod:`.isg_cross`).
- ``siemens-cec`` — SINUMERIK CEC init program for EYX on Y, EZX on Z, with the activation data
  as comments (:mod:`.siemens`).
- ``heidenhain`` — TNC nonlinear compensation ``NAME.COM`` (``NR AXISPOS X Y Z``) +
  ``.cma`` + ``.note.txt``; *experimental* frame; angles refused (:mod:`.heidenhain`).
- ``fanuc`` — pitch error compensation of X for parameters 3620–3624 as a setting sheet;
  *experimental*; no straightness (:mod:`.fanuc`).
"""

import os
from dataclasses import replace
from pathlib import Path

import numpy as np

from . import fanuc, heidenhain, isg, isg_cross, plain, siemens
from ._common import SIDES as SIDES
from ._common import ExportSpec as ExportSpec
from ._common import parse_axis_side as parse_axis_side
from .plain import sigma_csv as sigma_csv
from .settings import merged, spec_options

FORMATS = ("csv", "isg", "isg-cross", "siemens-cec", "heidenhain", "fanuc")
#: Formats whose syntax could not be fully confirmed from documentation, and why.
EXPERIMENTAL = {"heidenhain": heidenhain.EXPERIMENTAL, "fanuc": fanuc.EXPERIMENTAL}
_WRITERS = {"isg": isg.write, "isg-cross": isg_cross.write, "siemens-cec": siemens.write,
            "heidenhain": heidenhain.write, "fanuc": fanuc.write}


def file_spec(fmt: str, path: str | os.PathLike, axis_side: str | None = None,
              settings: dict | None = None) -> ExportSpec:
    """The :class:`ExportSpec` of an export written to ``path`` (the command line's
    ``--export-compensation``): the table named after the file (its stem, upper case), the
    file's name on the configuration lines, ``axis_side`` as :func:`parse_axis_side` reads it,
    the controller ``settings`` (:func:`.settings.merged`: the command line's over the machine
    file's over the defaults). ``ValueError`` naming the file where its name cannot be written
    into the table."""
    path = Path(path)
    side = None if axis_side is None else parse_axis_side(axis_side)
    options = spec_options(merged() if settings is None else settings)
    try:
        return ExportSpec(fmt, axis_side=side, table_name=path.stem.upper(), file_name=path.name,
                          **options)
    except ValueError as exc:
        raise ValueError(f"--export-compensation {path}: the file's name is written into the "
                         f"table: {exc}") from None


def export_compensation(
    fmt,
    x_mm,
    errors,
    sigma=None,
    *,
    x0_mm: float = 0.0,
    point: str = "P",
    source: str = "",
    detection_unit_mm: float | None = None,
    axis_side=None,
    exx_includes_lead: bool | None = None,
    straightness_note: tuple[str, ...] | None = None,
) -> dict[str, str]:
    """The files of a compensation export: ``{suffix: text}``, ``""`` the table itself, and
    companions by format (``.sigma.csv`` the σ where the table has no room for it, ``.cma``,
    ``.lis``, ``.note.txt``).

    Arguments:
        fmt: a :data:`FORMATS` name or an :class:`ExportSpec` (the format with its options).
        x_mm: table positions (mm, x = 0 the reference position). errors: ``(n, 6)`` joint
            errors (m, rad). sigma: their standard uncertainties, or ``None``.
        x0_mm: machine coordinate (mm) of x = 0. point, source: for the header.
        detection_unit_mm, axis_side: override the spec's (``fanuc`` detection unit in mm;
            side of Y and Z: :class:`ExportSpec`).
        exx_includes_lead: whether EXX includes the fitted lead error (``True``), has none
            (``False``: a simulation), or is unknown (``None``: EXX left out, ``fanuc``
            refused).
        straightness_note: lines for the header of every file holding EYX or EZX: what the
            straightness leaves undetermined (a fit's common slope:
            :func:`diffguide.studies.compensation.common_slope_note`).

    ``ValueError`` with the reason where a table cannot be written (module docstring).
    """
    spec = fmt if isinstance(fmt, ExportSpec) else ExportSpec(str(fmt))
    if spec.format not in FORMATS:
        raise ValueError(f"--format must be one of {', '.join(FORMATS)}, got {spec.format!r}")
    if axis_side is not None:
        spec = replace(spec, axis_side=axis_side)
    if detection_unit_mm is not None:
        spec = replace(spec, detection_unit_mm=detection_unit_mm)
    x_mm = np.asarray(x_mm, float)
    err = np.asarray(errors, float)
    sig = None if sigma is None else np.asarray(sigma, float)
    if err.shape != (len(x_mm), 6) or (sig is not None and sig.shape != err.shape):
        raise ValueError("errors (and sigma) must have shape (n_positions, 6)")
    kw = dict(x0_mm=x0_mm, point=point, source=source, exx_includes_lead=exx_includes_lead,
              straightness_note=tuple(straightness_note or ()))
    if spec.format == "csv":
        return plain.write(x_mm, err, sig, **kw)
    files = _WRITERS[spec.format](x_mm, err, spec=spec, **kw)
    if sig is not None:
        note = kw["straightness_note"] if spec.format != "fanuc" else ()
        files[".sigma.csv"] = sigma_csv(x_mm, sig, x0_mm, point, exx_includes_lead, note)
    return files
