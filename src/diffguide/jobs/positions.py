"""Table positions of the sweeping jobs (``simulate``, ``predict``, ``montecarlo``,
``tolerance``, ``design``): ``START:STOP:COUNT`` (mm) read into metres, the machine's whole
stroke, and the check that a sweep stays within the stroke. Nothing heavy imported."""

import numpy as np

from .._core.limits import MAX_MESH_DIVISIONS, MAX_POSITIONS, check_range


def parse_positions(text: str) -> np.ndarray:
    """``START:STOP:COUNT`` (mm, inclusive) → positions (m); ``ValueError`` naming
    ``--positions`` for a malformed or too long range."""
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


def stroke_positions(cfg: dict, text: str | None, name: str | None = None) -> np.ndarray:
    """The swept positions (m): ``text`` (``START:STOP:COUNT``, mm) or the whole stroke at 71
    positions; ``ValueError`` where they leave the ±stroke/2 of ``cfg`` (``name``: the
    machine, named in the message)."""
    positions = default_positions(cfg) if text is None else parse_positions(text)
    half = cfg["machine"]["stroke_mm"] / 2
    if np.max(np.abs(positions)) * 1e3 > half + 1e-9:
        of = f" of {name}" if name else ""
        raise ValueError(f"--positions must lie within the ±{half:g} mm stroke{of}, got {text!r}")
    return positions


def parse_mesh(text: str, most: int = MAX_MESH_DIVISIONS) -> tuple[int, int]:
    """``"20x10"`` → ``(20, 10)``, each in ``1..most``; a clear ``ValueError`` otherwise."""
    parts = str(text).lower().replace("×", "x").split("x")
    try:
        nx, ny = (int(v) for v in parts)
    except ValueError:
        raise ValueError(f"--mesh must be NXxNY with integers, e.g. 20x10, got {text!r}") from None
    if not (1 <= nx <= most and 1 <= ny <= most):
        raise ValueError(f"--mesh: both divisions must be in 1..{most}, got {text!r}")
    return nx, ny


def settle_mesh(s) -> None:
    """A frozen settings object's mesh: ``nx``/``ny`` from its ``mesh`` text where only the
    text is given, and the divisions checked."""
    if s.mesh is not None and s.nx is None and s.ny is None:
        nx, ny = parse_mesh(s.mesh)
        object.__setattr__(s, "nx", nx)
        object.__setattr__(s, "ny", ny)
    check_mesh(s.nx, s.ny)


def check_mesh(nx: int | None, ny: int | None) -> None:
    """``--mesh``'s divisions (``None``: the machine's own), each in 1..MAX_MESH_DIVISIONS."""
    for v in (nx, ny):
        if v is not None and not (isinstance(v, int) and 1 <= v <= MAX_MESH_DIVISIONS):
            raise ValueError(f"--mesh: both divisions must be in 1..{MAX_MESH_DIVISIONS}, "
                             f"got {nx}x{ny}")
