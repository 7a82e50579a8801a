"""Derivatives of every order through the equilibrium solves.

The implicit function theorem gives the first derivative of a root ``y*(θ)`` of ``g(y, θ) = 0``;
a second derivative differentiates that tangent again, ``y*`` and ``H = ∂g/∂y`` included. A
tangent computed on stopped-gradient copies of ``y*`` and ``H`` is right at first order and
silently wrong at the second (``jax.hessian`` of Σ roll² w.r.t. a rail amplitude once gave −99
where the derivative of the exact gradient is +625). References here: a closed form (two
opposed Hertz rows) and central differences of the exact first derivative (``jax.grad``, itself
checked against differences of values in ``test_machine.py``), at preload and near lift-off.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide.contact import HertzBall
from diffguide.guideway import Carriage, element_offsets
from diffguide.guideway.rails import SplineRail
from diffguide.guideway.solve import solve_carriage
from diffguide.machine.kinematics import joint_errors
from diffguide.machine.majda2012 import majda2012_machine

LAW = HertzBall(3e-3, 3.03e-3)


def _opposed_rows(n=10, per_element=40.0):
    """One opposed, preloaded pair of ball rows (up and down), as in ``test_guideway.py``."""
    return Carriage(
        LAW,
        row_yz=np.array([[0.0, 0.0], [0.0, -0.02]]),
        row_normals=np.array([[0.0, 1.0], [0.0, -1.0]]),
        xi=element_offsets(n, pitch=4e-3),
        preload_force=per_element,
        eps_ratio=0.01,
    )


def _tz(carriage, F):
    """Vertical displacement (µm) of the carriage under an upward load ``F`` (N)."""
    load = jnp.zeros(6).at[2].set(F)
    return solve_carriage(carriage, load, free=(2,)).pose[2] * 1e6


def test_second_derivative_of_two_opposed_rows_is_the_closed_form():
    # Both rows loaded: F(δ) = nK((g0+δ)^α − (g0−δ)^α); the inverse function's derivatives are
    # δ' = 1/F'(δ), δ'' = −F''(δ)/F'(δ)³ (closed forms of the Hertz law, not of the solver).
    c = _opposed_rows()
    n, a = c.n_elements, LAW.exponent  # elements per row
    K, g0 = float(LAW.stiffness_constant()), float(c.preload_approach)
    F = 1.6 * n * c.preload_force  # both rows still carry load (lift-off at 2^α n P = 2.8 nP)
    delta = float(_tz(c, F)) * 1e-6
    F1 = n * K * a * ((g0 + delta) ** (a - 1) + (g0 - delta) ** (a - 1))
    F2 = n * K * a * (a - 1) * ((g0 + delta) ** (a - 2) - (g0 - delta) ** (a - 2))
    second = float(jax.grad(jax.grad(lambda f: _tz(c, f)))(F)) * 1e-6
    assert second == pytest.approx(-F2 / F1**3, rel=1e-3)
    assert float(jax.hessian(lambda f: _tz(c, f))(F)) * 1e-6 == pytest.approx(second, rel=1e-9)


@pytest.mark.parametrize("fraction", [0.5, 2**1.5 * 0.98, 2**1.5 * 1.05])
def test_second_derivative_at_and_past_lift_off_is_the_derivative_of_the_gradient(fraction):
    # through the smoothed lift-off of the row pushing up (at 2^α P): finite, and the derivative
    # of the exact first derivative
    c = _opposed_rows()
    F = fraction * c.n_elements * c.preload_force
    g = jax.jit(jax.grad(lambda f: _tz(c, f)))
    h = 1e-3 * c.preload_force
    fd = (float(g(F + h)) - float(g(F - h))) / (2 * h)
    forward = float(jax.jvp(g, (F,), (1.0,))[1])
    reverse = float(jax.jacrev(jax.jacfwd(lambda f: _tz(c, f)))(F))
    assert np.isfinite(forward) and np.isfinite(reverse)
    assert forward == pytest.approx(fd, rel=1e-4, abs=1e-6 * abs(float(g(F))) / F)
    assert reverse == pytest.approx(forward, rel=1e-9)


# ---------------------------------------------------------------------------------------------
# the machine: condensed table, four carriages, the implicit root of the full potential

POSITIONS = jnp.linspace(-0.3, 0.3, 5)
N = 15


def _objective(p, base, shape, scale):
    """Σ roll² + Σ EZX² (µrad², µm²) over the points and positions, as a function of
    ``(thickness (m), preload fraction, rail amplitude a)``; rails ``scale·(base + a·shape)``."""
    m = majda2012_machine(nx=8, ny=4, thickness=p[0], preload_fraction=p[1])
    c = scale * (base + p[2] * 1e-6 * shape)
    r1 = SplineRail(-0.6, 0.1, c[:N], c[N : 2 * N])
    r2 = SplineRail(-0.6, 0.1, c[2 * N : 3 * N], c[3 * N :])
    je = joint_errors(m, (r1, r2), POSITIONS)
    return jnp.sum((je.errors[:, :, 3] * 1e6) ** 2) + jnp.sum((je.errors[:, :, 2] * 1e6) ** 2)


def test_machine_hessian_is_the_derivative_of_the_gradient():
    # rails 8× a 3 µm coefficient scatter: 40 % of the elements carry less than 5 % of the
    # median element force (measured), so the Hessian crosses lift-offs; at 1× it agrees to 1e-8
    scale = 8.0
    rng = np.random.default_rng(1)
    base = jnp.asarray(rng.normal(scale=3e-6, size=4 * N))
    shape = jnp.asarray(rng.normal(size=4 * N))
    p0 = jnp.array([0.05, 0.05, 1.0])
    f = jax.jit(lambda p: _objective(p, base, shape, scale))
    grad = jax.jit(jax.grad(f))
    H = np.asarray(jax.jit(jax.hessian(f))(p0))
    steps = np.array([1e-6, 1e-6, 1e-3])
    fd = np.stack([
        (np.asarray(grad(p0.at[i].add(steps[i]))) - np.asarray(grad(p0.at[i].add(-steps[i]))))
        / (2 * steps[i])
        for i in range(3)
    ])
    assert np.all(np.isfinite(H))
    # every entry, to 1e-5 of the largest in its row (rows differ in units by 10⁴)
    scale_row = np.max(np.abs(fd), axis=1, keepdims=True)
    assert np.all(np.abs(H - fd) <= 1e-5 * scale_row), (H, fd)


def test_ellipticity_second_derivative_is_the_derivative_of_its_gradient():
    # ln(a/b) of the Hertz ellipse is a root found by bisection; its second derivative in the
    # curvature ratio against a central difference of the (implicit) first derivative
    from diffguide.contact.hertz import ellipticity

    g = jax.grad(ellipticity)
    for ratio in (1.5, 20.0):
        h = 1e-5 * ratio
        fd = (float(g(ratio + h)) - float(g(ratio - h))) / (2 * h)
        assert float(jax.grad(g)(ratio)) == pytest.approx(fd, rel=1e-6)
    assert float(g(1.0)) == 0.0
