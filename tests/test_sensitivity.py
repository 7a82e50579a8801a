"""Sensitivity studies: the traced carriage spacing (a moved mesh that equals a rebuilt one, its
derivative against finite differences of rebuilt machines), the roll spread and influence maps."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide.io.config import default_config, spec_from_config
from diffguide.machine.build import build_machine
from diffguide.machine.kinematics import joint_errors
from diffguide.machine.majda2012 import paper_variant
from diffguide.studies.sensitivity import (
    CORNERS,
    bump_centres,
    corner_roll,
    influence_map,
    roll_spread,
    spline_rails,
)

MESH = {"nx": 10, "ny": 5}
POSITIONS = jnp.linspace(-0.3, 0.3, 7)
RAILS = paper_variant(1)


def _rebuilt(spacing):
    """The coarse machine rebuilt from a configuration with carriages ±spacing/2 (m)."""
    cfg = default_config()
    cfg["guideway"]["carriage_x_mm"] = (-500 * spacing, 500 * spacing)
    return build_machine(spec_from_config(cfg), **MESH)


def _table_arrays(machine):
    t = machine.table
    return [t.K, t.f, t.R, t.r0, t.ref_points, machine.carriage_x]


@pytest.mark.parametrize("spacing", [0.32, 0.335])
def test_traced_spacing_gives_the_rebuilt_machine(spacing):
    moved = build_machine(carriage_spacing=jnp.asarray(spacing), **MESH)
    for a, b in zip(_table_arrays(moved), _table_arrays(_rebuilt(spacing))):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * float(jnp.max(jnp.abs(b))))


def test_spacing_that_crosses_a_grid_line_is_refused():
    # coarse grid lines at x = ±200 mm; footprint edges at ±190 mm would move to ±205 mm
    with pytest.raises(RuntimeError, match="carriage_spacing"):
        build_machine(carriage_spacing=0.35, **MESH)


def _spread(machine):
    return roll_spread(corner_roll(joint_errors(machine, RAILS, POSITIONS)))


def test_spacing_derivative_against_rebuilt_machines():
    spread = jax.jit(lambda s: _spread(build_machine(carriage_spacing=s, **MESH)))
    _, dD = jax.jvp(spread, (jnp.asarray(0.32),), (jnp.asarray(1.0),))
    h = 1e-5
    fd = (float(_spread(_rebuilt(0.32 + h))) - float(_spread(_rebuilt(0.32 - h)))) / (2 * h)
    assert abs(fd) > 1.0  # µrad/m: the spread does depend on the spacing
    assert float(dD) == pytest.approx(fd, rel=1e-5)


def test_roll_spread_definition():
    roll = jnp.array([[1.0, 1.0, 3.0, 3.0], [0.0, 0.0, 0.0, 0.0]]) * 1e-6
    # deviations from the mean ±1 µrad at the first position, 0 at the second
    assert float(roll_spread(roll)) == pytest.approx(np.sqrt(0.5))
    assert float(roll_spread(jnp.ones((5, 4)) * 3e-6)) == 0.0


def test_influence_map_matches_a_finite_difference_and_the_carriage_geometry():
    machine = build_machine(**MESH)
    rails = spline_rails(RAILS, start=-0.6, stop=0.6, spacing=0.04)
    s = np.linspace(-0.5, 0.5, 11)
    np.testing.assert_allclose(rails[0](s)[1], RAILS[0](s)[1], atol=1e-12)
    x = jnp.array([-0.2, 0.2])
    J = np.asarray(influence_map(machine, rails, x))
    assert J.shape == (2, 4, rails[0].n_coeffs)
    centres = bump_centres(rails[0])
    # one column against a central difference of the coefficient (1 µm bump = 1e-6 m)
    k = int(np.argmin(abs(centres - 0.36)))  # under the +160 mm carriage at x = 0.2
    h = 1e-8

    def roll(dc):
        r1 = type(rails[0])(
            rails[0].start, rails[0].spacing, rails[0].vertical.at[k].add(dc), rails[0].horizontal
        )
        return np.asarray(corner_roll(joint_errors(machine, (r1, rails[1]), x)))

    fd = (roll(h) - roll(-h)) / (2 * h)
    np.testing.assert_allclose(J[:, :, k], fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    # a bump that no carriage reaches at these positions or at x_ref does nothing
    far = np.abs(centres) > 0.2 + 0.16 + 0.022 + 2 * rails[0].spacing
    assert np.abs(J[:, :, far]).max() < 1e-12
    # the bump under the +x carriage (x = 0.2) rolls the +x corners (P1, P4) far more
    P = {n: i for i, n in enumerate(CORNERS)}
    assert abs(J[1, P["P1"], k]) > 5 * abs(J[1, P["P2"], k])
    assert abs(J[1, P["P4"], k]) > 5 * abs(J[1, P["P3"], k])
