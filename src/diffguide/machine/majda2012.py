r"""The source paper's machine (preset ``majda2012``) and its three rail-error variants.

Values the paper gives and those chosen here are listed with their reasons in
:mod:`diffguide.presets` (table, layout, points), :func:`diffguide.guideway.majda2012_carriage`
(the runner block) and :func:`diffguide.fe.table.majda2012_table` (mesh, nut patch).

Rail error (Majda 2012, eq. 4): ``i(s) = (Δ/2)(s/1 m + (s/1 m)²)``, ``Δ = 0.05 mm``, on

1. rail 1 vertical, rail 2 straight;
2. rail 1 horizontal, rail 2 straight;
3. rail 1 vertical, rail 2 horizontal.

Rail 1 is the rail at −Y. The rail coordinate ``s`` is measured along each rail from the point
under the table centre at the reference position (x = 0).
"""

from ..guideway.rails import AbstractRailProfile, PaperPolynomialRail, StraightRail
from .build import build_machine
from .equilibrium import Machine

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
    from ..io.config import default_config

    if law not in ("hertz", "rivin"):
        raise ValueError(f"law must be 'hertz' or 'rivin', got {law!r}")
    cfg = default_config()
    cfg["carriage"]["law"] = law
    return build_machine(
        cfg,
        thickness=thickness,
        E=E,
        preload_fraction=preload_fraction,
        nx=nx,
        ny=ny,
        points=points,
    )


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
