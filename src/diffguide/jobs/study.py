"""The random-rail study's settings shared by the jobs that draw random rails (``design``; the
``montecarlo`` and ``tolerance`` commands have the same options): the rails' model, the swept
positions, the batching, each checked with a ``ValueError`` naming the option."""

import math

import numpy as np

from .._core.limits import MAX_POSITIONS, check_range

#: ``--kernel`` -> the covariance of :class:`diffguide.studies.random_rails.GaussianRailModel`.
KERNELS = {"se": "squared_exponential", "matern52": "matern52"}
#: ``--planes`` -> the planes with straightness error.
PLANES = {
    "both": ("vertical", "horizontal"),
    "vertical": ("vertical",),
    "horizontal": ("horizontal",),
}
#: diffguide.studies.random_rails.MOUNTING_CLASSES, named here so that no JAX is imported
#: (tests/test_cli_common.py checks they agree)
MOUNTING_CHOICES = ("none", "precision", "size25-ZB", "size25-ZA", "size25-ZO")


def check_study(s) -> None:
    """Range checks of the study options of ``s`` (``corr_mm``, ``kernel``, ``planes``,
    ``mounting``, ``chunk``, ``cpu_devices``; ``ValueError`` naming the flag)."""
    if not (math.isfinite(s.corr_mm) and 1 <= s.corr_mm <= 1e5):
        raise ValueError(f"--corr-mm must be in 1..100000 mm, got {s.corr_mm}")
    for flag, value, allowed in (("--kernel", s.kernel, KERNELS), ("--planes", s.planes, PLANES),
                                 ("--mounting", s.mounting, MOUNTING_CHOICES)):
        if value not in allowed:
            raise ValueError(f"{flag} must be one of {', '.join(allowed)}, got {value!r}")
    if s.chunk is not None and not 1 <= s.chunk <= 100_000:
        raise ValueError(f"--chunk must be in 1..100000, got {s.chunk}")
    if s.cpu_devices is not None and not 1 <= s.cpu_devices <= 256:
        raise ValueError(f"--cpu-devices must be in 1..256, got {s.cpu_devices}")


def parse_positions(text: str) -> np.ndarray:
    """``START:STOP:COUNT`` (mm, inclusive) → positions (m)."""
    parts = text.split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise ValueError(
            f"--positions must be START:STOP:COUNT in mm (e.g. -350:350:71), got {text!r}"
        ) from None
    if count < 2 or not np.isfinite(start) or not np.isfinite(stop) or stop <= start:
        raise ValueError(f"--positions needs STOP > START and COUNT >= 2, got {text!r}")
    check_range(count, 2, MAX_POSITIONS, f"--positions {text}: COUNT",
                "about 10 kB of memory and 20 ms per position")
    return np.linspace(start, stop, count) * 1e-3


def default_positions(cfg: dict, count: int = 71) -> np.ndarray:
    """``count`` positions (m) over the whole stroke of the machine configuration ``cfg``."""
    half = cfg["machine"]["stroke_mm"] / 2e3
    return np.linspace(-half, half, count)
