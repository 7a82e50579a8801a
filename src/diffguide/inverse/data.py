"""The measurement data the identification works on (no file format here: reading and
validation of measurement files live in :mod:`diffguide.io.measurements`, the merging of their
readings in :mod:`.merge`).

:class:`Reading` is one validated reading (SI units); :class:`Measurements` holds one row per
(position, point, quantity, instrument), SI units (m, rad): the merged value, its standard
uncertainty, and what the merge saw (readings, reversal).
"""

import dataclasses

import numpy as np

#: The six joint kinematic errors of the X axis (ISO 230-1), the order of
#: :data:`diffguide.machine.kinematics.ERROR_NAMES`.
QUANTITIES = ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX")
#: The linear ones (m); the others are angles (rad).
LINEAR = ("EXX", "EYX", "EZX")


def default_instrument(quantity: str) -> str:
    """``"level"`` for roll and pitch (EAX, EBX), ``"interferometer"`` otherwise (only an
    interferometer measures yaw and the linear errors)."""
    return "level" if quantity in ("EAX", "EBX") else "interferometer"


@dataclasses.dataclass(frozen=True)
class Reading:
    """One validated row of a measurement file (SI units; ``line`` is its line number)."""

    line: int
    position: float
    point: str
    xy: tuple[float, float]
    quantity: str
    value: float
    unit: str
    sigma: float | None
    run: str
    direction: str  # "forward" or "backward"
    instrument: str
    z: float = 0.0  # height of the sensing point above the table top (m)
    #: standard uncertainty of the rounding of the value as written (SI; ``q/√12``, ``q`` a unit
    #: of its last digit; a differential pair's two roundings in quadrature; 0: unknown)
    resolution: float = 0.0
    #: the file it was read from (several files merged into one data set; "" when one)
    source: str = ""


@dataclasses.dataclass(frozen=True, repr=False)
class Measurements:
    """Merged measurements: one row per (position, point, quantity), SI units.

    Attributes:
        point_names: the control points, in order of first appearance.
        points_xy: their (x, y) on the table top, ``(p, 2)`` (m).
        position: table position of each row (m). point: index into ``point_names``.
        quantity: index into :data:`QUANTITIES`. value: merged value (m or rad).
        sigma: standard uncertainty of ``value`` (m or rad), > 0.
        n_readings: readings merged into the row. reversal: forward − backward mean (NaN when
            the row is not bidirectional). instrument: per row.
        sigma_source: per row, ``"column"``, ``"scatter"``, ``"floor"`` (the scatter raised to
            its floor: rounding or a tenth of the default) or ``"default"``; joined with
            ``copies`` (``"copies+default"``, ``"column+copies"``) where the runs are identical
            at every position and were merged as one run.
        z: per row, height of the sensing point above the table top (m).
        readings: the validated input rows (empty when built from arrays). row_of_reading:
            the merged row of each reading (−1 for a rejected outlier).
        rejected: line numbers of the readings set aside as gross outliers.
        source: file name (for messages).
    """

    point_names: tuple[str, ...]
    points_xy: np.ndarray
    position: np.ndarray
    point: np.ndarray
    quantity: np.ndarray
    value: np.ndarray
    sigma: np.ndarray
    n_readings: np.ndarray
    reversal: np.ndarray
    instrument: tuple[str, ...]
    sigma_source: tuple[str, ...]
    z: np.ndarray | None = None
    readings: tuple = ()
    row_of_reading: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, int))
    rejected: tuple[int, ...] = ()
    source: str = "<arrays>"

    def __post_init__(self):
        n = len(self.position)
        if self.z is None:
            object.__setattr__(self, "z", np.zeros(n))
        for name in ("point", "quantity", "value", "sigma", "n_readings", "reversal", "z"):
            if np.shape(getattr(self, name)) != (n,):
                got = np.shape(getattr(self, name))
                raise ValueError(f"{name} must have shape ({n},), got {got}")
        if len(self.instrument) != n or len(self.sigma_source) != n:
            raise ValueError("instrument and sigma_source need one entry per row")
        if np.shape(self.points_xy) != (len(self.point_names), 2):
            raise ValueError("points_xy must have shape (n_points, 2)")
        if n == 0:
            raise ValueError("no measurements")
        if not (np.all(np.isfinite(self.value)) and np.all(np.isfinite(self.position))):
            raise ValueError("values and positions must be finite")
        if not np.all(np.asarray(self.sigma) > 0):
            raise ValueError("sigma must be > 0")

    def __repr__(self) -> str:
        """One line: rows, channels, distinct positions (range in mm), points, readings, source
        (the arrays themselves are attributes; the full dataclass repr ran to ~800 kB)."""
        pos = np.unique(np.asarray(self.position, float))
        span = f"{pos[0] * 1e3:g}..{pos[-1] * 1e3:g} mm"
        extra = f", rejected={len(self.rejected)}" if self.rejected else ""
        return (
            f"Measurements(rows={self.n}, channels={len(self.channels)}, "
            f"positions={len(pos)} ({span}), points={self.point_names!r}, "
            f"readings={len(self.readings)}{extra}, source={self.source!r})"
        )

    @property
    def n(self) -> int:
        return len(self.position)

    @property
    def channels(self) -> list[tuple[int, int, str]]:
        """The (point, quantity, instrument) triples present, sorted: each has its own zero."""
        return sorted(set(self._keys()))

    def _keys(self):
        return [(int(p), int(q), i) for p, q, i in zip(self.point, self.quantity, self.instrument)]

    def channel_index(self) -> np.ndarray:
        """Index of each row's channel in :attr:`channels`."""
        lookup = {c: k for k, c in enumerate(self.channels)}
        return np.array([lookup[k] for k in self._keys()], int)

    def channel_label(self, c: int) -> str:
        """``"EBX at P1 (level)"`` for channel ``c``."""
        p, q, inst = self.channels[c]
        return f"{QUANTITIES[q]} at {self.point_names[p]} ({inst})"

    def with_values(self, value, sigma=None) -> "Measurements":
        """The same rows with other values (and σ), e.g. synthetic noise (SI)."""
        sigma = self.sigma if sigma is None else np.broadcast_to(sigma, (self.n,)).astype(float)
        return dataclasses.replace(
            self,
            value=np.asarray(value, float),
            sigma=np.asarray(sigma),
            readings=(),
            row_of_reading=np.zeros(0, int),
        )

    @classmethod
    def from_arrays(
        cls,
        points: dict[str, tuple[float, float]],
        position,
        point,
        quantity,
        value,
        sigma,
        instrument=None,
        z=None,
    ) -> "Measurements":
        """Merged rows from arrays (SI): ``point`` names, ``quantity`` names, one row each;
        ``z`` the sensing height above the table top (m, default 0)."""
        names = tuple(points)
        pidx = np.array([names.index(p) for p in point])
        qidx = np.array([QUANTITIES.index(q) for q in quantity])
        n = len(pidx)
        inst = (
            tuple(instrument)
            if instrument is not None
            else tuple(default_instrument(QUANTITIES[q]) for q in qidx)
        )
        return cls(
            names,
            np.array([points[k] for k in names], float),
            np.asarray(position, float),
            pidx,
            qidx,
            np.asarray(value, float),
            np.broadcast_to(sigma, (n,)).astype(float),
            np.ones(n, int),
            np.full(n, np.nan),
            inst,
            ("column",) * n,
            z=None if z is None else np.broadcast_to(z, (n,)).astype(float),
        )
