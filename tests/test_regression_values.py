"""Regression pins: the figures the README and the notebooks state, stored as literal values.

These tests are *regression pins*, not validation: the literals below are the numbers the README
(the Hertz figures, the block's preload approach, stiffness and lift-off load, the roller/ball
ratios, the paper-findings table of the Validation section) and the executed notebooks print,
and they were produced by this code. They catch an unintended change of any of those numbers —
a units slip, a changed preset value, a changed default — which the ratio- and sign-based
physics tests let through. The independent check of the assembled machine is the CalculiX
reference (``tests/test_calculix_reference.py``).

Tolerance: 2 % of the value, or 0.6 units of the last digit printed where the figure is given
with fewer significant digits than that (so rounding in the README never fails a test); a 10 %
change of any pinned value fails.
"""

import jax.numpy as jnp
import numpy as np
import pytest

import diffguide as dg

paper_variant = dg.paper_variant

REL = 0.02


def pin(value: float, expected: float, decimals: int) -> None:
    """``value`` within 2 % of ``expected`` (or 0.6 units of its last printed digit)."""
    tol = max(REL * abs(expected), 0.6 * 10.0**-decimals)
    assert tol < 0.1 * abs(expected) or expected == 0.0, "the pin would not catch a 10 % change"
    assert abs(value - expected) <= tol, f"{value!r} is not {expected} ± {tol:.3g}"


# --------------------------------------------------------------------------------------------
# the contact law and the size-25 ball block (README "contact law" section)
# --------------------------------------------------------------------------------------------


def test_hertz_ball_figures():
    hertz = dg.HertzBall(3e-3, 3.03e-3, 210e9, 0.3)
    rivin = dg.RivinBall(3e-3, 3.03e-3)
    per_contact = lambda law, F: float(law.contact_compliance()) * F ** (2 / 3) * 1e6  # noqa: E731
    pin(per_contact(hertz, 10.0), 0.514, 3)  # µm per contact at 10 N
    pin(per_contact(hertz, 100.0), 2.385, 3)  # µm at 100 N
    pin(per_contact(rivin, 10.0), 2.71, 2)  # the paper's Rivin form
    pin(float(rivin.compliance() / hertz.compliance()), 5.28, 2)


@pytest.fixture(scope="module")
def block():
    return dg.majda2012_carriage()


def test_block_preload_approach_and_initial_stiffness(block):
    pin(float(block.preload_approach) * 1e6, 2.50, 2)  # g0, µm
    loads = jnp.array([0.0, 1.0])
    d = np.asarray(dg.static_characteristics(block, loads)["down"][0])
    pin(1.0 / (d[1] - d[0]) * 1e-6, 546.0, 0)  # N/µm at zero load


def test_block_lift_off_load(block):
    # the load at which the lower rows' approach reaches zero under a downward load (kN)
    loads = jnp.linspace(1500.0, 2200.0, 141)
    sols = dg.static_characteristics(block, loads)["down"][1]
    a_lower = np.asarray(sols.approaches[:, 2, 0])
    k = int(np.argmax(a_lower <= 0.0))
    lift = np.interp(0.0, [a_lower[k], a_lower[k - 1]], [float(loads[k]), float(loads[k - 1])])
    pin(lift * 1e-3, 1.82, 2)


def test_roller_block_stiffness_ratios(block):
    roller = dg.roller25_carriage()

    def deflection(carriage):  # down, at 0, 1 N and 10 kN (m)
        loads = jnp.array([0.0, 1.0, 10e3])
        return np.asarray(dg.static_characteristics(carriage, loads)["down"][0])

    b, r = deflection(block), deflection(roller)
    pin((b[1] - b[0]) / (r[1] - r[0]), 5.4, 1)  # initial (tangent) stiffness ratio
    pin((b[2] - b[0]) / (r[2] - r[0]), 3.6, 1)  # secant stiffness ratio at 10 kN


# --------------------------------------------------------------------------------------------
# the paper's findings on majda2012 (README Validation table; notebooks/01_paper_reproduction)
# --------------------------------------------------------------------------------------------

POSITIONS = np.linspace(-0.35, 0.35, 71)  # the notebook's sweep over the 700 mm stroke
P5, CORNERS = 4, slice(0, 4)
EXX, EYX, EZX, EAX, ECX = 0, 1, 2, 3, 5


@pytest.fixture(scope="module")
def paper():
    """Peak-to-peak ranges (points, 6) in µm / µrad and the roll curves, per variant."""
    machine = dg.majda2012_machine()
    out = {}
    for v in (1, 2, 3):
        je = dg.joint_errors(machine, paper_variant(v), POSITIONS)
        assert bool(je.converged.all())
        e = je.user_units()
        out[v] = (np.ptp(e, axis=0), e[:, :, EAX])
    return out


# variant: (max EZX, max EYX, EXX at P5, yaw min, yaw max, roll max, corner roll min), README
PAPER_TABLE = {
    1: ((30.8, 1), (5.4, 1), (0.88, 2), (3.17, 2), (3.17, 2), (70.5, 1), (32.5, 1)),
    2: ((3.1, 1), (17.3, 1), (0.19, 2), (16.4, 1), (18.6, 1), (25.6, 1), (16.7, 1)),
    3: ((25.7, 1), (22.5, 1), (0.55, 2), (19.4, 1), (21.5, 1), (94.0, 1), (16.3, 1)),
}


@pytest.mark.parametrize("variant", [1, 2, 3])
def test_paper_findings_table(paper, variant):
    ranges, _ = paper[variant]
    got = (
        ranges[:, EZX].max(),
        ranges[:, EYX].max(),
        ranges[P5, EXX],
        ranges[:, ECX].min(),
        ranges[:, ECX].max(),
        ranges[:, EAX].max(),
        ranges[CORNERS, EAX].min(),
    )
    for value, (expected, decimals) in zip(got, PAPER_TABLE[variant], strict=True):
        pin(float(value), expected, decimals)


def test_variant2_roll_at_centre_is_near_zero(paper):
    ranges, _ = paper[2]
    assert ranges[P5, EAX] <= 0.05  # README: 0.01 µrad (against 16.7 at the smallest corner)


def test_roll_left_after_compensating_with_p1(paper):
    # notebook 01: the largest |EAX(Pj) - EAX(P1)| over the stroke, µrad
    expected = {1: 19.0, 2: 31.8, 3: 32.2}
    for v, value in expected.items():
        roll = paper[v][1]
        pin(float(np.abs(roll[:, 1:] - roll[:, :1]).max()), value, 1)


# --------------------------------------------------------------------------------------------
# notebooks/03_sensitivity: the corner-roll spread D of variant 1
# --------------------------------------------------------------------------------------------


def test_corner_roll_spread_and_roll_ranges():
    machine = dg.build_machine(dg.spec_from_config(dg.default_config()))
    positions = np.linspace(-0.35, 0.35, 36)  # the notebook's sweep
    je = dg.joint_errors(machine, paper_variant(1), positions)
    roll = je.user_units()[:, CORNERS, EAX]  # µrad, P1..P4
    spread = np.sqrt(np.mean((roll - roll.mean(axis=1, keepdims=True)) ** 2))
    pin(float(spread), 5.626, 3)  # D, µrad
    for value, expected in zip(np.ptp(roll, axis=0), (70.4, 32.5, 32.6, 70.3), strict=True):
        pin(float(value), expected, 1)
