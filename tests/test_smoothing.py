"""The compression-only smoothed element law."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide.contact import HertzBall, PalmgrenRoller
from diffguide.contact.smoothing import element_energy, element_force, element_stiffness

LAWS = [HertzBall(3e-3, 3.03e-3), PalmgrenRoller(6e-3)]


@pytest.mark.parametrize("law", LAWS)
def test_zero_force_beyond_lift_off_and_exact_at_preload(law):
    P = 38.0
    g0 = float(law.preload_approach(P))
    eps = 0.02 * g0
    K, alpha = law.stiffness_constant(), law.exponent
    for k in (1.0, 2.0, 3.0, 10.0, 1e3):
        assert abs(float(element_force(-k * eps, K, alpha, eps))) <= 1e-12 * P
    # at preload the smoothed force equals the unsmoothed law (here to rounding; issue: 0.1 %)
    assert float(element_force(g0, K, alpha, eps)) == pytest.approx(P, rel=1e-3)
    assert float(element_force(g0, K, alpha, eps)) == pytest.approx(float(law.force(g0)), rel=1e-12)


@pytest.mark.parametrize("law", LAWS)
def test_gradients_finite_at_and_beyond_lift_off(law):
    g0 = float(law.preload_approach(38.0))
    eps = 0.02 * g0
    K, alpha = law.stiffness_constant(), law.exponent
    a = jnp.array([-1e3 * eps, -2 * eps, -eps, -0.5 * eps, 0.0, 0.5 * eps, eps, g0])
    for fn in (element_force, element_stiffness, element_energy):
        f = lambda x: fn(x, K, alpha, eps)  # noqa: E731
        d1 = jax.vmap(jax.grad(f))(a)
        d2 = jax.vmap(jax.grad(jax.grad(f)))(a)
        assert np.all(np.isfinite(d1)) and np.all(np.isfinite(d2))
    # consistency: dφ/da = F and dF/da = stiffness, everywhere
    dphi = jax.vmap(jax.grad(lambda x: element_energy(x, K, alpha, eps)))(a)
    np.testing.assert_allclose(dphi, element_force(a, K, alpha, eps), rtol=1e-12, atol=1e-12 * 38)
    dF = jax.vmap(jax.grad(lambda x: element_force(x, K, alpha, eps)))(a)
    np.testing.assert_allclose(dF, element_stiffness(a, K, alpha, eps), rtol=1e-12, atol=1e-6)


def test_energy_matches_numerical_integral_of_force():
    law = LAWS[0]
    g0 = float(law.preload_approach(38.0))
    eps = 0.02 * g0
    K, alpha = law.stiffness_constant(), law.exponent
    a = np.linspace(-2 * eps, 1.5 * g0, 200001)
    F = np.asarray(element_force(jnp.asarray(a), K, alpha, eps))
    integral = np.sum(0.5 * (F[1:] + F[:-1]) * np.diff(a))
    assert float(element_energy(a[-1], K, alpha, eps)) == pytest.approx(integral, rel=1e-8)
