r"""Compensation tables for real controllers, from the joint errors predicted at one point.

Input everywhere: table positions ``x`` (mm, relative to the reference position x = 0, the
middle of the stroke), the six joint errors at the chosen point ``(n, 6)`` in SI (m, rad;
ISO 230-1 signs, relative to x = 0) and their standard uncertainties (same shape, or ``None``).
``x0_mm`` is the machine coordinate of x = 0: every table is written in machine coordinates
``X = x + x0``.

**Sign.** A compensation table is *added* by the controller to the commanded position of the
compensated axis, so a compensation value is the **negated error**: ``C = −E``. This holds for
``siemens-cec``, ``heidenhain`` and ``fanuc``. Two files hold the *errors* themselves, because
their documented columns are error parameters: ``isg`` (TwinCAT/ISG volumetric compensation
reads ISO 230-1 component errors and computes the correction itself; its ``negate`` parameter
must stay 0) and ``csv``. A cross-axis table (EYX on Y, EZX on Z) assumes the compensating axis
moves the same component as the erring X axis (the table); where it moves the tool instead the
sign flips — check one point on the machine.

Formats (``FORMATS``):

- ``csv`` — ``X_machine_mm,x_mm,EXX_um,EXX_sigma_um,...,ECX_urad,ECX_sigma_urad``: the errors
  (not negated) and their σ, ``#`` comment lines first.
- ``isg`` — ISG CSV format of TwinCAT CNC volumetric compensation (Beckhoff TF5280 "ISG CSV
  format"): a header line ``X EXX EYX EZX EAX EBX ECX`` naming the argument and the component
  errors, whitespace-separated records below, ``//`` line comments (``#`` would start a new
  table, so it is never written). Units **mm and rad** (an assumption: the documentation's
  example values are consistent with it; the unit is not stated in what could be checked).
  Values are the errors. σ: companion ``FILE.sigma.csv``.
- ``siemens-cec`` — SINUMERIK 840D sag/cross-error compensation (CEC) init program
  (``%_N_NC_CEC_INI``, ``CHANDATA(1)``, ``$AN_CEC[t,i]=value``, ``$AN_CEC_INPUT_AXIS[t]``,
  ``$AN_CEC_OUTPUT_AXIS[t]``, ``$AN_CEC_STEP[t]``, ``$AN_CEC_MIN[t]``, ``$AN_CEC_MAX[t]``,
  ``$AN_CEC_DIRECTION[t]=0``, ``$AN_CEC_MULT_BY_TABLE[t]=0``, ``$AN_CEC_IS_MODULO[t]=0``,
  ``;`` comments, ``M17`` at the end; syntax as in the K3 function manual). Table 0: EYX on
  the Y axis, table 1: EZX on the Z axis, both as functions of X; values in mm, ``−E``; the
  points must be equidistant. Axis names ``AX1``/``AX2``/``AX3`` for X/Y/Z are an assumption
  (use the machine's names). σ: companion ``FILE.sigma.csv``.
- ``heidenhain`` — a TNC table ``BEGIN NAME.COM MM`` / column line / rows / ``[END]``, columns
  ``NR X EXX EYX EZX EAX EBX ECX`` (ISO 230-1 names, the column scheme HEIDENHAIN recommends for
  a linear axis' KinematicsComp .COM file): X in machine coordinates (mm), compensation values
  ``−E`` in mm and degrees (assumed units: the TNC's length unit and degrees). σ: companion.
- ``fanuc`` — a Fanuc-style pitch / straightness list: per quantity (EXX pitch on X, EYX on Y,
  EZX on Z) the compensation point numbers ``N`` with **incremental** values ``P`` in detection
  units (``detection_unit_mm``, default 0.001 mm), the value of point n being the change of the
  compensation from point n−1 to n (rounded so that their sum is the rounded absolute value);
  the reference point (compensation 0) is the point at x = 0 and its number, the most negative
  and positive point numbers and the interval are given in comments in the parameter roles of
  3620/3621/3622/3624 (an assumption; the numbering 10000 + n / 20000 + n / 30000 + n is
  diffguide's, not a controller's). Angles are not written. σ: companion.
"""

import numpy as np

from ..machine.kinematics import ERROR_NAMES

FORMATS = ("csv", "isg", "siemens-cec", "heidenhain", "fanuc")
_USER = (1e6,) * 6
_UNIT = ("um", "um", "um", "urad", "urad", "urad")


