"""FANUC pitch error compensation of X (EXX), as a setting sheet for parameters 3620–3624.

Parameters from the FANUC *Series 0i-PB Parameter Manual* B-63980EN/01, "Description of
parameters", pitch error compensation (p. 100 and around), and the FANUC technical report
A-77810E "Series 16i/18i-MA/TA bidirectional pitch error compensation" (May 2000), section 2:

- 3620: number of the compensation point of the reference position;
- 3621 / 3622: numbers of the farthest points on the − / + side;
- 3623: magnification (the values are multiplied by it);
- 3624: interval of the compensation points (detection units);
- (3625: travel per revolution, rotary axes; 3626/3627: bidirectional compensation — unused).

Compensation point ``n`` sits at ``X_ref + (n − n_ref) × interval``; its value is the
*increment* of the compensation over the section from point ``n − 1`` to point ``n`` (the
rotary example of the parameter manual: the reference point's value equals the last section's),
in detection units × magnification; the compensation is zero at the reference position. Values
are ``C = −EXX`` (X carries the workpiece; :mod:`._common`).

**Experimental:** the numbers and values are written as a sheet to enter on the parameter
screen, not as a punch tape: the tape numbering of the pitch data could not be confirmed.
Straightness compensation (EYX, EZX) is not written: its parameters could not be confirmed from
documentation.
"""

import numpy as np

from ._common import FANUC_COMMENT, equidistant_step, header_lines, lead_line
from .settings import INCREMENT_SYSTEMS

EXPERIMENTAL = ("a setting sheet for the parameter screen, not a punch tape (the tape numbering "
                "of pitch data was not confirmed)")
MAX_VALUE = 127  # the documented range of one pitch value is -128..127 (× magnification)


def _unit_name(du: float) -> str:
    names = [k for k, v in INCREMENT_SYSTEMS.items() if abs(v - du) <= 1e-12]
    return f"{names[0]} with CMR 1" if names else "a length"


def write(x_mm, err, *, x0_mm, point, source, spec, exx_includes_lead,
          straightness_note=None) -> dict[str, str]:
    if exx_includes_lead is None:
        raise ValueError(f"fanuc (pitch error compensation of X): {lead_line(None)}")
    step = equidistant_step(x_mm, "fanuc")
    du = spec.detection_unit_mm
    X = np.asarray(x_mm) + x0_mm
    x_ref = x0_mm if spec.reference_mm is None else float(spec.reference_mm)
    k = (X - x_ref) / step
    i_ref = int(np.argmin(np.abs(k)))
    if abs(k[i_ref]) > 1e-6 or abs(k[i_ref] - round(k[i_ref])) > 1e-6:
        raise ValueError(f"fanuc: the reference position X = {x_ref:g} mm must be one of the "
                         f"table's positions ({X[0]:g} to {X[-1]:g} mm, every {step:g} mm)")
    interval = step / du
    if abs(interval - round(interval)) > 1e-6:
        raise ValueError(f"fanuc: the interval {step:g} mm is not a whole number of detection "
                         f"units ({du:g} mm)")
    comp = -(err[:, 0] - err[i_ref, 0]) * 1e3  # mm, zero at the reference position
    mag = max(1, int(np.ceil(np.max(np.abs(np.diff(comp))) / du / MAX_VALUE)))
    absolute = np.round(comp / (du * mag)).astype(int)
    inc = np.diff(absolute, prepend=absolute[0])  # value of point n: from n-1 to n
    numbers = spec.first_number + np.arange(len(X))
    n_ref = int(numbers[i_ref])
    if numbers[0] < 0 or numbers[-1] > 1023:
        raise ValueError(f"fanuc: point numbers {numbers[0]}..{numbers[-1]} outside 0..1023")
    head = header_lines(point, source, x0_mm, "values: increments of the compensation -EXX "
                        "from the previous point, detection units x magnification",
                        exx_includes_lead)
    head += [f"EXPERIMENTAL: {EXPERIMENTAL}",
             f"REFERENCE POINT X = {x_ref:.4f} MM (the reference position of the axis)",
             f"detection unit {du:g} mm ({_unit_name(du)}; CLI --fanuc-detection-unit, "
             "[export] fanuc_detection_unit): it must be the axis' detection unit (least "
             "command increment / CMR), else every value is off by their ratio",
             "straightness (EYX, EZX) not written",
             "parameters of the X axis (enter on the parameter screen, then power off/on):",
             f"3620 = {n_ref}   (compensation point of the reference position)",
             f"3621 = {numbers[0]}   (farthest point, - side)",
             f"3622 = {numbers[-1]}   (farthest point, + side)",
             f"3623 = {mag}   (magnification)",
             f"3624 = {round(interval)}   (interval, detection units = {step:g} mm)",
             "pitch error compensation data: point number, X (mm), value"]
    out = FANUC_COMMENT.lines(head)
    out += [f"{n} {x:.4f} {v}" for n, x, v in zip(numbers, X, inc)]
    return {"": "\n".join(out) + "\n"}
