"""Parameter checks that run on concrete values and stand aside for traced ones (inside
``jit``/``vmap``/``grad``, where the caller's concrete inputs were already checked).

The public entry points check their arguments as a machine file's keys are checked: a length in
metres within a plausible range (with a hint when the value looks like millimetres typed as
metres), an integer that must be positive, an object of the expected type (with what to pass
instead). Every message names the argument, the value and what is allowed.
"""

import math
import numbers

import jax
import numpy as np


def concrete(*values) -> bool:
    """Whether the values can be checked now (none is a JAX tracer)."""
    return not any(isinstance(v, jax.core.Tracer) for v in values)


def mm_hint(value: float, lo: float, hi: float) -> str:
    """``": did you mean 48 mm = 0.048 m?"`` when ``value`` (m) read as millimetres lies in
    ``[lo, hi]`` (m); ``""`` otherwise."""
    if np.isfinite(value) and lo <= value * 1e-3 <= hi:
        return f": did you mean {value:g} mm = {value * 1e-3:g} m?"
    return ""


def length(name: str, value, lo: float, hi: float):
    """``value`` (m), refused with a ``ValueError`` naming ``name`` unless finite and within
    ``[lo, hi]`` (m) — a scalar or an array (every element checked). A traced value is
    returned unchecked.

    The message gives the value, the allowed range in m and, when the value read as
    millimetres would be allowed, the conversion (``"48 m: did you mean 48 mm = 0.048 m?"``).
    """
    if not concrete(value) or value is None:
        return value
    arr = np.asarray(value, dtype=float)
    bad = arr[~(np.isfinite(arr) & (arr >= lo) & (arr <= hi))]
    if bad.size:
        v = float(bad.flat[0])
        what = "a finite length" if not np.isfinite(v) else "a length"
        raise ValueError(
            f"{name} must be {what} in metres within [{lo:g}, {hi:g}] m, got {v:g} m"
            + mm_hint(v, lo, hi)
        )
    return value


def positive_int(name: str, value, minimum: int = 1) -> int:
    """``value`` as an ``int``, refused (``ValueError``, ``TypeError`` for a non-number) unless
    an integer ``>= minimum``; the message names ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real | np.integer):
        raise TypeError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if not (math.isfinite(value) and int(value) == value and value >= minimum):
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def instance(name: str, value, cls: type, hint: str):
    """``value`` unchanged if it is a ``cls``; otherwise a ``TypeError`` naming ``name``, the
    type received and ``hint`` (what to pass instead)."""
    if not isinstance(value, cls):
        got = type(value).__name__
        if isinstance(value, str | bytes) or hasattr(value, "__fspath__"):
            got += f" {str(value)!r}"
        raise TypeError(f"{name} must be {cls.__name__}, got {got}; {hint}")
    return value