def _header_lines(point, source, x0_mm, sign):
    return [
        f"diffguide compensation table, point {point}" + (f"; {source}" if source else ""),
        f"machine coordinates: X = x + x0, x0 = {x0_mm:g} mm (x = 0: the reference "
        "position, mid-stroke)",
        sign,
    ]


def sigma_csv(x_mm, sigma, x0_mm, point) -> str:
    """The companion file: ``X_machine_mm,x_mm`` and the six σ (µm, µrad), standard
    uncertainties of the *errors* (the same for the compensation values)."""
    lines = [
        f"# diffguide: standard uncertainty (1 sigma) of the errors at point {point}",
        "X_machine_mm,x_mm," + ",".join(f"{n}_sigma_{u}" for n, u in zip(ERROR_NAMES, _UNIT)),
    ]
    for x, s in zip(x_mm, sigma):
        lines.append(f"{x + x0_mm:.4f},{x:.4f}," + ",".join(f"{v * 1e6:.5f}" for v in s))
    return "\n".join(lines) + "\n"


def _csv(x_mm, err, sig, x0_mm, point, source):
    head = _header_lines(
        point,
        source,
        x0_mm,
        "values: the errors (ISO 230-1 signs, relative to "
        "x = 0); a controller compensates with their negatives",
    )
    cols = ["X_machine_mm", "x_mm"]
    for n, u in zip(ERROR_NAMES, _UNIT):
        cols += [f"{n}_{u}", f"{n}_sigma_{u}"]
    lines = [f"# {h}" for h in head] + [",".join(cols)]
    for i, x in enumerate(x_mm):
        vals = []
        for k in range(6):
            vals += [f"{err[i, k] * 1e6:.5f}", "" if sig is None else f"{sig[i, k] * 1e6:.5f}"]
        lines.append(f"{x + x0_mm:.4f},{x:.4f}," + ",".join(vals))
    return "\n".join(lines) + "\n"


def _isg(x_mm, err, x0_mm, point, source):
    head = _header_lines(
        point,
        source,
        x0_mm,
        "values: ISO 230-1 component errors of the X "
        "axis (not negated: the controller compensates them)",
    )
    head.append("units: X, EXX, EYX, EZX in mm; EAX, EBX, ECX in rad")
    lines = [f"// {h}" for h in head] + ["X EXX EYX EZX EAX EBX ECX"]
    for i, x in enumerate(x_mm):
        lin = " ".join(f"{v * 1e3:.9f}" for v in err[i, :3])
        ang = " ".join(f"{v:.12f}" for v in err[i, 3:])
        lines.append(f"{x + x0_mm:.4f} {lin} {ang}")
    return "\n".join(lines) + "\n"


def _equidistant_step(x_mm):
    d = np.diff(x_mm)
    if len(x_mm) < 2 or not np.allclose(d, d[0], rtol=0, atol=1e-6):
        raise ValueError("a Siemens CEC table needs equidistant positions")
    return float(d[0])


def _siemens(x_mm, err, x0_mm, point, source):
    step = _equidistant_step(x_mm)
    out = ["%_N_NC_CEC_INI", "CHANDATA(1)"]
    out += [
        f"; {h}"
        for h in _header_lines(
            point, source, x0_mm, "values: compensation = -error (added to the output axis), mm"
        )
    ]
    for t, (k, axis) in enumerate(((1, "AX2"), (2, "AX3"))):
        out.append(f"; table {t}: -{ERROR_NAMES[k]} on {axis} as a function of AX1 (X)")
        for i in range(len(x_mm)):
            out.append(f"$AN_CEC[{t},{i}]={-err[i, k] * 1e3:.6f}")
        out += [
            f"$AN_CEC_INPUT_AXIS[{t}]=(AX1)",
            f"$AN_CEC_OUTPUT_AXIS[{t}]=({axis})",
            f"$AN_CEC_STEP[{t}]={step:.4f}",
            f"$AN_CEC_MIN[{t}]={x_mm[0] + x0_mm:.4f}",
            f"$AN_CEC_MAX[{t}]={x_mm[-1] + x0_mm:.4f}",
            f"$AN_CEC_DIRECTION[{t}]=0",
            f"$AN_CEC_MULT_BY_TABLE[{t}]=0",
            f"$AN_CEC_IS_MODULO[{t}]=0",
        ]
    out.append("M17")
    return "\n".join(out) + "\n"


