"""Two size-25 runner blocks, each value with its source: the paper's ball block (Majda,
Precision Engineering 36 (2012) 369-378) and a catalogue-typical roller block, as
specifications (:class:`~diffguide.guideway.carriage.CarriageSpec`, SI) and as carriages.
"""

import dataclasses

from .carriage import Carriage, CarriageSpec, carriage_from_spec


def ball_block_25(law: str = "hertz") -> CarriageSpec:
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


def roller_block_25() -> CarriageSpec:
    """A catalogue-typical size-25 roller runner block (four rows of rollers at 45°).

    Values typical of size-25 roller blocks in the Bosch Rexroth and THK (SRG 25) catalogues:
    dynamic capacity C ≈ 48.9 kN, preload class 8 % C, cylindrical rollers of 5 mm diameter with
    an effective length of 6 mm, 16 rollers per row at a 5.5 mm pitch (an 88 mm loaded zone in a
    ~100 mm steel body); rows placed as in :func:`ball_block_25` (same rail size). These are
    representative, not one product's data sheet. Steel rollers: Palmgren's law holds for
    E ≈ 210 GPa, ν ≈ 0.3.
    """
    return dataclasses.replace(
        ball_block_25(),
        law="roller",
        ball_diameter=5e-3,  # the roller diameter; Palmgren's law does not use it
        roller_length=6e-3,
        elements_per_row=16,
        pitch=5.5e-3,
        capacity=48.9e3,
    )


def majda2012_carriage(law: str = "hertz") -> Carriage:
    """The paper's size-25 ball runner block (:func:`ball_block_25`).

    Arguments:
        law: ``"hertz"`` (full elliptic Hertz theory) or ``"rivin"`` (the paper's eq. 1).
    """
    if law not in ("hertz", "rivin"):
        raise ValueError(f"law must be one of ['hertz', 'rivin'], got {law!r}")
    return carriage_from_spec(ball_block_25(law))


def roller25_carriage() -> Carriage:
    """A catalogue-typical size-25 roller block (:func:`roller_block_25`)."""
    return carriage_from_spec(roller_block_25())
