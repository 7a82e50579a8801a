r"""Runner blocks from manufacturers' catalogues: published figures in, a calibrated model out.

A catalogue gives, per block, the dynamic capacity C, the static capacity C0, preload classes as
fractions of C, a rigidity (N/µm) per preload class and the block's envelope; it gives none of
the internal parameters the element model (:class:`~diffguide.guideway.carriage.CarriageSpec`)
needs. The table of published figures is :mod:`~diffguide.guideway.catalogue_data` (every block
with its source); :func:`calibrate_block` turns a block and a preload class into a specification
in four steps:

1. **Published, used as given:** the capacity C (so the preload ``f·C`` and any life figure use
   the published C), the contact angle where the catalogue gives one, the preload class's
   range of fractions of C.
2. **Chosen from the envelope** (:func:`envelope_geometry`; a fixed rule, the same for every
   block): element diameter ``d = 0.2·W_R`` (rail width); element pitch ``d`` (balls, a full
   row) or ``1.1·d`` (rollers, with a cage); loaded zone ``0.8·L₁`` (steel body length, the
   rest being the relieved entry zones), hence ``n = ⌊0.8·L₁/pitch⌋`` elements per row; the
   upper rows at ``(±0.4·W_R, −(H − H_R) − 0.1·H_R)`` and the lower rows at
   ``(±0.5·W_R, −(H − H_R) − 0.45·H_R)`` below the block's top face (``H`` block height from
   the rail's foot, ``H_R`` rail height); O arrangement; steel, E = 210 GPa, ν = 0.3; the
   preload fraction is the middle of the published class range.
3. **Calibrated:** the one contact parameter left — the groove conformity D/d (balls, Hertz) or
   the effective roller length (rollers, Palmgren) — is found by a bracketed scalar root-find
   (regula falsi, float64, on its logarithm; the rigidity is monotonic in it) so that the
   model's rigidity equals the published one — or, for a block whose sources publish none
   (HIWIN RG: a graph only), the one its user gives.
4. **Explicit values override:** any :class:`CarriageSpec` field given by the caller replaces
   steps 1–2; the contact parameter is re-fitted with the caller's geometry unless it is given
   too. An explicit ``preload_fraction`` sets the operating preload only: the calibration stays
   at the class's preload, where the published rigidity holds.

**The model's rigidity** (:func:`radial_rigidity`) is the carriage's tangent stiffness in the
catalogue's load direction — radial, i.e. Z, a load pressing the block onto the rail — at the
preloaded state without external load: ``−∂W_z/∂t_z`` from
:meth:`~diffguide.guideway.carriage.Carriage.tangent`. The catalogues read here give no load for
their rigidity (deflection = load / rigidity), so the tangent at zero load is the reading used.

The fitted conformity is an *effective* value: it absorbs what a Hertz model of the balls alone
leaves out (deformation of the block body and the rail, which is why published rigidities rise
less with preload than Hertz contact does), so it is fitted per preload class. The provenance
returned with each specification says which values are published, chosen, calibrated or explicit.
"""

import dataclasses
import functools
import math
from collections.abc import Mapping

import jax.numpy as jnp

from .._core.precision import require_x64
from . import catalogue_data
from .carriage import CarriageSpec, carriage_from_spec

#: Elements' material (chosen; bearing steel).
STEEL_E, STEEL_NU = 210e9, 0.3
#: The rule of step 2 (module docstring): diameter / rail width, pitch / diameter, loaded zone /
#: body length.
DIAMETER_PER_RAIL_WIDTH = 0.2
PITCH_PER_DIAMETER = {"ball": 1.0, "roller": 1.1}
LOADED_ZONE_PER_BODY = 0.8
#: Search ranges of the calibrated parameter (the machine file's ranges).
CONFORMITY_RANGE = (1.0001, 1.5)
ROLLER_LENGTH_RANGE = (0.5e-3, 100e-3)
#: Contact angle where a catalogue gives none (degrees; chosen).
DEFAULT_CONTACT_ANGLE = 45.0


