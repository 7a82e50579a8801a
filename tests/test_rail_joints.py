"""Rail joints: a step per profile at a stated joint (``fit_rails(joints=...)``,
``diffguide fit --rail-joints-mm``), checked against closed forms: the smoothed step's values
and derivatives, the step's gradient, the curvature penalty that does not charge it, and the
refusals. The fit recovering a step and predicting through it is the battery's
``rail_joint_step`` case (test_battery.py); the prediction's σ with a joint, test_predict.py."""

import argparse

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide.cli.fit import _joints_mm
from diffguide.guideway.rails import SplineRail, SteppedRail, basis_rail, joint_ramp
from diffguide.inverse.basis import RailBasis
from diffguide.inverse.settings import rail_joints
from diffguide.io.config import validate_config

W = 5e-3


def test_the_ramp_is_a_twice_differentiable_unit_step():
    """0 before ``s_j − w/2``, 1 after ``s_j + w/2``, ½ at ``s_j``, ``H(s_j+d) + H(s_j−d) = 1``;
    slope ``15/(8w)`` at the centre (``H'(u) = 30u²(1−u)²`` at u = ½) and zero first and
    second derivatives at both ends."""
    s0 = 0.137
    s = np.array([s0 - 0.1, s0 - W / 2, s0, s0 + W / 2, s0 + 0.1])
    np.testing.assert_allclose(joint_ramp(s, (s0,), W, xp=np)[:, 0], [0, 0, 0.5, 1, 1],
                               atol=1e-15)
    d = np.linspace(0, W, 7)
    np.testing.assert_allclose(joint_ramp(s0 + d, (s0,), W, xp=np)
                               + joint_ramp(s0 - d, (s0,), W, xp=np), 1.0, atol=1e-15)
    H = jax.vmap(lambda x: joint_ramp(x, (s0,), W)[0])
    dH = jax.vmap(jax.grad(lambda x: joint_ramp(x, (s0,), W)[0]))
    d2H = jax.vmap(jax.grad(jax.grad(lambda x: joint_ramp(x, (s0,), W)[0])))
    ends = jnp.array([s0 - W / 2, s0 + W / 2])
    np.testing.assert_allclose(dH(jnp.array([s0])), 15 / (8 * W), rtol=1e-12)
    np.testing.assert_allclose(dH(ends), 0.0, atol=1e-9)
    np.testing.assert_allclose(d2H(ends), 0.0, atol=1e-6 / W**2)
    # two joints: the last axis holds one step each
    two = joint_ramp(np.array([0.0, 0.2]), (0.1, 0.15), W, xp=np)
    np.testing.assert_array_equal(two, [[0, 0], [1, 1]])
    assert H(jnp.array([s0])).shape == (1,)


def test_a_stepped_rail_is_its_spline_plus_the_steps():
    spline = SplineRail(-0.5, 0.1, jnp.linspace(0, 1e-6, 13), jnp.linspace(1e-6, 0, 13))
    rail = SteppedRail(spline, (0.0, 0.2), W, jnp.array([3e-6, -1e-6]), jnp.array([2e-6, 0.0]))
    s = jnp.array([-0.3, 0.1, 0.35])  # before both, between, after both
    ey, ez = rail(s)
    sy, sz = spline(s)
    np.testing.assert_allclose(ez - sz, [0, 3e-6, 2e-6], atol=1e-18)
    np.testing.assert_allclose(ey - sy, [0, 2e-6, 2e-6], atol=1e-18)
    # the step height's gradient is the unit step
    g = jax.grad(lambda h: rail.__class__(spline, rail.joints, W, h, rail.horizontal_steps)(
        jnp.array(0.35))[1])(rail.vertical_steps)
    np.testing.assert_allclose(g, [1.0, 1.0])
    # the layout of the fit's unknowns: spline coefficients, then the steps
    c = jnp.concatenate([spline.vertical, rail.vertical_steps])
    d = jnp.concatenate([spline.horizontal, rail.horizontal_steps])
    same = basis_rail(-0.5, 0.1, c, d, (0.0, 0.2), W)
    np.testing.assert_allclose(same(s)[1], ez, atol=1e-18)
    assert isinstance(basis_rail(-0.5, 0.1, spline.vertical, spline.horizontal), SplineRail)
    with pytest.raises(ValueError, match="one per joint"):
        SteppedRail(spline, (0.0,), W, jnp.zeros(2), jnp.zeros(2))


