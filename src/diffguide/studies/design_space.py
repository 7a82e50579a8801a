r"""What a design study may vary, and what it may constrain: one table entry per traced variable
and per constraint, so that a newly traceable field of the specification (rail spacing, a rib
depth) is one more entry.

**Variables** (:data:`VARIABLES`): a field of :class:`~diffguide.machine.spec.MachineSpec` that
:func:`~diffguide.machine.build.build_machine` accepts traced, with how to set it, its user unit
and its default bounds:

============================  ======  ================================================
``thickness``                 mm      the plate's equivalent thickness; default ½..2 × the machine's
``carriage_spacing``          mm      distance between the two carriages of a rail; default: the
                                      range where the mesh keeps its topology
                                      (:func:`carriage_spacing_range`)
``rail_spacing``              mm      distance between the two rails; default: the range where the
                                      mesh keeps its topology (:func:`rail_spacing_range`)
``preload_fraction``          %       preload as a fraction of the capacity C; default 1 .. 13 %
``E``                         GPa     the table's Young's modulus; default ½..2 × the machine's
============================  ======  ================================================

**Constraints** (:data:`CONSTRAINTS`), each a function of the specification (SI), traced:

- ``mass``: the table's mass ``ρ·L·W·t`` (kg; the plate's volume × density — ribs, where a
  machine has them, are not counted);
- ``preload``: the total preload force ``n_c·f·C`` of the ``n_c`` carriages (N);
- ``spacing``: the carriage spacing less the room on the table, ``s − (L − b)`` (m; ``b`` the
  carriage footprint's length): ``spacing<=0`` keeps the carriages under the table;
- ``rail_length``: the rail length the stroke needs, ``S + s + b`` (m; ``S`` the stroke):
  ``rail_length<=L`` keeps both carriages of a rail on rails of length ``L`` over the stroke.
"""

import dataclasses
from collections.abc import Callable

import jax.numpy as jnp
import numpy as np

from ..machine.build import layout_ranges, with_overrides
from ..machine.spec import MachineSpec

#: The gap (m) a moved footprint line keeps from the next fixed grid line at the ends of
#: :func:`carriage_spacing_range`: no degenerate (zero-length) element.
MIN_GAP = 1e-3


@dataclasses.dataclass(frozen=True)
class Variable:
    """A traced design variable: ``name`` (a :func:`~diffguide.machine.build.with_overrides`
    keyword), its ``unit`` and ``scale`` (SI per user unit), ``value(spec)`` its current value
    (SI) and ``bounds(spec)`` its default bounds (SI)."""

    name: str
    unit: str
    scale: float
    value: Callable[[MachineSpec], float]
    bounds: Callable[[MachineSpec], tuple[float, float]]
    what: str

    def apply(self, spec: MachineSpec, x) -> MachineSpec:
        """``spec`` with this variable set to ``x`` (SI; may be traced)."""
        return with_overrides(spec, **{self.name: x})


def carriage_spacing_of(spec: MachineSpec):
    """The carriage spacing (m; may be traced): the traced ``carriage_spacing`` where set,
    else the configuration's ``carriage_x`` difference."""
    s = spec.guideway.carriage_spacing
    cx = spec.guideway.carriage_x
    return cx[1] - cx[0] if s is None else s


def _spacing(spec: MachineSpec) -> float:
    return float(carriage_spacing_of(spec))


def _layout_range(spec: MachineSpec, name: str) -> tuple[float, float]:
    """The range (m) of the traced layout variable ``name`` on ``spec``'s mesh
    (:func:`~diffguide.machine.build.layout_ranges`), :data:`MIN_GAP` inside each open end:
    no degenerate (zero-length) element at a bound."""
    rng = layout_ranges(spec)[name]
    if rng is None:
        raise ValueError(f"{name} cannot be varied on this machine's layout (a footprint on the "
                         "table edge or sharing a grid line with one it does not move)")
    lo, hi = rng
    return float(lo + MIN_GAP), float(hi - MIN_GAP)


def carriage_spacing_range(spec: MachineSpec) -> tuple[float, float]:
    """The carriage spacings (m) a traced ``carriage_spacing`` reaches on ``spec``'s mesh.

    :func:`~diffguide.machine.build.build_machine` moves each carriage's footprint lines (edges
    and centre) with the carriage and keeps every other grid line; the spacing is valid while
    the lines keep their order (:func:`~diffguide.machine.build.layout_ranges`). The range is
    that, :data:`MIN_GAP` inside each end, and the carriages of a rail do not overlap."""
    lo, hi = _layout_range(spec, "carriage_spacing")
    return max(lo, float(spec.guideway.footprint[0]) + MIN_GAP), hi


