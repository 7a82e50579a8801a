"""The elastic machine's Newton solve on the carriages' contact DOF (the quadratic DOF condensed
exactly) against the uncondensed potential written out here, its screw-stiffness derivative
against finite differences, and the Newton loop's stopping rule against closed forms."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide._core.newton import solve_equilibrium
from diffguide._core.result import RESULTS
from diffguide.machine import equilibrium
from diffguide.machine.kinematics import joint_errors
from diffguide.machine.majda2012 import majda2012_machine, paper_variant

POSITIONS = jnp.array([-0.32, -0.1, 0.0, 0.17, 0.33])  # x = 0: k_s(x) = k_s(0), β = 0


@pytest.fixture(scope="module", params=["weight", "feed force"])
def machine(request):
    m = majda2012_machine(nx=10, ny=5)
    if request.param == "feed force":
        # 800 N along X on the first carriage's patch (a cutting force): without an X load the
        # screw carries nothing and k_s(x) has no influence
        m = eqx.tree_at(lambda m: m.table.f, m, m.table.f.at[0].add(800.0))
    return m


def _full_potential(machine, rails, x, u):
    """Π(u) (J) over all 30 interface DOF (m, rad), from the public pieces: no condensation."""
    n = machine.n_carriages
    rail = machine.rail_under_carriages(x, rails)
    a = jax.vmap(machine.carriage.approaches)(u[: 6 * n].reshape(n, 6), rail)
    nut = u[6 * n]
    return (
        0.5 * u @ machine.table.K @ u
        - machine.table.f @ u
        + machine.carriage.energy(a)
        + 0.5 * machine.screw_stiffness(x) * nut**2
    )


def test_condensed_solution_is_the_full_potentials_minimum(machine):
    rails = paper_variant(3)
    state = equilibrium(machine, rails, POSITIONS)
    assert bool(jnp.all(state.converged))
    scale = jnp.full(30, 1e-6)  # µm, µrad
    for x, u in zip(POSITIONS, state.interface):
        # Newton's correction of the full, uncondensed problem from the condensed solution
        # (autodiff gradient and Hessian in µm, µrad): round-off sized
        def pot(y, x=x, u=u):
            return _full_potential(machine, rails, x, u + y * scale)

        g = jax.grad(pot)(jnp.zeros(30))
        H = jax.hessian(pot)(jnp.zeros(30))
        assert np.all(np.linalg.eigvalsh(np.asarray(H)) > 0)  # a strict minimum
        step = np.linalg.solve(np.asarray(H), -np.asarray(g))
        assert np.max(np.abs(step)) < 1e-8, (float(x), np.max(np.abs(step)))


def test_screw_stiffness_derivative_against_finite_differences(machine):
    # the screw's k_s(x) = EA/(L0 + x) enters the condensation through Sherman–Morrison
    if float(machine.table.f[0]) == 0.0:
        pytest.skip("no X load: the errors do not depend on the screw")
    rails = paper_variant(3)
    ea = float(machine.screw_EA)

    def errors(ea):
        m = eqx.tree_at(lambda m: m.screw_EA, machine, ea)
        return joint_errors(m, rails, POSITIONS, x_ref=0.2).errors

    f = jax.jit(errors)
    _, jv = jax.jvp(f, (ea,), (ea,))  # d/d(log EA)
    h = 1e-5
    fd = (np.asarray(f(ea * (1 + h))) - np.asarray(f(ea * (1 - h)))) / (2 * h)
    scale = np.max(np.abs(fd))
    assert scale > 0
    assert np.max(np.abs(np.asarray(jv) - fd)) <= 1e-4 * scale


def _exp_potential(y, b):
    return jnp.sum(jnp.exp(y) - b * y)


def _exp_grad_hess(y, b):
    return jnp.exp(y) - b, jnp.diag(jnp.exp(y))


def test_newton_stop_quadratic_convergence_exact_to_round_off():
    # Π = Σ exp(y) − b·y: y* = log b; quadratic convergence, the confirming step is skipped
    b = jnp.array([0.5, 1.2, 1.7])  # full steps pass the Armijo test from 0
    y, result, steps = solve_equilibrium(_exp_potential, _exp_grad_hess, jnp.zeros(3), b, tol=1e-9)
    assert result == RESULTS.successful
    np.testing.assert_allclose(y, np.log(np.asarray(b)), rtol=0, atol=1e-13)
    # plain Newton in NumPy: steps until a step is below tol (the old rule)
    z, k = np.zeros(3), 0
    while True:
        s = (np.exp(z) - np.asarray(b)) / np.exp(z)
        z, k = z - s, k + 1
        if np.max(np.abs(s)) <= 1e-9:
            break
    assert int(steps) < k


def _quartic_potential(y, c):
    return jnp.sum((y - c) ** 4) / 4


def _quartic_grad_hess(y, c):
    return (y - c) ** 3, jnp.diag(3 * (y - c) ** 2)


def test_newton_stop_not_extrapolated_under_linear_convergence():
    # Π = Σ (y − c)⁴/4: a singular Hessian at y* = c, Newton converges only linearly
    # (y − c → ⅔(y − c)); the quadratic extrapolation must not end the loop early: the same
    # steps and result as plain Newton in NumPy stopped at the first step below tol
    c = jnp.array([0.3, -1.1])
    tol = 1e-6
    y, result, steps = solve_equilibrium(
        _quartic_potential, _quartic_grad_hess, jnp.zeros(2), c, tol=tol, max_steps=200
    )
    assert result == RESULTS.successful
    z, k = np.zeros(2), 0
    while True:
        s = -(z - np.asarray(c)) / 3
        z, k = z + s, k + 1
        if np.max(np.abs(s)) <= tol:
            break
    assert int(steps) == k
    np.testing.assert_allclose(y, z, rtol=1e-12)


def test_condensed_and_full_newton_agree_with_derivatives(machine):
    # Newton on the contact DOF (the quadratic DOF condensed) and on all 30 interface DOF:
    # the same solution, and the same derivative w.r.t. the table loads
    rails = paper_variant(3)

    def interface(scale, condensed):
        m = eqx.tree_at(lambda m: m.table.f, machine, machine.table.f * scale)
        return equilibrium(m, rails, POSITIONS, condensed=condensed).interface

    a, da = jax.jvp(lambda s: interface(s, True), (1.0,), (1.0,))
    b, db = jax.jvp(lambda s: interface(s, False), (1.0,), (1.0,))
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * float(jnp.max(jnp.abs(b))))
    np.testing.assert_allclose(da, db, rtol=0, atol=1e-9 * float(jnp.max(jnp.abs(db))))


def test_newton_stop_at_lift_off_within_tol_of_a_tight_solve(monkeypatch):
    # The extrapolated stop assumes the quadratic rate holds for one more step; where a
    # compression-only element lifts off the tangent changes within a step. Roller carriages at
    # 2 % preload with a sharp law (smoothing 0.2 % of the approach) and bumps up to 12× the
    # preload approach, which unload whole rows: the default solve (tol 1e-9 µm / µrad) against
    # Newton without the extrapolated stop at tol 1e-13 — within the default tol everywhere
    # (measured: 7e-18 to 2.1e-16 m against 1e-15 m).
    from diffguide._core import newton
    from diffguide.guideway.rails import BumpRail, SinusoidalRail
    from diffguide.io.config import default_config, spec_from_config
    from diffguide.machine.build import build_machine
    from diffguide.machine.equilibrium import equilibrium_traced

    cfg = default_config()
    cfg["carriage"].update(law="roller", preload_fraction=0.02, smoothing_fraction=0.002)
    cfg["table"].update(mesh_nx=8, mesh_ny=4)
    m = build_machine(spec_from_config(cfg))
    g0 = float(m.carriage.preload_approach)
    xs = jnp.linspace(-0.3, 0.3, 31)

    def rails(amp):
        return (BumpRail(jnp.asarray(amp * g0), jnp.asarray(-0.05), jnp.asarray(0.02)),
                SinusoidalRail(jnp.asarray(3e-6), jnp.asarray(0.17), jnp.asarray(0.4),
                               "horizontal"))

    amps = (1.0, 3.0, 6.0, 12.0)
    rule = eqx.filter_jit(lambda r: equilibrium_traced(m, r, xs))
    got = [rule(rails(a)) for a in amps]
    monkeypatch.setattr(newton, "_PREDICTED", 0.0)  # read when traced: a new function
    tight = eqx.filter_jit(lambda r: equilibrium_traced(m, r, xs, tol=1e-13, max_steps=100))
    ref = [tight(rails(a)) for a in amps]
    for a, s, r in zip(amps, got, ref):
        assert bool(jnp.all(s.converged)) and bool(jnp.all(r.converged)), a
        err = float(jnp.max(jnp.abs(s.interface - r.interface)))  # m, rad
        assert err <= 1e-9 * 1e-6, (a, err)  # tol 1e-9 µm / µrad
    lifted = float(jnp.mean(got[-1].forces <= 1e-9 * float(jnp.max(got[-1].forces))))
    assert lifted > 0.05, lifted  # the largest bump does unload elements