def test_the_basis_carries_one_uncharged_step_per_profile_and_joint():
    plain = RailBasis.covering(-0.5, 0.5, 0.05)
    basis = RailBasis.covering(-0.5, 0.5, 0.05, joints=(0.137,))
    n = plain.n_coeffs
    assert basis.n_coeffs == n and basis.per_profile == n + 1 and basis.size == 4 * (n + 1)
    s = np.linspace(-0.5, 0.5, 101)
    M = basis.matrix(s)
    np.testing.assert_array_equal(M[:, :n], plain.matrix(s))
    np.testing.assert_array_equal(M[:, n], s > 0.137 + W / 2 - 1e-12)  # no sample in the rise
    # ∫e''² does not see a step, and sees the spline part as before
    G, G_plain = basis.penalty_factor(), plain.penalty_factor()
    step = np.zeros(basis.size)
    step[n::n + 1] = 1e-6
    assert np.all(G @ step == 0.0)
    c = np.random.default_rng(0).normal(size=plain.size)
    c_j = np.insert(c.reshape(4, n), n, 0.0, axis=1).ravel()
    np.testing.assert_allclose(G @ c_j, G_plain @ c, rtol=1e-12)
    # ∫e²/ℓ⁴ does: a unit step over the last (0.5 − 0.137) m of a 1 m rail
    G0 = basis.amplitude_factor()
    np.testing.assert_allclose(np.sum((G0 @ (step / 1e-6)) ** 2) / 4, 0.5 - 0.137, rtol=0.02)
    # the gauge: the mean of a profile that is a pure step is the step times its share
    C, _ = basis.gauge_functionals((True, True))
    assert C.shape[1] == basis.size
    np.testing.assert_allclose(C[0, n], np.mean(basis.matrix(basis.grid(801))[:, n]))


@pytest.mark.parametrize(
    ("joints", "width", "match"),
    [((0.6,), W, "not inside the fitted rail range"),
     ((0.499,), W, "by half the step width"),
     ((0.1, 0.102), W, "at least the step width"),
     ((0.2, 0.1), W, "must increase"),
     ((float("nan"),), W, "not inside"),
     ((0.1,), 0.0, "joint_width must be a finite width > 0")],
)
def test_bad_joints_are_refused_naming_the_joint(joints, width, match):
    with pytest.raises(ValueError, match=match):
        RailBasis.covering(-0.5, 0.5, 0.05, joints=joints, joint_width=width)


def test_the_joints_from_the_command_line_and_the_config():
    assert _joints_mm("137") == (137.0,)
    assert _joints_mm("437,-63.5") == (437.0, -63.5)
    for bad in ("a", "1,,2", "nan"):
        with pytest.raises(argparse.ArgumentTypeError):
            _joints_mm(bad)
    cfg = validate_config({"fit": {"rail_joints_mm": [437, -63.5]}}, "m.toml")
    assert rail_joints(cfg) == (-0.0635, 0.437)  # m, increasing
    assert rail_joints(cfg, (137.0,)) == (0.137,)  # the flag wins
    assert rail_joints(validate_config({}, "m.toml")) == ()
    with pytest.raises(ValueError, match="key 'fit.rail_joints_mm': must be a list of numbers"):
        validate_config({"fit": {"rail_joints_mm": 137}}, "m.toml")
    with pytest.raises(ValueError, match="outside the allowed range"):
        validate_config({"fit": {"rail_joints_mm": [1e9]}}, "m.toml")
