"""What a measurement plan places: instrument types, what each reads, and candidate sites.

A *placement* is ``(instrument kind, site name)``; a site is a point ``(x, y)`` (m) on the table
top. :mod:`.plan` chooses placements; :mod:`diffguide.io.plan_files` reads them from files.
"""

import dataclasses

import numpy as np

#: Instrument kinds and the quantities each can read.
KINDS = {
    "level": ("EBX", "EAX"),
    "interferometer": ("EBX", "ECX"),
    "straightness": ("EYX", "EZX"),
}
#: σ of one reading per kind (rad for the angular kinds, m for straightness): the defaults of
#: :mod:`diffguide.inverse.merge` (4 µm/m levels, 2 µm/m interferometer, 1 µm straightness).
DEFAULT_READING_SIGMA = {"level": 4e-6, "interferometer": 2e-6, "straightness": 1e-6}

Placement = tuple[str, str]  # (instrument kind, site name)


@dataclasses.dataclass(frozen=True)
class Instrument:
    """An instrument type available for the plan.

    Attributes:
        kind: ``"level"``, ``"interferometer"`` (angular) or ``"straightness"`` (optics).
        count: how many can be placed (the greedy budget), >= 0.
        quantities: what one placement reads (a subset of :data:`KINDS` ``[kind]``; default
            all of them, e.g. a two-axis level reads pitch EBX and roll EAX).
        sigma: σ of one reading (rad, or m for straightness); default
            :data:`DEFAULT_READING_SIGMA`.
    """

    kind: str
    count: int = 1
    quantities: tuple[str, ...] | None = None
    sigma: float | None = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"instrument kind must be one of {tuple(KINDS)}, got {self.kind!r}")
        if self.quantities is None:
            object.__setattr__(self, "quantities", KINDS[self.kind])
        q = tuple(self.quantities)
        object.__setattr__(self, "quantities", q)
        bad = [x for x in q if x not in KINDS[self.kind]]
        if not q or bad or len(set(q)) != len(q):
            raise ValueError(f"a {self.kind} reads {' and/or '.join(KINDS[self.kind])}, got {q!r}")
        if self.sigma is None:
            object.__setattr__(self, "sigma", DEFAULT_READING_SIGMA[self.kind])
        if not (np.isfinite(self.sigma) and self.sigma > 0):
            raise ValueError(f"{self.kind}: the reading sigma must be > 0, got {self.sigma!r}")
        if int(self.count) != self.count or self.count < 0:
            raise ValueError(f"{self.kind}: count must be an integer >= 0, got {self.count!r}")


def grid_sites(length: float, width: float, nx: int, ny: int, margin: float = 0.05) -> dict:
    """``nx × ny`` candidate sites ``{"G<i>_<j>": (x, y)}`` (m) evenly over the table top
    ``length × width`` (m) centred on the origin, ``margin`` (m) from the edges."""
    if nx < 1 or ny < 1:
        raise ValueError(f"the site grid needs nx, ny >= 1, got {nx} x {ny}")
    xs = np.linspace(-length / 2 + margin, length / 2 - margin, nx) if nx > 1 else [0.0]
    ys = np.linspace(-width / 2 + margin, width / 2 - margin, ny) if ny > 1 else [0.0]
    return {
        f"G{i + 1}_{j + 1}": (float(np.round(x, 12)) + 0.0, float(np.round(y, 12)) + 0.0)
        for i, x in enumerate(xs)
        for j, y in enumerate(ys)
    }


def bundled_layout_mm(length_mm: float, width_mm: float) -> list[tuple[str, float, float]]:
    """The bundled data set's layout on a ``length_mm × width_mm`` table, as ``(kind, x_mm,
    y_mm)``: a two-axis level at each corner 50 mm inside the edges, an angular interferometer
    at the centre."""
    hx, hy = length_mm / 2 - 50, width_mm / 2 - 50
    rows = [("level", x, y) for x, y in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy))]
    rows.append(("interferometer", 0.0, 0.0))
    return rows


def check_on_table(name: str, x_mm: float, y_mm: float, table_mm, where: str) -> None:
    """Refuse a site ``(x_mm, y_mm)`` (mm from the table centre) off a ``table_mm = (length,
    width)`` (mm) table top; ``where`` starts the message (a file and line, an option)."""
    half_l, half_w = table_mm[0] / 2, table_mm[1] / 2
    if abs(x_mm) > half_l or abs(y_mm) > half_w:
        raise ValueError(
            f"{where}: site {name!r} at ({x_mm:g}, {y_mm:g}) mm is off the table "
            f"(|x| <= {half_l:g}, |y| <= {half_w:g} mm)"
        )


def place_on_sites(rows, sites: dict, what: str) -> list[Placement]:
    """``(kind, x_mm, y_mm)`` rows as placements ``(kind, site)``: a row at a site of ``sites``
    (``{name: (x, y)}``, m; to 1 nm) takes its name, any other adds a site ``U<k>`` to
    ``sites``. The same kind twice on one site is refused; ``what`` names the plan in the
    message."""
    out = []
    for kind, x, y in rows:
        name = next(
            (
                n
                for n, (sx, sy) in sites.items()
                if abs(sx * 1e3 - x) < 1e-6 and abs(sy * 1e3 - y) < 1e-6
            ),
            None,
        )
        if name is None:
            name = f"U{len([n for n in sites if n.startswith('U')]) + 1}"
            sites[name] = (x * 1e-3, y * 1e-3)
        out.append((kind, name))
    if len(set(out)) != len(out):
        raise ValueError(f"{what}: the same instrument twice on one site")
    return out


__all__ = [
    "DEFAULT_READING_SIGMA",
    "KINDS",
    "Instrument",
    "Placement",
    "bundled_layout_mm",
    "check_on_table",
    "grid_sites",
    "place_on_sites",
]
