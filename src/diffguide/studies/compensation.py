"""CNC compensation tables of joint kinematic errors, for one point on the table.

Volumetric compensation treats the table as a rigid body: the errors of one point, carried to the
others by rigid-body kinematics, stand for the whole table. :func:`compensation_table` writes the
errors at the chosen point as a plain-text table in the style of ISG/Heidenhain axis-error
tables, and :func:`location_warnings` says where the other points depart from that rigid-body
prediction by more than a tolerance — the paper's conclusion (Majda 2012) made actionable: on a
deforming table such a table is only valid near the point it was made for.

Table format (whitespace-separated; ``#`` starts a comment)::

    # diffguide compensation table ... units ... point ...
    X_mm  EXX_um  EYX_um  EZX_um  EAX_urad  EBX_urad  ECX_urad
    -350.000  0.123 ...

The values are the *errors* (ISO 230-1 signs, relative to the reference position); a controller
compensates by moving by their negatives.
"""

import numpy as np

from .._core.comments import CommentSyntax
from .._core.rigid import transfer
from ..machine.errors import ERROR_UNITS as _UNITS
from ..machine.errors import error_columns
from ..machine.kinematics import ERROR_NAMES

_COMMENT = CommentSyntax("#", ascii_only=False)  # its header: "#" lines, UTF-8


def compensation_table(positions_mm, errors_user, point_names, at: str, source: str = "") -> str:
    """The compensation table of point ``at``.

    Arguments:
        positions_mm: (n_pos,) table positions (mm), increasing.
        errors_user: (n_pos, n_points, 6) errors in µm / µrad.
        point_names: names of the points (``at`` must be one).
        at: the point whose errors the table holds.
        source: a line describing where the errors come from (for the header).
    """
    if at not in point_names:
        raise ValueError(f"--at must be one of the points {', '.join(point_names)}, got {at!r}")
    j = list(point_names).index(at)
    head = [
        "# diffguide compensation table (ISG-style axis error table for the X axis)",
        *_COMMENT.lines([f"point {at}; {source}".rstrip("; ")]),
        "# values are errors (ISO 230-1 signs) relative to the reference position;",
        "# the controller compensates by their negatives. Units: X in mm, EXX EYX EZX in µm,",
        "# EAX (roll) EBX (pitch) ECX (yaw) in µrad (µm/m).",
        "X_mm " + " ".join(error_columns()),
    ]
    rows = [
        f"{x:9.3f} " + " ".join(f"{v + 0.0:10.4f}" for v in errors_user[i, j])
        for i, x in enumerate(positions_mm)
    ]
    return "\n".join(head + rows) + "\n"


def non_rigid_part(errors_user, points_xy, at_index: int):
    """What volumetric compensation from point ``at`` cannot capture, per point: the errors minus
    their rigid-body prediction from the errors at ``at``
    (``t_P = t_at + θ_at × (P − at)``, ``θ_P = θ_at``; µm and µrad, lever arms in m).

    Arguments:
        errors_user: (n_pos, n_points, 6) in µm / µrad. points_xy: (n_points, 2) in m (all on
        the table top, so the lever arm has no Z part).
    """
    e = np.asarray(errors_user)
    xy = np.asarray(points_xy)
    arm = np.zeros((xy.shape[0], 3))
    arm[:, :2] = xy - xy[at_index]
    predicted = transfer(e[:, at_index, None, :], arm[None, :, :])  # µm + µrad × m, µrad
    return e - predicted


def location_warnings(
    errors_user, point_names, points_xy, at: str, tol_um: float = 2.0, tol_urad: float = 5.0
) -> list[str]:
    """Points where a rigid-body compensation made at ``at`` is off by more than the tolerance
    somewhere on the stroke (:func:`non_rigid_part`; µm for EXX/EYX/EZX, µrad for the angles).
    One message per point and error."""
    j = list(point_names).index(at)
    worst = np.max(np.abs(non_rigid_part(errors_user, points_xy, j)), axis=0)
    out = []
    for k, name in enumerate(point_names):
        if k == j:
            continue
        for e, (err, unit) in enumerate(zip(ERROR_NAMES, _UNITS)):
            tol = tol_um if e < 3 else tol_urad
            if worst[k, e] > tol:
                out.append(
                    f"{err} at {name} departs from the rigid-body prediction from {at} by up to "
                    f"{worst[k, e]:.1f} {unit} (tolerance {tol:g} {unit}): the table deforms; a "
                    f"compensation made at {at} does not hold at {name}"
                )
    return out


#: each plane's straightness: (plane, the error its common slope tilts)
_PLANES = (("vertical", "EZX"), ("horizontal", "EYX"))


