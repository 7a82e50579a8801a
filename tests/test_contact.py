"""Contact laws against closed forms and an independent elliptic-integral evaluation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import optimize, special

from diffguide.contact import HertzBall, PalmgrenRoller, RivinBall
from diffguide.contact.hertz import hamrock_brewe, point_contact

E, NU = 210e9, 0.3
E_STAR = E / (2 * (1 - NU**2))  # two steel bodies


@pytest.mark.parametrize("F", [1.0, 10.0, 123.0, 5000.0])
@pytest.mark.parametrize("R", [1e-3, 7.5e-3, 0.1])
def test_sphere_on_flat_closed_form(F, R):
    # Johnson (4.23): δ = (9F²/(16 R E*²))^(1/3), a = (3FR/(4E*))^(1/3)
    out = point_contact(F, 1 / (2 * R), 1 / (2 * R), E_STAR)
    assert float(out["approach"]) == pytest.approx(
        (9 * F**2 / (16 * R * E_STAR**2)) ** (1 / 3), rel=1e-10
    )
    assert float(out["a"]) == pytest.approx((3 * F * R / (4 * E_STAR)) ** (1 / 3), rel=1e-10)


@pytest.mark.parametrize("R1,R2", [(2e-3, 5e-3), (1.5e-3, -1.6e-3), (10e-3, 10e-3)])
def test_sphere_on_sphere_closed_form(R1, R2):
    # effective radius 1/R = 1/R1 + 1/R2 (R2 < 0: a spherical cup)
    F = 40.0
    R = 1 / (1 / R1 + 1 / R2)
    out = point_contact(F, 1 / (2 * R), 1 / (2 * R), E_STAR)
    assert float(out["approach"]) == pytest.approx(
        (9 * F**2 / (16 * R * E_STAR**2)) ** (1 / 3), rel=1e-10
    )


def _scipy_elliptic_approach(F, A, B, E_star):
    """Independent evaluation: Johnson eqs. (3.70)-(3.72) with scipy's K, E and brentq."""

    def ratio(m):  # B/A as a function of m = e² (scipy uses the parameter m)
        K, Ee = special.ellipk(m), special.ellipe(m)
        return (Ee / (1 - m) - K) / (K - Ee)

    m = optimize.brentq(lambda m: ratio(m) - B / A, 1e-12, 1 - 1e-15, xtol=1e-18, rtol=1e-15)
    K, Ee = special.ellipk(m), special.ellipe(m)
    a = (3 * F * (K - Ee) / (2 * np.pi * E_star * A * m)) ** (1 / 3)
    return 3 * F * K / (2 * np.pi * a * E_star)


@pytest.mark.parametrize("ratio", [1.5, 4.0, 20.0, 101.0, 1000.0])
def test_elliptical_contact_against_scipy(ratio):
    A = 100.0
    got = float(point_contact(50.0, A, ratio * A, E_STAR)["approach"])
    ref = _scipy_elliptic_approach(50.0, A, ratio * A, E_STAR)
    assert got == pytest.approx(ref, rel=5e-3)  # the bound
    assert got == pytest.approx(ref, rel=1e-8)  # what the AGM actually reaches


def test_hamrock_brewe_approximation_is_close():
    # Hamrock & Brewe (1983) quote a few per cent for their curve fits
    for ratio in (2.0, 10.0, 101.0):
        exact = float(point_contact(20.0, 50.0, 50.0 * ratio, E_STAR)["approach"])
        approx = float(hamrock_brewe(20.0, 50.0, 50.0 * ratio, E_STAR)["approach"])
        assert approx == pytest.approx(exact, rel=0.05)


def test_paper_ball_approach_per_contact():
    # an independent Hertz estimate (elliptic-integral point contact, by hand): ≈0.5 µm per
    # contact at 10 N and ≈2.3–2.4 µm at 100 N for d = 3 mm, D = 1.01 d
    law = HertzBall(3e-3, 3.03e-3, E, NU)
    c1 = float(law.contact_compliance())
    assert 0.45e-6 < c1 * 10 ** (2 / 3) < 0.55e-6
    assert 2.3e-6 <= c1 * 100 ** (2 / 3) <= 2.4e-6
    # the element is two contacts in series
    assert float(law.approach(10.0)) == pytest.approx(2 * c1 * 10 ** (2 / 3), rel=1e-12)


def test_rivin_form_versus_hertz():
    """The paper's Rivin form, evaluated as written, gives 5.3x the Hertz approach (README)."""
    hertz = HertzBall(3e-3, 3.03e-3, E, NU)
    rivin = RivinBall(3e-3, 3.03e-3, E, NU, eta=1.412)
    # hand evaluation of eq. (1) at F = 10 N (SI):
    # 1.41·1.412·(100·1.0099/3e-3)^(1/3)·(1.82/210e9)^(2/3)
    by_hand = 1.41 * 1.412 * (100 * (2 * 3.03e-3 - 3e-3) / (3e-3 * 3.03e-3)) ** (1 / 3)
    by_hand *= (2 * (1 - 0.09) / 210e9) ** (2 / 3)
    assert float(rivin.contact_compliance()) * 10 ** (2 / 3) == pytest.approx(by_hand, rel=1e-12)
    ratio = float(rivin.contact_compliance() / hertz.contact_compliance())
    assert 5.0 < ratio < 5.6


def test_palmgren_roller():
    # δ = 3.84e-5 F^0.9 / l^0.8 mm per contact; l = 10 mm, F = 1000 N: 3.84e-5·501.19/6.3096 mm
    law = PalmgrenRoller(10e-3)
    per_contact = 3.84e-5 * 1000**0.9 / 10**0.8 * 1e-3
    assert float(law.approach(1000.0)) == pytest.approx(2 * per_contact, rel=1e-12)
    assert law.exponent == pytest.approx(10 / 9)


@pytest.mark.parametrize(
    "law", [HertzBall(3e-3, 3.03e-3), RivinBall(3e-3, 3.03e-3), PalmgrenRoller(6e-3)]
)
def test_force_inverts_approach(law):
    for F in (0.1, 38.0, 900.0):
        assert float(law.force(law.preload_approach(F))) == pytest.approx(F, rel=1e-12)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: HertzBall(-3e-3, 3.03e-3), "d .*> 0"),
        (lambda: HertzBall(3e-3, 3e-3), "D .*conformity"),
        (lambda: HertzBall(3e-3, 2e-3), "D .*conformity"),
        (lambda: HertzBall(3e-3, 3.03e-3, E=-1.0), "E must be > 0"),
        (lambda: HertzBall(3e-3, 3.03e-3, nu=0.7), "nu .*-1, 0.5"),
        (lambda: RivinBall(3e-3, 3.03e-3, eta=0.0), "eta must be > 0"),
        (lambda: PalmgrenRoller(0.0), "length .*> 0"),
    ],
)
def test_invalid_law_parameters(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_law_gradient_in_geometry_matches_finite_difference():
    # the ellipticity solve is differentiated implicitly (one Newton step on top of bisection)
    f = lambda d: HertzBall(d, 1.01 * 3e-3).contact_compliance()  # noqa: E731
    g = float(jax.grad(f)(3e-3))
    h = 1e-8
    fd = (float(f(3e-3 + h)) - float(f(3e-3 - h))) / (2 * h)
    assert g == pytest.approx(fd, rel=1e-5)
    assert np.isfinite(g) and jnp.isfinite(f(3e-3))