@dataclasses.dataclass(frozen=True)
class CatalogueBlock:
    """One runner block's published figures, SI.

    Arguments:
        name: ``"<family> <size> <type>"``. element: ``"ball"`` or ``"roller"``.
        capacity: dynamic load capacity C (N). static_capacity: C0 (N) or ``None``.
        preload_classes: ``{class: (low, high)}`` preload as fractions of C.
        rigidity: ``{class: k}`` published rigidity (N/m) in ``rigidity_direction``.
        rigidity_direction: e.g. ``"radial"``. rigidity_load: at which load it is given.
        contact_angle_deg: published contact angle (degrees) or ``None``.
        block_height: H, rail foot to block top (m). block_width: W (m).
        body_length: steel body length L₁ (m). block_length: with end caps (m) or ``None``.
        bolt_pattern: bolt spacing (along X, across Y) (m) or ``None``.
        rail_width, rail_height: W_R, H_R (m).
        source: the block's figures (C, C0, rigidity, dimensions): catalogue, edition, pages,
            address. family_source: the same for the preload classes and the contact angle.
        cite: a short name of the block's source; family_cite: of the family's.
    """

    name: str
    element: str
    capacity: float
    static_capacity: float | None
    preload_classes: Mapping[str, tuple[float, float]]
    rigidity: Mapping[str, float]
    rigidity_direction: str
    rigidity_load: str
    contact_angle_deg: float | None
    block_height: float
    block_width: float
    body_length: float
    block_length: float | None
    bolt_pattern: tuple[float, float] | None
    rail_width: float
    rail_height: float
    source: str
    family_source: str = ""
    cite: str = ""
    family_cite: str = ""

    def __post_init__(self):
        if self.element not in ("ball", "roller"):
            raise ValueError(
                f"{self.name}: element must be 'ball' or 'roller', got {self.element!r}"
            )
        for what, v in (
            ("capacity C (N)", self.capacity),
            ("block_height (m)", self.block_height),
            ("block_width (m)", self.block_width),
            ("body_length (m)", self.body_length),
            ("rail_width (m)", self.rail_width),
            ("rail_height (m)", self.rail_height),
        ):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{self.name}: {what} must be > 0, got {v!r}")
        if not self.rail_height < self.block_height:
            raise ValueError(
                f"{self.name}: rail_height ({self.rail_height} m) must be below block_height "
                f"({self.block_height} m)"
            )
        for cls, (lo, hi) in self.preload_classes.items():
            if not 0.0 <= lo <= hi < 1.0 or hi <= 0.0:
                raise ValueError(
                    f"{self.name}: preload class {cls!r} must be 0 <= low <= high < 1 (fractions "
                    f"of C, high > 0), got [{lo}, {hi}]"
                )
        for cls, k in self.rigidity.items():
            if cls not in self.preload_classes:
                raise ValueError(f"{self.name}: rigidity given for unknown preload class {cls!r}")
            if not (math.isfinite(k) and k > 0):
                raise ValueError(f"{self.name}: rigidity of class {cls!r} must be > 0, got {k!r}")

    @property
    def footprint(self) -> tuple[float, float]:
        """The steel body's top face bolted to the table, (X, Y) = (L₁, W) (m)."""
        return (self.body_length, self.block_width)

    def preload_fraction(self, preload_class: str) -> float:
        """The nominal preload of a class: the middle of its published range (fraction of C)."""
        if preload_class not in self.preload_classes:
            raise ValueError(
                f"{self.name}: preload class {preload_class!r} is unknown; allowed: "
                f"{', '.join(self.preload_classes)}"
            )
        lo, hi = self.preload_classes[preload_class]
        return 0.5 * (lo + hi)


def _normalise(name: str) -> str:
    return " ".join(str(name).split()).upper()


