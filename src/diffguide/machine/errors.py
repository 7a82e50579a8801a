"""The six joint errors of the X axis (ISO 230-1): names, meanings and units, one table.

Inside, joint errors are SI: m for EXX, EYX, EZX; rad for EAX, EBX, ECX, in the order of
:data:`ERROR_NAMES` (the last axis of :attr:`~diffguide.machine.kinematics.JointErrors.errors`).
Files, plots and the CLI show them in µm and µrad (= µm/m); file columns carry the unit in ASCII
(``EXX_um``, ``EAX_urad``), plots in Unicode (``µm``, ``µrad``).
"""

from typing import NamedTuple

import numpy as np

#: ISO 230-1 names of the six joint errors of the X axis, in the order of the last axis of
#: ``JointErrors.errors`` (SI: m for the first three, rad for the last three).
ERROR_NAMES = ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX")
#: What each error is.
ERROR_MEANINGS = (
    "positioning",
    "horizontal straightness",
    "vertical straightness",
    "roll",
    "pitch",
    "yaw",
)


class ErrorUnit(NamedTuple):
    """One joint error at the edge: ISO name, meaning, unit in files (ASCII), unit in plots,
    and the factor from SI to that unit."""

    name: str
    meaning: str
    unit: str
    label: str
    scale: float


#: SI -> user unit for translations (m -> µm) and rotations (rad -> µrad = µm/m).
_TRANSLATION = ("um", "µm", 1e6)
_ROTATION = ("urad", "µrad", 1e6)

#: The six joint errors in the order of ``JointErrors.errors[..., k]``.
ERRORS: tuple[ErrorUnit, ...] = tuple(
    ErrorUnit(name, meaning, *(_TRANSLATION if k < 3 else _ROTATION))
    for k, (name, meaning) in enumerate(zip(ERROR_NAMES, ERROR_MEANINGS))
)
#: ASCII units of the six errors, as in file columns: ``("um", "um", "um", "urad", ...)``.
ERROR_UNITS: tuple[str, ...] = tuple(e.unit for e in ERRORS)
#: ``(name, unit label, meaning)`` of the six errors, for figures.
ERROR_LABELS: tuple[tuple[str, str, str], ...] = tuple((e.name, e.label, e.meaning) for e in ERRORS)
#: SI -> user units, one factor per error (broadcasts over ``(..., 6)``).
USER_SCALE = np.array([e.scale for e in ERRORS])


def error_columns(suffix: str = "") -> tuple[str, ...]:
    """File column names ``EXX_um … ECX_urad`` (``suffix`` appended to each name)."""
    return tuple(f"{e.name}{suffix}_{e.unit}" for e in ERRORS)


def to_user(errors) -> np.ndarray:
    """Joint errors ``(..., 6)`` from SI to µm / µrad (NumPy)."""
    return np.asarray(errors) * USER_SCALE