def rail_spacing_range(spec: MachineSpec) -> tuple[float, float]:
    """The rail spacings (m) a traced ``rail_spacing`` reaches on ``spec``'s mesh (as
    :func:`carriage_spacing_range`; the footprints of the two rails do not overlap)."""
    lo, hi = _layout_range(spec, "rail_spacing")
    return max(lo, float(spec.guideway.footprint[1]) + MIN_GAP), hi


def _rail_spacing(spec: MachineSpec) -> float:
    s = spec.guideway.rail_spacing
    ry = spec.guideway.rail_y
    return float(ry[-1] - ry[0]) if s is None else float(s)


def _scaled(spec: MachineSpec, x: float, lo: float, hi: float) -> tuple[float, float]:
    return (lo * x, hi * x)


VARIABLES: dict[str, Variable] = {
    v.name: v
    for v in (
        Variable("thickness", "mm", 1e-3, lambda s: float(s.table.thickness),
                 lambda s: _scaled(s, float(s.table.thickness), 0.5, 2.0),
                 "equivalent plate thickness of the table"),
        Variable("carriage_spacing", "mm", 1e-3, _spacing, carriage_spacing_range,
                 "distance between the two carriages on each rail"),
        Variable("rail_spacing", "mm", 1e-3, _rail_spacing, rail_spacing_range,
                 "distance between the two rails"),
        Variable("preload_fraction", "%", 1e-2, lambda s: float(s.carriage.preload_fraction),
                 lambda s: (0.01, 0.13), "preload as a fraction of the dynamic capacity C"),
        Variable("E", "GPa", 1e9, lambda s: float(s.table.material.E),
                 lambda s: _scaled(s, float(s.table.material.E), 0.5, 2.0),
                 "Young's modulus of the table"),
    )
}


def table_mass(spec: MachineSpec):
    """The table plate's mass ``ρ·L·W·t`` (kg; may be traced)."""
    t = spec.table
    return t.material.rho * t.length * t.width * t.thickness


def total_preload(spec: MachineSpec):
    """The total preload force of the carriages, ``n_c·f·C`` (N; may be traced)."""
    g, c = spec.guideway, spec.carriage
    return len(g.rail_y) * len(g.carriage_x) * c.preload_fraction * c.capacity


def spacing_margin(spec: MachineSpec):
    """Carriage spacing less the table length minus the carriage length, ``s − (L − b)`` (m)."""
    return carriage_spacing_of(spec) - (spec.table.length - spec.guideway.footprint[0])


@dataclasses.dataclass(frozen=True)
class Quantity:
    """A constrainable quantity: ``name``, ``unit``, ``scale`` (SI per user unit), ``of(spec)``
    (SI, traced)."""

    name: str
    unit: str
    scale: float
    of: Callable[[MachineSpec], object]
    what: str


def rail_length_needed(spec: MachineSpec):
    """The rail length the stroke needs, ``S + s + b`` (m): stroke ``S``, carriage spacing
    ``s``, carriage footprint length ``b`` — both carriages of a rail stay on it over the whole
    stroke. ``rail_length<=L`` keeps a design on rails of length ``L``."""
    return spec.stroke + carriage_spacing_of(spec) + spec.guideway.footprint[0]


CONSTRAINTS: dict[str, Quantity] = {
    q.name: q
    for q in (
        Quantity("mass", "kg", 1.0, table_mass, "table plate mass (volume × density)"),
        Quantity("preload", "N", 1.0, total_preload, "total preload force of the carriages"),
        Quantity("spacing", "mm", 1e-3, spacing_margin,
                 "carriage spacing − (table length − carriage length)"),
        Quantity("rail_length", "mm", 1e-3, rail_length_needed,
                 "rail length the stroke needs: stroke + carriage spacing + carriage length"),
    )
}


@dataclasses.dataclass(frozen=True)
class Constraint:
    """``quantity kind value``: ``kind`` is ``"<="``, ``">="`` or ``"="``; ``value`` in SI."""

    quantity: str
    kind: str
    value: float

    def __post_init__(self):
        if self.quantity not in CONSTRAINTS:
            raise ValueError(f"constraint quantity must be one of {', '.join(CONSTRAINTS)}, "
                             f"got {self.quantity!r}")
        if self.kind not in ("<=", ">=", "="):
            raise ValueError(f"constraint kind must be '<=', '>=' or '=', got {self.kind!r}")
        if not np.isfinite(self.value):
            raise ValueError(f"constraint {self.quantity}: value must be finite, got "
                             f"{self.value!r}")

    def slack(self, spec: MachineSpec):
        """``≥ 0`` when satisfied (``= 0`` for an equality), in SI (traced)."""
        q = jnp.asarray(CONSTRAINTS[self.quantity].of(spec), dtype=float)
        return self.value - q if self.kind == "<=" else q - self.value

    def text(self) -> str:
        q = CONSTRAINTS[self.quantity]
        return f"{self.quantity} {self.kind} {self.value / q.scale:g} {q.unit}"