@functools.cache
def _table() -> dict[str, CatalogueBlock]:
    out = {}
    for row in catalogue_data.BLOCKS:
        fam = catalogue_data.FAMILIES[row["family"]]
        src = catalogue_data.SOURCES[row["source"]]
        fam_src = catalogue_data.SOURCES[fam["source"]]

        def full(s):
            return f"{s['catalogue']}, {s['edition']}, {s['pages']} ({s['url']})"

        name = f"{row['family']} {row['size']} {row['type']}"
        mm = 1e-3
        out[_normalise(name)] = CatalogueBlock(
            name=name,
            element=fam["element"],
            capacity=float(row["C_N"]),
            static_capacity=float(row["C0_N"]),
            preload_classes={
                k: (float(v[0]), float(v[1])) for k, v in fam["preload_classes"].items()
            },
            rigidity={k: float(v) * 1e6 for k, v in row["rigidity_N_um"].items()},
            rigidity_direction=fam["rigidity_direction"],
            rigidity_load=fam["rigidity_load"],
            contact_angle_deg=fam.get("contact_angle_deg"),
            block_height=row["block_height_mm"] * mm,
            block_width=row["block_width_mm"] * mm,
            body_length=row["body_length_mm"] * mm,
            block_length=row["block_length_mm"] * mm,
            bolt_pattern=None
            if row["bolt_pattern_mm"] is None
            else tuple(v * mm for v in row["bolt_pattern_mm"]),
            rail_width=row["rail_width_mm"] * mm,
            rail_height=row["rail_height_mm"] * mm,
            source=full(src),
            family_source=full(fam_src),
            cite=src["short"],
            family_cite=fam_src["short"],
        )
    return out


def known_blocks() -> tuple[str, ...]:
    """The names of the blocks in the package's catalogue table."""
    return tuple(b.name for b in _table().values())


def catalogue_block(name: str) -> CatalogueBlock:
    """A block of the catalogue table by its name ``"<family> <size> <type>"`` (case and
    spacing ignored), e.g. ``"HIWIN-HG 25 C"``.

    Raises:
        ValueError: an unknown name; the message lists the known ones.
    """
    try:
        return _table()[_normalise(name)]
    except KeyError:
        raise ValueError(
            f"block {name!r} is not in the catalogue table; known blocks: "
            f"{', '.join(known_blocks())} (or give the block's datasheet values instead)"
        ) from None


def datasheet_block(
    *,
    element: str,
    capacity: float,
    preload_fraction: float,
    rigidity: float,
    block_height: float,
    block_width: float,
    body_length: float,
    rail_width: float,
    rail_height: float,
    contact_angle_deg: float | None = None,
    name: str = "datasheet block",
) -> CatalogueBlock:
    """A block not in the table, from its datasheet alone (SI): capacity C (N), preload as a
    fraction of C, the rigidity (N/m, radial, at that preload) and the envelope (m, as
    :class:`CatalogueBlock`). Its one preload class is called ``"datasheet"``."""
    return CatalogueBlock(
        name=name,
        element=element,
        capacity=float(capacity),
        static_capacity=None,
        preload_classes={"datasheet": (float(preload_fraction), float(preload_fraction))},
        rigidity={"datasheet": float(rigidity)},
        rigidity_direction="radial",
        rigidity_load="as the datasheet gives it (read as the tangent at the preload)",
        contact_angle_deg=contact_angle_deg,
        block_height=float(block_height),
        block_width=float(block_width),
        body_length=float(body_length),
        block_length=None,
        bolt_pattern=None,
        rail_width=float(rail_width),
        rail_height=float(rail_height),
        source="user's datasheet",
        family_source="user's datasheet",
        cite="datasheet",
        family_cite="datasheet",
    )


def envelope_geometry(block: CatalogueBlock) -> dict:
    """The internal geometry chosen from a block's envelope (step 2 of the module docstring):
    :class:`CarriageSpec` fields (SI) except the calibrated one, the capacity and the preload."""
    d = DIAMETER_PER_RAIL_WIDTH * block.rail_width
    pitch = PITCH_PER_DIAMETER[block.element] * d
    n = max(2, int(LOADED_ZONE_PER_BODY * block.body_length / pitch))
    top = -(block.block_height - block.rail_height)  # rail top below the block's top face
    wr, hr = block.rail_width, block.rail_height
    return {
        "law": "hertz" if block.element == "ball" else "roller",
        "ball_diameter": d,
        "E": STEEL_E,
        "nu": STEEL_NU,
        "elements_per_row": n,
        "pitch": pitch,
        "contact_angle_deg": block.contact_angle_deg or DEFAULT_CONTACT_ANGLE,
        "arrangement": "O",
        "upper_row_yz": (0.4 * wr, top - 0.1 * hr),
        "lower_row_yz": (0.5 * wr, top - 0.45 * hr),
    }


