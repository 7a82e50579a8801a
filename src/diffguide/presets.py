"""Every value of the built-in machines, each defined once, with the reason it was chosen.

``majda2012`` is the vertical machining centre of Majda, Precision Engineering 36 (2012) 369-378:
strokes X/Y/Z 700/460/500 mm, size-25 Rexroth ball guideways (C = 22.8 kN, preload 8 % C,
d = 3 mm, D = 1.01 d), a 32 mm screw core, four carriages under a cast-iron table modelled as a
plate of equivalent thickness, five control points on the table top. The paper does not give the
table size, the rail and carriage spacing, the element count or the plate thickness; the values
below are chosen and justified one by one. SI units throughout (m, Pa, kg/m³, N).

Frame: X along the rails, Y across, Z up; origin at the table centre on the plate mid-surface at
the reference position. Rail 1 is at -Y, rail 2 at +Y.

Each preset is a function returning a fresh typed specification
(:class:`~diffguide.machine.spec.MachineSpec`, :class:`~diffguide.guideway.carriage.CarriageSpec`,
:class:`~diffguide.fe.materials.Material`); change a value with ``eqx.tree_at`` (array fields,
which may then be traced) or ``dataclasses.replace``. This module imports nothing from diffguide
at import time, so every layer may read it.
"""

from types import MappingProxyType


def cast_iron():
    """Grey cast iron EN-GJL-250: E 103-118 GPa (EN 1561), ν 0.26, 7200 kg/m³; E = 110 GPa."""
    from .fe.materials import Material

    return Material(E=110e9, nu=0.26, rho=7200.0, name="cast iron")


def steel():
    """Structural steel: E 210 GPa, ν 0.3, 7850 kg/m³."""
    from .fe.materials import Material

    return Material(E=210e9, nu=0.3, rho=7850.0, name="steel")


def ball_block_25(law: str = "hertz"):
    """The paper's size-25 ball runner block (Majda 2012, §3).

    From the paper: C = 22.8 kN, preload 8 % C, balls d = 3 mm in grooves D = 1.01 d,
    E = 210 GPa, ν = 0.3, four rows at 45°. Chosen here (the paper gives no element count or row
    positions): 12 balls per row at a 4 mm pitch (3 mm ball + 1 mm spacer; a 48 mm loaded zone,
    inside a size-25 block's ~60 mm steel body); upper rows at y = ±9 mm, z = −15 mm and lower rows
    at y = ±11.5 mm, z = −23 mm below the carriage's top face (a size-25 rail is 23 mm wide; the
    block is 36 mm tall over a 23 mm rail, so the rail top is 13 mm below the face), O arrangement;
    smoothing length 2 % of the preload approach.

    Arguments:
        law: ``"hertz"`` (full elliptic Hertz theory) or ``"rivin"`` (the paper's eq. 1).
    """
    from .guideway.carriage import CarriageSpec

    return CarriageSpec(
        law=law,
        ball_diameter=3e-3,
        groove_conformity=1.01,
        roller_length=6e-3,  # unused by balls; the roller block's value (a valid default)
        E=210e9,
        nu=0.3,
        elements_per_row=12,
        pitch=4e-3,
        contact_angle_deg=45.0,
        arrangement="O",
        upper_row_yz=(9e-3, -15e-3),
        lower_row_yz=(11.5e-3, -23e-3),
        capacity=22.8e3,
        preload_fraction=0.08,
        smoothing_fraction=0.02,
    )


def roller_block_25():
    """A catalogue-typical size-25 roller runner block (four rows of rollers at 45°).

    Values typical of size-25 roller blocks in the Bosch Rexroth and THK (SRG 25) catalogues:
    dynamic capacity C ≈ 48.9 kN, preload class 8 % C, cylindrical rollers of 5 mm diameter with
    an effective length of 6 mm, 16 rollers per row at a 5.5 mm pitch (an 88 mm loaded zone in a
    ~100 mm steel body); rows placed as in :func:`ball_block_25` (same rail size). These are
    representative, not one product's data sheet. Steel rollers: Palmgren's law holds for
    E ≈ 210 GPa, ν ≈ 0.3.
    """
    import dataclasses

    return dataclasses.replace(
        ball_block_25(),
        law="roller",
        ball_diameter=5e-3,  # the roller diameter; Palmgren's law does not use it
        roller_length=6e-3,
        elements_per_row=16,
        pitch=5.5e-3,
        capacity=48.9e3,
    )


