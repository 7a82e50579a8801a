r"""The source paper's machine (preset ``majda2012``) and its three rail-error variants.

Values the paper gives and those chosen here are listed with their reasons in
:mod:`diffguide.presets` (table, layout, points), :func:`diffguide.guideway.majda2012_carriage`
(the runner block) and :func:`diffguide.fe.table.majda2012_table` (mesh, nut patch).

Rail error (Majda 2012, eq. 4, SPEC §3): ``i(s) = (Δ/2)(s/1 m + (s/1 m)²)``, ``Δ = 0.05 mm``, on

1. rail 1 vertical, rail 2 straight;
2. rail 1 horizontal, rail 2 straight;
3. rail 1 vertical, rail 2 horizontal.

Rail 1 is the rail at −Y. The rail coordinate ``s`` is measured along each rail from the point
under the table centre at the reference position (x = 0).
"""

import numpy as np

from .fe.materials import Material
from .fe.table import majda2012_table
from .guideway import majda2012_carriage
from .machine import Machine
from .presets import MAJDA2012_LAYOUT, MAJDA2012_TABLE
from .rails import AbstractRailProfile, PaperPolynomialRail, StraightRail

#: The paper's stroke: X 700 mm, symmetric about the reference position.
STROKE = 0.7


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
    """
    material = None
    if E is not None:
        material = Material(E=E, nu=MAJDA2012_TABLE["nu"], rho=MAJDA2012_TABLE["rho"],
                            name="cast iron")
    kwargs = {} if points is None else {"points": points}
    table_model = majda2012_table(nx, ny, thickness=thickness, material=material, **kwargs)
    condensed = table_model.condense()
    carriage = majda2012_carriage(law)
    if preload_fraction is not None:
        per_element = preload_fraction * 22.8e3 / (carriage.n_rows * carriage.n_elements)
        carriage = type(carriage)(
            carriage.law, carriage.row_yz, carriage.row_normals, carriage.xi, per_element,
            carriage.eps_ratio, carriage.crowning,
        )
    L = MAJDA2012_LAYOUT
    carriage_x, carriage_rail = [], []
    for patch in table_model.patches[:-1]:  # carriages, then the nut
        carriage_x.append(patch.x)
        carriage_rail.append(int(np.argmin([abs(patch.y - ry) for ry in L["rail_y"]])))
    d = L["screw_core_diameter"]
    return Machine(
        table=condensed,
        carriage=carriage,
        carriage_x=np.asarray(carriage_x),
        carriage_rail=tuple(carriage_rail),
        point_names=table_model.point_names,
        points_xy=np.asarray(table_model.points),
        screw_EA=L["screw_E"] * np.pi * d**2 / 4,
        screw_length_ref=L["screw_free_length_at_ref"],
    )


def paper_variant(variant: int, delta: float = 0.05e-3) -> tuple[AbstractRailProfile, AbstractRailProfile]:
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