#: Why each value of :func:`envelope_geometry` is what it is (provenance texts).
_RULES = {
    "law": "Hertz point contact for balls, Palmgren line contact for rollers",
    "ball_diameter": f"element diameter {DIAMETER_PER_RAIL_WIDTH:g} × rail width",
    "E": "steel",
    "nu": "steel",
    "elements_per_row": f"⌊{LOADED_ZONE_PER_BODY:g} × body length / pitch⌋",
    "pitch": "diameter (balls, full row) or 1.1 × diameter (rollers, caged)",
    "contact_angle_deg": f"{DEFAULT_CONTACT_ANGLE:g}° (none published)",
    "arrangement": "O",
    "upper_row_yz": "(0.4 × rail width, rail top − 0.1 × rail height)",
    "lower_row_yz": "(0.5 × rail width, rail top − 0.45 × rail height)",
}


def radial_rigidity(spec: CarriageSpec) -> float:
    """The model's radial rigidity (N/m): ``−∂W_z/∂t_z`` of the carriage at its preload, without
    external load and on a straight rail, from :meth:`Carriage.tangent`."""
    carriage = carriage_from_spec(spec)
    a = jnp.full((carriage.n_rows, carriage.n_elements), carriage.preload_approach)
    return float(-carriage.tangent(a)[2, 2])


def _free_parameter(law: str) -> tuple[str, tuple[float, float]]:
    if law == "roller":
        return "roller_length", ROLLER_LENGTH_RANGE
    return "groove_conformity", CONFORMITY_RANGE


def _fit(spec: CarriageSpec, field: str, bounds, target: float, block: str) -> CarriageSpec:
    """Solve ``log radial_rigidity = log target`` for ``u = log(field)`` (conformity:
    ``u = log(D/d − 1)``) by regula falsi with the Illinois step (bracketed, float64; the
    rigidity is monotonic and nearly a power of the parameter, so a few steps suffice)."""
    require_x64("calibrate_block (the catalogue calibration)")
    shift = 1.0 if field == "groove_conformity" else 0.0

    def f(u):
        value = shift + math.exp(u)
        return math.log(radial_rigidity(dataclasses.replace(spec, **{field: value})) / target)

    a, b = (math.log(x - shift) for x in bounds)
    fa, fb = f(a), f(b)
    if fa * fb > 0:
        k_a, k_b = (target * math.exp(v) / 1e6 for v in (fa, fb))
        raise ValueError(
            f"{block}: the published rigidity {target / 1e6:g} N/µm is outside what the model "
            f"reaches with {field} in [{bounds[0]:g}, {bounds[1]:g}] "
            f"({min(k_a, k_b):.4g} .. {max(k_a, k_b):.4g} N/µm) with this geometry and "
            "preload; give the geometry (element size and count) explicitly"
        )
    side = 0
    for _ in range(100):
        c = (a * fb - b * fa) / (fb - fa)
        fc = f(c)
        if abs(fc) < 1e-13 or abs(b - a) < 1e-14:
            break
        if fc * fb < 0:
            a, fa = b, fb
            side = 0
        else:
            fa = fa / 2 if side == 1 else fa  # Illinois: halve the end that stays
            side = 1
        b, fb = c, fc
    else:  # pragma: no cover - the bracket always converges
        raise RuntimeError(f"{block}: calibration of {field} did not converge")
    return dataclasses.replace(spec, **{field: shift + math.exp(c)})


def _target(block: CatalogueBlock, preload_class: str, rigidity: float | None):
    """The rigidity the contact parameter is fitted to (N/m, or ``None``) and whose it is."""
    published = block.rigidity.get(preload_class)
    if rigidity is None:
        return published, None if published is None else f"published ({block.cite})"
    if published is not None:
        raise ValueError(
            f"{block.name}: the catalogue publishes a rigidity for class {preload_class!r} "
            f"({published / 1e6:g} N/µm); give either the catalogue block or your own rigidity "
            "(a datasheet block), not both"
        )
    if not (math.isfinite(rigidity) and rigidity > 0):
        raise ValueError(f"{block.name}: rigidity must be > 0 N/m, got {rigidity!r}")
    return float(rigidity), f"given (none published in {block.cite})"


#: The CarriageSpec fields a caller may set explicitly (SI).
SPEC_FIELDS = tuple(f.name for f in dataclasses.fields(CarriageSpec))