def parse_constraint(text: str) -> Constraint:
    """``"mass<=180"`` (user units: kg, N, mm) → :class:`Constraint` (SI); ``ValueError`` naming
    the allowed forms."""
    for kind in ("<=", ">=", "="):
        if kind in text:
            name, _, value = text.partition(kind)
            name = name.strip()
            try:
                v = float(value)
            except ValueError:
                v = None
            if name in CONSTRAINTS and v is not None and np.isfinite(v):
                return Constraint(name, kind, v * CONSTRAINTS[name].scale)
            break
    forms = ", ".join(f"{q.name}<=V ({q.unit})" for q in CONSTRAINTS.values())
    raise ValueError(f"a constraint is QUANTITY<=V, QUANTITY>=V or QUANTITY=V with QUANTITY one of "
                     f"{forms}; got {text!r}")


def apply_all(spec: MachineSpec, names, x) -> MachineSpec:
    """``spec`` with the variables ``names`` set to ``x[i]`` (SI; may be traced)."""
    for i, name in enumerate(names):
        spec = VARIABLES[name].apply(spec, x[i])
    return spec


def _check_layout_bounds(spec: MachineSpec, name: str, lo: float, hi: float) -> None:
    """``ValueError`` unless spacings ``lo..hi`` (m) of ``name`` keep the two footprints apart
    (``lo > b + MIN_GAP``, ``b`` the footprint's side along the spacing) and on the table
    (``|c| + hi/2 + b/2 <= L/2 - MIN_GAP``, ``c`` the pair's centre, ``L`` the table's side)."""
    g = spec.guideway
    if name == "carriage_spacing":
        b, pair, side, what = g.footprint[0], g.carriage_x, spec.table.length, "carriages"
    else:
        b, pair, side, what = g.footprint[1], g.rail_y, spec.table.width, "rails"
    centre = 0.5 * (float(pair[0]) + float(pair[-1]))
    top = 2 * (side / 2 - MIN_GAP - abs(centre)) - b
    if lo < b + MIN_GAP:
        raise ValueError(f"{name}: lower bound {lo * 1e3:g} mm overlaps the {what}' footprints "
                         f"({b * 1e3:g} mm long): it must be >= {(b + MIN_GAP) * 1e3:.4g} mm")
    if hi > top:
        raise ValueError(f"{name}: upper bound {hi * 1e3:g} mm puts the {what}' footprints off "
                         f"the table ({side * 1e3:g} mm): it must be <= {top * 1e3:.4g} mm")


def check_bounds(spec: MachineSpec, names, bounds) -> tuple[tuple[float, float], ...]:
    """Each variable's bounds (SI; ``None``: its default), checked: known name, ``0 < lo < hi``,
    the spacings' footprints neither overlapping nor off the table (:func:`_check_layout_bounds`;
    bounds wider than the mesh's range are allowed: :func:`~diffguide.studies.design.design`
    re-centres the mesh)."""
    out = []
    for name, b in zip(names, bounds):
        if name not in VARIABLES:
            raise ValueError(f"design variable must be one of {', '.join(VARIABLES)}, got "
                             f"{name!r}")
        v = VARIABLES[name]
        default = v.bounds(spec)
        lo, hi = default if b is None else (float(b[0]), float(b[1]))
        u = v.scale
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
            raise ValueError(f"{name}: bounds must be finite with 0 < lo < hi, got "
                             f"{lo / u:g}:{hi / u:g} {v.unit}")
        if name in ("carriage_spacing", "rail_spacing"):
            _check_layout_bounds(spec, name, lo, hi)
        if name == "preload_fraction" and not hi < 1:
            raise ValueError(f"preload_fraction: bounds must lie in (0, 100) %, got "
                             f"{lo / u:g}:{hi / u:g} %")
        out.append((lo, hi))
    return tuple(out)


def spec_values(spec: MachineSpec, names) -> np.ndarray:
    """The current values (SI) of the variables ``names`` on ``spec``."""
    return np.array([VARIABLES[n].value(spec) for n in names], dtype=float)