def _heidenhain(x_mm, err, x0_mm, point, source, name="X_ISO230"):
    head = _header_lines(
        point,
        source,
        x0_mm,
        "values: compensation = -error; X, EXX, EYX, EZX in mm, EAX, EBX, ECX in degrees",
    )
    cols = ("NR", "X", "EXX", "EYX", "EZX", "EAX", "EBX", "ECX")
    widths = (5, 12, 13, 13, 13, 15, 15, 15)
    lines = [f"BEGIN {name}.COM MM", "".join(c.ljust(w) for c, w in zip(cols, widths)).rstrip()]
    for i, x in enumerate(x_mm):
        vals = [f"{i}", f"{x + x0_mm:+.4f}"]
        vals += [f"{-v * 1e3:+.7f}" for v in err[i, :3]]
        vals += [f"{np.degrees(-v):+.10f}" for v in err[i, 3:]]
        lines.append("".join(v.ljust(w) for v, w in zip(vals, widths)).rstrip())
    lines.append("[END]")
    # comments are not part of the TNC table syntax: the header goes into a companion note
    return "\n".join(lines) + "\n", "\n".join(head) + "\n"


def _fanuc(x_mm, err, x0_mm, point, source, detection_unit_mm):
    step = _equidistant_step(x_mm)
    ref = int(np.argmin(np.abs(x_mm)))
    du = detection_unit_mm
    out = ["%", f"(DIFFGUIDE FANUC-STYLE COMPENSATION, POINT {point})"]
    out += [
        f"({h.upper().replace('(', '').replace(')', '')})"
        for h in _header_lines(
            point,
            source,
            x0_mm,
            "values: incremental compensation = change of -error from the previous point",
        )
    ]
    out.append(f"(DETECTION UNIT {du:g} MM, INTERVAL {step:g} MM = {round(step / du)} UNITS)")
    out.append(f"(REFERENCE POINT X = {x_mm[ref] + x0_mm:.4f} MM)")
    for base, k, what in (
        (10000, 0, "PITCH EXX ON X"),
        (20000, 1, "STRAIGHTNESS EYX ON Y"),
        (30000, 2, "STRAIGHTNESS EZX ON Z"),
    ):
        absolute = np.round(-(err[:, k] - err[ref, k]) * 1e3 / du).astype(int)
        inc = np.diff(absolute, prepend=absolute[0])
        n_ref = base + ref
        out.append(
            f"({what}: REFERENCE NO. {n_ref} (3620), MOST NEGATIVE NO. {base} (3621), "
            f"MOST POSITIVE NO. {base + len(x_mm) - 1} (3622), INTERVAL "
            f"{round(step / du)} (3624))"
        )
        for i in range(len(x_mm)):
            out.append(f"N{base + i} P{inc[i]}")
    out.append("%")
    return "\n".join(out) + "\n"


def export_compensation(
    fmt: str,
    x_mm,
    errors,
    sigma=None,
    *,
    x0_mm: float = 0.0,
    point: str = "P",
    source: str = "",
    detection_unit_mm: float = 0.001,
) -> dict[str, str]:
    """The files of a compensation export: ``{suffix: text}``, ``""`` the table itself,
    ``".sigma.csv"`` the σ companion (formats without room for σ, when ``sigma`` is given),
    ``".note.txt"`` a note (Heidenhain: the table syntax has no comments). See the module
    docstring.
    """
    x_mm = np.asarray(x_mm, float)
    err = np.asarray(errors, float)
    sig = None if sigma is None else np.asarray(sigma, float)
    if err.shape != (len(x_mm), 6) or (sig is not None and sig.shape != err.shape):
        raise ValueError("errors (and sigma) must have shape (n_positions, 6)")
    if fmt not in FORMATS:
        raise ValueError(f"--format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    if fmt == "csv":
        return {"": _csv(x_mm, err, sig, x0_mm, point, source)}
    if fmt == "isg":
        files = {"": _isg(x_mm, err, x0_mm, point, source)}
    elif fmt == "siemens-cec":
        files = {"": _siemens(x_mm, err, x0_mm, point, source)}
    elif fmt == "heidenhain":
        table, note = _heidenhain(x_mm, err, x0_mm, point, source)
        files = {"": table, ".note.txt": note}
    else:
        files = {"": _fanuc(x_mm, err, x0_mm, point, source, detection_unit_mm)}
    if sig is not None:
        files[".sigma.csv"] = sigma_csv(x_mm, sig, x0_mm, point)
    return files