def calibrate_block(
    block: CatalogueBlock | str,
    preload_class: str | None = None,
    *,
    rigidity: float | None = None,
    **explicit,
) -> tuple[CarriageSpec, dict[str, str]]:
    """The :class:`CarriageSpec` of a catalogue block at a preload class, and where each value
    comes from: published, chosen, calibrated or explicit.

    The capacity is the published C; the element size, count, pitch and rows follow
    :func:`envelope_geometry`; the preload is the middle of the class's published range; the
    groove conformity (balls) or effective roller length (rollers) is fitted so that
    :func:`radial_rigidity` (the tangent stiffness under a load pressing the block onto the
    rail, at the preload without other load) equals the published rigidity of the class.
    Explicit fields replace the rules; the contact parameter is re-fitted with them unless it
    is explicit too. An explicit ``preload_fraction`` sets the operating preload only. A block
    whose sources publish no rigidity for the class (HIWIN RG) is fitted to ``rigidity``, the
    user's figure; a published rigidity is never replaced (a block with other figures is a
    :func:`datasheet_block`).

    Arguments:
        block: a :class:`CatalogueBlock` or a name in the table (:func:`catalogue_block`).
        preload_class: one of the block's classes (``"datasheet"`` for a
            :func:`datasheet_block`; may be omitted when the block has only one).
        rigidity: the block's radial rigidity at the class's preload (N/m), only where the
            table has none for the class.
        explicit: :class:`CarriageSpec` fields (SI) that override the catalogue and the rules.

    Returns:
        ``(spec, provenance)``: ``provenance[field]`` is a one-line text for each field.
    """
    if isinstance(block, str):
        block = catalogue_block(block)
    unknown = sorted(set(explicit) - set(SPEC_FIELDS))
    if unknown:
        raise ValueError(f"unknown carriage fields {unknown}; allowed: {', '.join(SPEC_FIELDS)}")
    if preload_class is None:
        if len(block.preload_classes) != 1:
            allowed = ", ".join(block.preload_classes)
            raise ValueError(f"{block.name}: a preload class is needed; allowed: {allowed}")
        preload_class = next(iter(block.preload_classes))
    fraction = block.preload_fraction(preload_class)
    target, whose = _target(block, preload_class, rigidity)
    lo, hi = block.preload_classes[preload_class]
    values = envelope_geometry(block)
    prov = {k: f"chosen: {_RULES[k]}" for k in values}
    if block.contact_angle_deg is not None:
        prov["contact_angle_deg"] = f"published: {block.family_cite}"
    values |= {"capacity": block.capacity, "preload_fraction": fraction, "smoothing_fraction": 0.02}
    prov["capacity"] = f"published: C = {block.capacity:g} N ({block.cite})"
    prov["preload_fraction"] = (
        f"chosen: middle of class {preload_class}'s published range [{lo:g}, {hi:g}]·C "
        f"({block.family_cite})"
    )
    prov["smoothing_fraction"] = "chosen: default 0.02"
    field, bounds = _free_parameter(explicit.get("law", values["law"]))
    if rigidity is not None and field in explicit:
        raise ValueError(
            f"{block.name}: give either the rigidity (fitted by {field}) or {field} itself, "
            "not both"
        )
    other = "roller_length" if field == "groove_conformity" else "groove_conformity"
    values[other] = 6e-3 if other == "roller_length" else 1.01
    prov[other] = "unused by this law (a valid placeholder)"
    values[field] = bounds[0]  # replaced by the fit below unless explicit
    values |= {k: v for k, v in explicit.items() if k != "preload_fraction"}
    prov |= {k: "explicit" for k in explicit}
    spec = CarriageSpec(**values)
    if field not in explicit:
        if target is None:
            raise ValueError(
                f"{block.name}: no rigidity is published for preload class {preload_class!r} "
                f"in the source read ({block.cite}; classes with one: "
                f"{', '.join(block.rigidity) or 'none'}); give the block's radial rigidity at "
                f"this class from its datasheet (rigidity=... N/m; in a machine file "
                f"[carriage] rigidity_N_um) or {field} explicitly"
            )
        spec = _fit(spec, field, bounds, target, block.name)
        prov[field] = (
            f"calibrated: radial rigidity at class {preload_class} preload = "
            f"{target / 1e6:g} N/µm, {whose}"
        )
    if "preload_fraction" in explicit:
        spec = dataclasses.replace(spec, preload_fraction=explicit["preload_fraction"])
    return spec, prov