def common_slope_note(fit, x_mm, x0_mm: float = 0.0) -> tuple[str, ...]:
    """What a fit's straightness (EYX, EZX) leaves undetermined, for an export's header.

    A common slope ``a`` of both rails in one plane moves the table by ``a·x`` and tilts it by
    a constant: the angles (relative to x = 0) do not see it and a straightness channel's own
    alignment slope takes it (:mod:`diffguide.inverse.basis`), so the fit fixes it at zero
    (``fit.fix_slope``, report.json's gauge). The machine's straightness is then the table's
    value plus ``a·(X − x0)`` with ``a`` unknown and outside σ. Where the fit has straightness
    channels, their fitted alignment slopes (µm/m, with their posterior σ) bound what the data
    showed: the common slope is an unknown part of each.

    Arguments: fit: the :class:`~diffguide.inverse.RailFit` (or a
    :class:`~diffguide.inverse.predict.FitPosterior`: no alignment slopes then). x_mm: the table's positions (mm,
    x = 0 the reference). x0_mm: the machine coordinate of x = 0 (mm).
    """
    from ..inverse.problem import FIX_SLOPE

    # a FitPosterior (predict's, read back from posterior.json) holds neither: every fit fixes
    # the common slopes of FIX_SLOPE, and its alignment slopes are in report.json
    fix_slope = getattr(fit, "fix_slope", FIX_SLOPE)
    planes = [f"{e} ({p} plane)" for (p, e), fixed in zip(_PLANES, fix_slope) if fixed]
    if not planes:
        return ()
    reach = float(np.max(np.abs(np.asarray(x_mm, float)))) * 1e-3  # µm per µm/m at the ends
    lines = [
        f"STRAIGHTNESS SLOPE NOT DETERMINED: {' and '.join(planes)} carry the fit's "
        "undetermined common slope of both rails in their plane, fixed at zero (report.json: "
        "identifiability gauge, fixed modes 'common ... slope of both rails')",
        f"the machine's EYX/EZX may differ from these values by a*(X - {x0_mm:g} mm), a the "
        f"unknown slope; it is NOT in the sigma; 1 um/m of it is {reach:.3g} um at the "
        "table's ends",
    ]
    n = len(getattr(fit, "alignment", ()))
    if n:
        cov = np.asarray(fit.posterior_cov, float)
        sd = (np.sqrt(np.clip(np.diag(cov)[-n:], 0.0, None)) if cov.shape[0] >= n
              else np.full(n, np.nan))
        slopes = ", ".join(f"{a * 1e6:+.3g} +/- {s_ * 1e6:.2g}"
                           for a, s_ in zip(fit.alignment, sd))
        lines.append(f"the fit's alignment slopes of the straightness channels (report.json "
                     f"alignment_slopes_um_per_m, in its order): {slopes} um/m; the common "
                     "slope is an unknown part of each")
    lines.append("to remove it: measure the slope of the X motion against a straightness "
                 "reference aligned to the machine (its parallelism to the axis it must "
                 "follow) and add a*(X - x0) to the table, or accept a table that corrects "
                 "straightness about this reference line only")
    return tuple(lines)


def fitted_compensation(spec, fit, x_mm, at: str, fmt: str, *, points: dict,
                        nx: int | None = None, ny: int | None = None, x0_mm: float = 0.0,
                        source: str = "", tol_um: float = 2.0,
                        tol_urad: float = 5.0, z: float = 0.0,
                        make_machine=None) -> tuple[dict[str, str], list[str]]:
    """A compensation export of the errors a fitted model predicts at point ``at``, with σ.

    Arguments:
        spec: the fitted machine's :class:`~diffguide.machine.spec.MachineSpec` (the fitted
            structure replaces its own). fit: the :class:`~diffguide.inverse.RailFit`.
            x_mm: table positions (mm, x = 0 the reference position); positions outside the
            measured range are extrapolated (their σ says how little the data hold there).
            at: the point. fmt: a :data:`~.exports.FORMATS` name or an
            :class:`~.exports.ExportSpec`. points: ``{name: (x, y)}``
            (m), ``at`` among them, the fit's measured points included (their mesh lines).
            nx, ny: the fit's mesh. x0_mm: the machine coordinate (mm) of x = 0. source: a
            line for the header. tol_um, tol_urad: the tolerances of
            :func:`location_warnings` (µm, µrad). z: the tool point's height above the table
            top (m; :func:`~diffguide.inverse.predict.predict`'s Abbe terms). make_machine:
            the fitted machine's builder, for an imported table (``predict``'s).

    Returns ``({suffix: text}, warnings)``: :func:`~.exports.export_compensation`'s files —
    the errors and σ of :func:`diffguide.inverse.predict.predict`, the prediction with σ from
    the fit's full posterior (rails, structure, lead and alignment nuisances), EXX including the
    fitted lead error, the straightness with :func:`common_slope_note` in its header — and one
    warning per point where a rigid-body compensation made at ``at`` would not hold.
    ``ValueError`` when an equilibrium over the stroke does not converge.
    """
    from ..inverse.predict import predict
    from .exports import export_compensation

    x_mm = np.asarray(x_mm, float)
    if at not in points:
        raise ValueError(f"--at must be one of the points {', '.join(points)}, got {at!r}")
    pred = predict(fit, spec, points, x_mm * 1e-3, nx=nx, ny=ny, extrapolate=True, z=z,
                   make_machine=make_machine, mesh_points=points)
    if z:
        source = f"{source}; at {z * 1e3:g} mm above the table top".lstrip("; ")
    j = list(pred.point_names).index(at)
    errs, _ = pred.user_units()
    # EXX holds the fitted lead error where EXX data were fitted; without them the lead is
    # unknown and EXX is left out of the table (exports' rule)
    files = export_compensation(fmt, x_mm, pred.errors[:, j, :], pred.sigma[:, j, :],
                                x0_mm=x0_mm, point=at, source=source,
                                exx_includes_lead=True if pred.lead else None,
                                straightness_note=common_slope_note(fit, x_mm, x0_mm))
    warnings = location_warnings(errs, pred.point_names, pred.points_xy, at, tol_um, tol_urad)
    return files, warnings
