"""One rigid carriage on its rail: lift-off, stiffness, averaging, implicit gradients."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide.contact import HertzBall, PalmgrenRoller
from diffguide.guideway import (
    Carriage,
    element_offsets,
    four_row_carriage,
    majda2012_carriage,
    roller25_carriage,
)
from diffguide.guideway.rails import SinusoidalRail
from diffguide.guideway.solve import (
    TRANSLATION_ONLY,
    rail_under,
    solve_carriage,
    static_characteristics,
)


def two_opposed_rows(law, n=10, pitch=4e-3, per_element=40.0):
    """Two rows pressing the carriage up (+Z) and down (−Z): one opposed, preloaded pair."""
    return Carriage(
        law,
        row_yz=np.array([[0.0, 0.0], [0.0, -0.02]]),
        row_normals=np.array([[0.0, 1.0], [0.0, -1.0]]),
        xi=element_offsets(n, pitch),
        preload_force=per_element,
        eps_ratio=0.01,
    )


def _vertical_sweep(carriage, loads, free):
    """Upward load sweep (Z); returns tz (m) and the approaches of the row pushing down."""
    sols = jax.vmap(lambda F: solve_carriage(carriage, jnp.array([0, 0, F, 0, 0, 0.0]), free=free))(
        loads
    )
    assert bool(jnp.all(sols.converged))
    return sols


@pytest.mark.parametrize("law", [HertzBall(3e-3, 3.03e-3), PalmgrenRoller(6e-3)])
def test_opposed_rows_lift_off_at_theory(law):
    # Preload P per row; upward load F compresses the row pushing down (normal −Z) and unloads
    # the row pushing up, which lifts off when F = (2^α) P... with α = 3/2 (balls), 10/9 (rollers):
    # F = K((g0+δ)^α − (g0−δ)^α) reaches K(2g0)^α = 2^α P at δ = g0.
    c = two_opposed_rows(law)
    P = c.n_elements * c.preload_force
    loads = jnp.linspace(0.0, 4.0 * P, 801)
    sols = _vertical_sweep(c, loads, free=(2,))
    a_up_row = np.asarray(sols.approaches[:, 0, 0])  # the row with normal +Z unloads
    k = np.argmax(a_up_row <= 0.0)
    lift = np.interp(0.0, [a_up_row[k], a_up_row[k - 1]], [loads[k], loads[k - 1]])
    assert lift == pytest.approx(2**law.exponent * P, rel=0.02)


def test_opposed_rows_stiffness_is_twice_one_row():
    law = HertzBall(3e-3, 3.03e-3)
    c = two_opposed_rows(law)
    g0 = float(c.preload_approach)
    one_row = (
        c.n_elements * law.exponent * float(law.stiffness_constant()) * g0 ** (law.exponent - 1)
    )
    dF = 1.0
    sols = _vertical_sweep(c, jnp.array([-dF, dF]), free=(2,))
    k = 2 * dF / float(sols.pose[1, 2] - sols.pose[0, 2])
    assert k == pytest.approx(2 * one_row, rel=1e-6)


def test_four_row_block_lift_off_and_symmetry():
    # 45° rows: a downward load unloads the two lower rows when it reaches 2^(3/2) times the
    # vertical preload component of the upper rows, 2·n·F_el·cos 45°.
    c = majda2012_carriage()
    Pv = 2 * c.n_elements * c.preload_force * np.cos(np.pi / 4)
    loads = jnp.linspace(0.0, 4.0 * Pv, 801)
    sols = jax.vmap(
        lambda F: solve_carriage(c, jnp.array([0, 0, -F, 0, 0, 0.0]), free=TRANSLATION_ONLY)
    )(loads)
    a_lower = np.asarray(sols.approaches[:, 2, 0])
    k = np.argmax(a_lower <= 0.0)
    lift = np.interp(0.0, [a_lower[k], a_lower[k - 1]], [loads[k], loads[k - 1]])
    assert lift == pytest.approx(2**1.5 * Pv, rel=0.02)
    # the four-direction-equal design: 45° rows give the same stiffness down, up and lateral
    out = static_characteristics(c, jnp.linspace(0, 5000.0, 6))
    d = {name: np.asarray(v[0]) for name, v in out.items()}
    np.testing.assert_allclose(d["down"], d["up"], rtol=1e-8, atol=1e-15)
    np.testing.assert_allclose(d["down"], d["lateral"], rtol=1e-8, atol=1e-15)
    assert np.all(np.diff(d["down"]) > 0)


def _crest_and_slope_expectations(c, lam, A):
    u = np.asarray(c.xi)
    n, p = len(u), u[1] - u[0]
    Hz = np.sin(n * np.pi * p / lam) / (n * np.sin(np.pi * p / lam))
    k = 2 * np.pi / lam
    pitch_ratio = np.sum(u * np.sin(k * u)) / (k * np.sum(u**2))
    return A * Hz, A * k * pitch_ratio


@pytest.mark.parametrize("ratio", [0.5, 0.8, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0, 20.0])
def test_averaging_of_a_sinusoidal_rail(ratio):
    # a rigid carriage averages a rail e = A sin(2πs/λ) over its n elements
    c = majda2012_carriage()
    lam = ratio * c.length
    A = 1e-9  # small against g0 ≈ 2.5 µm: the linearized relation
    H, slope = _crest_and_slope_expectations(c, lam, A)
    load = jnp.zeros(6)
    crest = solve_carriage(c, load, rail_under(c, SinusoidalRail(A, lam, np.pi / 2), 0.0))
    assert abs(float(crest.pose[2]) - H) <= 0.01 * A
    node = solve_carriage(c, load, rail_under(c, SinusoidalRail(A, lam, 0.0), 0.0))
    # pitch θy: a point at +x moves by −θy·x, so the carriage's slope is −θy
    assert abs(-float(node.pose[4]) - slope) <= 0.01 * A * 2 * np.pi / lam
    assert bool(crest.converged) and bool(node.converged)


def _fd(f, x, h):
    return (f(x + h) - f(x - h)) / (2 * h)


def test_implicit_gradients_match_finite_differences():
    c = majda2012_carriage()
    lam = 0.05

    def pose(F, A, preload):
        cc = four_row_carriage(
            c.law,
            n=12,
            pitch=4e-3,
            capacity=22.8e3,
            preload_fraction=preload,
            upper_yz=(9e-3, -15e-3),
            lower_yz=(11.5e-3, -23e-3),
        )
        rail = rail_under(cc, SinusoidalRail(A, lam, 0.3), 0.0)
        load = jnp.array([0.0, 0.3 * F, -F, 2.0, 1.0, -0.5])
        return solve_carriage(cc, load, rail).pose

    x0 = (1500.0, 2e-6, 0.08)
    jac = jax.jacfwd(pose, argnums=(0, 1, 2))(*x0)
    steps = (1.0, 1e-8, 1e-4)
    for i, h in enumerate(steps):

        def f(v, i=i):
            args = list(x0)
            args[i] = v
            return np.asarray(pose(*args))

        fd = _fd(f, x0[i], h)
        got = np.asarray(jac[i])
        scale = np.max(np.abs(fd))
        assert np.max(np.abs(got - fd)) <= 1e-5 * scale, (i, got, fd)
    # and reverse mode agrees with forward mode
    vjp = jax.grad(lambda F: pose(F, x0[1], x0[2])[2])(x0[0])
    assert float(vjp) == pytest.approx(float(jac[0][2]), rel=1e-8)


def test_roller_block_is_stiffer_than_ball_block():
    ball = static_characteristics(majda2012_carriage(), jnp.array([0.0, 2000.0]))
    roller = static_characteristics(roller25_carriage(), jnp.array([0.0, 2000.0]))
    assert float(roller["down"][0][1]) < float(ball["down"][0][1])


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(n=0), "n .*>= 1"),
        (dict(pitch=-1e-3), "pitch must be > 0"),
        (dict(capacity=0.0), "capacity .*> 0"),
        (dict(preload_fraction=1.0), "preload_fraction must be in \\(0, 1\\)"),
        (dict(preload_fraction=1.5), "preload_fraction must be in \\(0, 1\\)"),
        (dict(contact_angle_deg=90.0), "contact_angle_deg must be in \\(0, 90\\)"),
        (dict(arrangement="Y"), "arrangement must be 'O' or 'X'"),
        (dict(eps_ratio=0.0), "eps_ratio must be in \\(0, 1\\)"),
    ],
)
def test_invalid_carriage_parameters(kwargs, match):
    base = dict(
        n=12,
        pitch=4e-3,
        capacity=22.8e3,
        preload_fraction=0.08,
        upper_yz=(9e-3, -15e-3),
        lower_yz=(11.5e-3, -23e-3),
    )
    base.update(kwargs)
    with pytest.raises(ValueError, match=match):
        four_row_carriage(HertzBall(3e-3, 3.03e-3), **base)


def test_invalid_solve_inputs():
    c = majda2012_carriage()
    with pytest.raises(ValueError, match="load must be a 6-vector"):
        solve_carriage(c, jnp.zeros(3))
    with pytest.raises(ValueError, match="rail must have shape"):
        solve_carriage(c, jnp.zeros(6), jnp.zeros((5, 2)))
    with pytest.raises(ValueError, match="free must be"):
        solve_carriage(c, jnp.zeros(6), free=(0, 1))
