r"""The source paper's machine (preset ``majda2012``) and its three rail-error variants.

The vertical machining centre of Majda, Precision Engineering 36 (2012) 369-378: strokes X/Y/Z
700/460/500 mm, size-25 Rexroth ball guideways (C = 22.8 kN, preload 8 % C, d = 3 mm,
D = 1.01 d), a 32 mm screw core, four carriages under a cast-iron table modelled as a plate of
equivalent thickness, five control points on the table top. The paper does not give the table
size, the rail and carriage spacing, the element count or the plate thickness; the values of
:func:`majda2012_spec` are chosen and justified one by one (each defined once, there). SI units
throughout (m, Pa, kg/m³, N).

Frame: X along the rails, Y across, Z up; origin at the table centre on the plate mid-surface at
the reference position. Rail 1 is at -Y, rail 2 at +Y.

Rail error (Majda 2012, eq. 4): ``i(s) = (Δ/2)(s/1 m + (s/1 m)²)``, ``Δ = 0.05 mm``, on

1. rail 1 vertical, rail 2 straight;
2. rail 1 horizontal, rail 2 straight;
3. rail 1 vertical, rail 2 horizontal.

The rail coordinate ``s`` is measured along each rail from the point
under the table centre at the reference position (x = 0).
"""

import dataclasses
from collections.abc import Sequence

import equinox as eqx

from ..fe.materials import cast_iron
from ..fe.mesh import Rib
from ..fe.table import TableModel, TableSpec
from ..guideway.blocks import ball_block_25
from ..guideway.rails import AbstractRailProfile, PaperPolynomialRail, StraightRail
from .build import build_machine, table_from_spec, with_overrides
from .equilibrium import Machine
from .spec import GuidewaySpec, MachineSpec, ScrewSpec


def majda2012_spec(law: str = "hertz") -> MachineSpec:
    """The ``majda2012`` machine as a specification (SI), every value with its reason (module
    docstring); ``law``: the ball block's contact law. A fresh object on every call: change a
    value with ``eqx.tree_at`` (array fields, which may then be traced) or
    ``dataclasses.replace``."""
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


#: The paper's stroke: X 700 mm, symmetric about the reference position.
STROKE = majda2012_spec().stroke


def majda2012_machine(
    *,
    nx: int | None = None,
    ny: int | None = None,
    thickness=None,
    E=None,
    law: str = "hertz",
    preload_fraction=None,
    points: dict[str, tuple[float, float]] | None = None,
) -> Machine:
    """Build the ``majda2012`` machine (elastic table; ``.with_rigid_table()`` for the rigid one).

    Arguments:
        nx, ny: table mesh divisions (default 20 × 10).
        thickness: equivalent plate thickness (m), default 0.05; may be traced (gradients).
        E: Young's modulus of the table (Pa), default 110 GPa (cast iron); may be traced.
        law: carriage contact law, ``"hertz"`` or ``"rivin"``.
        preload_fraction: preload as a fraction of C (default 0.08); may be traced.
        points: control points ``{name: (x, y)}`` on the table top (m), default P1–P5.
            Concrete numbers only: each point puts mesh lines through itself (the mesh is
            static), so a point is not differentiable — a traced coordinate (``jax.grad``,
            ``jacfwd``, ``vmap`` over it) is refused with a ``TypeError``. For the
            effect of moving a point use :func:`~diffguide.machine.kinematics.error_field`
            (errors at every node of one mesh) or a finite difference over rebuilt machines.
    """
    if law not in ("hertz", "rivin"):
        raise ValueError(f"law must be 'hertz' or 'rivin', got {law!r}")
    overrides = dict(thickness=thickness, E=E, preload_fraction=preload_fraction, points=points)
    return build_machine(majda2012_spec(law), nx=nx, ny=ny, **overrides)


def paper_variant(
    variant: int, delta: float = 0.05e-3
) -> tuple[AbstractRailProfile, AbstractRailProfile]:
    """Rail profiles (rail 1, rail 2) of the paper's variant 1, 2 or 3 (see module docstring).

    Arguments:
        variant: 1, 2 or 3. delta: Δ of eq. 4 (m), 0.05 mm in the paper.
    """
    if variant == 1:
        return PaperPolynomialRail(delta, "vertical"), StraightRail()
    if variant == 2:
        return PaperPolynomialRail(delta, "horizontal"), StraightRail()
    if variant == 3:
        return PaperPolynomialRail(delta, "vertical"), PaperPolynomialRail(delta, "horizontal")
    raise ValueError(f"variant must be 1, 2 or 3, got {variant!r}")


def majda2012_table(
    nx: int | None = None,
    ny: int | None = None,
    *,
    nut: bool = True,
    ribs: Sequence[Rib] = (),
    thickness: float | None = None,
    material=None,
    points: dict[str, tuple[float, float]] | None = None,
) -> TableModel:
    """The ``majda2012`` table, ready to condense (:func:`~diffguide.machine.table_from_spec`).

    Arguments:
        nx, ny: uniform divisions along X and Y (default 20 × 10, 50 mm elements), >= 1.
        nut: add the screw-nut patch (last interface, 6 DOF) under the table centre.
        ribs: optional ribs under the plate.
        thickness: plate thickness in m (default 0.05, the preset's equivalent thickness).
        material: plate material (default: the preset's cast iron, E 110 GPa, ν 0.26).
        points: control points ``{name: (x, y)}`` on the top surface (m); default P1..P5.
            Concrete numbers only (they set mesh lines; see :func:`majda2012_machine`).
    """
    spec = with_overrides(majda2012_spec(), thickness=thickness, nx=nx, ny=ny, points=points)
    if material is not None:
        spec = eqx.tree_at(lambda m: m.table.material, spec, material)
    if ribs:
        spec = dataclasses.replace(spec, ribs=tuple(ribs))
    return table_from_spec(spec, nut=nut)
