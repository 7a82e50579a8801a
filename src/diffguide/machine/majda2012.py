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

from ..fe.mesh import Rib
from ..fe.table import TableModel
from ..guideway.rails import AbstractRailProfile, PaperPolynomialRail, StraightRail
from .build import build_machine, table_from_spec, with_overrides
from .equilibrium import Machine
from .paper import majda2012_spec as majda2012_spec

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