def majda2012(law: str = "hertz"):
    """The ``majda2012`` machine (module docstring); ``law``: the ball block's contact law."""
    from .fe.table import TableSpec
    from .machine.spec import GuidewaySpec, MachineSpec, ScrewSpec

    return MachineSpec(
        table=TableSpec(
            # 1000 x 500 mm: a medium VMC table (the paper's photographs; Majda's own class
            # "smaller than 1200 x 600 mm"), longer than the 700 mm stroke as usual.
            length=1.0,
            width=0.5,
            # Equivalent solid-plate thickness 50 mm (180 kg, the mass range of a ribbed
            # cast-iron table of this size). The paper obtained its plate thickness by matching a
            # detailed model's stiffness and does not give it; over the plausible 40-80 mm the
            # model's qualitative behaviour changes, and 50 mm is where it shows all of the
            # paper's findings (at 80 mm the variant-2 corner roll drops below the yaw; at 40 mm
            # the yaw differs by 13 % between points). A calibration to the paper, stated as such.
            thickness=0.05,
            material=cast_iron(),
            # FE mesh: 50 mm elements (20 x 10); refined by the footprint grid lines.
            nx=20,
            ny=10,
        ),
        guideway=GuidewaySpec(
            # Rails 340 mm apart: 80 mm inside each table edge, the usual margin for clamping
            # slots.
            rail_y=(-0.170, 0.170),
            # Carriages 320 mm apart along each rail, symmetric about the table centre.
            carriage_x=(-0.160, 0.160),
            # Carriage footprint bolted to the table (size-25 flanged block: body length ~60 mm,
            # width 48 mm).
            footprint=(0.060, 0.048),
        ),
        carriage=ball_block_25(law),
        screw=ScrewSpec(
            # The paper's 32 mm screw core, steel.
            core_diameter=0.032,
            E=210e9,
            # Nut under the table centre; the fixed bearing 450 mm behind it at x = 0, so the
            # free length is 0.45 m + x (0.10 ... 0.80 m over the 700 mm stroke).
            free_length_at_ref=0.45,
            nut_xy=(0.0, 0.0),
            # A 50 x 50 mm flange: the nut housing of a 32 mm screw, bolted under the table.
            nut_footprint=(0.05, 0.05),
        ),
        # Control points on the table top (x, y): four corners inset 50 mm (room for a level
        # or a reflector), and the centre. P1 (+x, +y), P2 (-x, +y), P3 (-x, -y), P4 (+x, -y).
        points={
            "P1": (0.450, 0.200),
            "P2": (-0.450, 0.200),
            "P3": (-0.450, -0.200),
            "P4": (0.450, -0.200),
            "P5": (0.0, 0.0),
        },
        ribs=(),
        gravity=9.81,
        # The paper's X stroke, symmetric about the reference position.
        stroke=0.7,
    )


def __getattr__(name: str):
    """The dictionaries of diffguide 0.1 (``MAJDA2012_TABLE``, ``MAJDA2012_LAYOUT``,
    ``MAJDA2012_POINTS``), now views of :func:`majda2012`; deprecated."""
    if name not in ("MAJDA2012_TABLE", "MAJDA2012_LAYOUT", "MAJDA2012_POINTS"):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import warnings

    warnings.warn(
        f"diffguide.presets.{name} is deprecated; use diffguide.presets.majda2012()",
        DeprecationWarning,
        stacklevel=2,
    )
    m = majda2012()
    t, g, s = m.table, m.guideway, m.screw
    views = {
        "MAJDA2012_TABLE": {
            "length": t.length,
            "width": t.width,
            "thickness": t.thickness,
            "E": t.material.E,
            "nu": t.material.nu,
            "rho": t.material.rho,
            "nx": t.nx,
            "ny": t.ny,
        },
        "MAJDA2012_LAYOUT": {
            "rail_y": g.rail_y,
            "carriage_x": g.carriage_x,
            "carriage_footprint": g.footprint,
            "nut_xy": s.nut_xy,
            "screw_free_length_at_ref": s.free_length_at_ref,
            "screw_core_diameter": s.core_diameter,
            "screw_E": s.E,
            "gravity": m.gravity,
        },
        "MAJDA2012_POINTS": dict(m.points),
    }
    return MappingProxyType(views[name])
