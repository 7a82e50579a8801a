"""Straightness (ISO 230-1) and its expanded uncertainty against closed forms and an
independent Monte Carlo; the ISO 14253-1 verdict's zones."""

import types

import numpy as np
import pytest

from diffguide.inverse.basis import RailBasis
from diffguide.studies.straightness import (
    deviation_bands,
    deviations,
    rail_straightness,
    sample_gaussian,
    straightness,
    uncertain_straightness,
    verdict,
)


def test_parabola_least_squares_and_end_point():
    # e = a s² on [0, L]: the least-squares line is a(L s − L²/6), the deviations a(s² − L s +
    # L²/6) reach a L²/6 at both ends and −a L²/12 at L/2: straightness a L²/4; the end-point
    # line a L s leaves a(s² − L s), down to −a L²/4 at L/2: also a L²/4
    a, L = 3e-5, 0.6
    s = np.linspace(0.0, L, 20001)
    for ref in ("least-squares", "end-point"):
        assert straightness(s, a * s**2, ref) == pytest.approx(a * L**2 / 4, rel=1e-4)
    d = deviations(s, a * s**2)
    assert d[0] == pytest.approx(a * L**2 / 6, rel=1e-3)
    assert d[len(s) // 2] == pytest.approx(-a * L**2 / 12, rel=1e-3)


def test_cubic_tells_the_reference_lines_apart():
    # e = s³ on [−1, 1]: least-squares slope ∫s⁴/∫s² = 3/5, deviations s³ − 3s/5 peak at ±2/5
    # at the ends: 4/5; the end-point line s leaves s³ − s, ±2/(3√3) at ∓1/√3: 4/(3√3)
    s = np.linspace(-1.0, 1.0, 40001)
    assert straightness(s, s**3, "least-squares") == pytest.approx(0.8, rel=1e-4)
    assert straightness(s, s**3, "end-point") == pytest.approx(4 / (3 * np.sqrt(3)), rel=1e-6)


def test_offset_and_slope_do_not_change_it():
    rng = np.random.default_rng(1)
    s = np.sort(rng.uniform(-0.3, 0.3, 200))
    e = rng.normal(size=(3, 200)) * 1e-6
    tilted = e + 4e-6 + 2e-5 * s
    for ref in ("least-squares", "end-point"):
        np.testing.assert_allclose(straightness(s, tilted, ref), straightness(s, e, ref),
                                   rtol=1e-12)


def test_bad_arguments():
    with pytest.raises(ValueError, match="reference"):
        straightness([0.0, 1.0], [0.0, 1.0], "minimum zone")
    with pytest.raises(ValueError, match="increasing"):
        straightness([1.0, 0.0], [0.0, 1.0])
    with pytest.raises(ValueError, match="tolerance"):
        verdict(1.0, 0.1, -2.0)


def test_verdict_zones():
    # ISO 14253-1: conformance proved inside T − U, non-conformance beyond T + U
    assert verdict(4.0, 1.0, 5.0) == "pass"  # boundary: value + U = T
    assert verdict(4.5, 1.0, 5.0) == "not decidable"
    assert verdict(6.0, 1.0, 5.0) == "not decidable"  # boundary: value − U = T
    assert verdict(6.5, 1.0, 5.0) == "fail"
    assert verdict(6.5, 1.0, None) is None


def _spline_of(basis, f):
    """Coefficients of ``f`` (a polynomial of degree <= 3: exact in a cubic spline)."""
    s = np.linspace(basis.start, basis.end, 400)
    c, *_ = np.linalg.lstsq(basis.matrix(s), f(s), rcond=None)
    return c


def test_linear_case_closed_form():
    # e = a s² with a ~ N(a0, σa²), a0 ≫ σa: the straightness a·L²/4 is linear in a, so
    # u = L²/4·σa, and the draws' 95 % interval is a0 L²/4 ± 1.96 L²/4 σa
    basis = RailBasis.covering(-0.3, 0.3, 0.05)
    v = _spline_of(basis, lambda s: (s + 0.3) ** 2)
    a0, sa = 2e-5, 1e-6
    s = np.linspace(basis.start, basis.end, 301)
    L = basis.end - basis.start
    res = uncertain_straightness(s, basis.matrix(s), a0 * v, sa**2 * np.outer(v, v),
                                 n_samples=20000, seed=3)
    assert res["value"] == pytest.approx(a0 * L**2 / 4, rel=1e-3)
    assert res["u"] == pytest.approx(sa * L**2 / 4, rel=0.02)  # 1/√(2N) = 0.5 %
    assert res["U"] == pytest.approx(2 * res["u"])
    lo, hi = res["interval_95"]
    assert lo == pytest.approx((a0 - 1.96 * sa) * L**2 / 4, rel=0.01)
    assert hi == pytest.approx((a0 + 1.96 * sa) * L**2 / 4, rel=0.01)


def test_u_against_an_independent_monte_carlo():
    # a Gaussian coefficient covariance of full rank: u against NumPy's multivariate normal, a
    # least-squares line by np.polyfit and the RMS about the estimate, another seed
    basis = RailBasis.covering(0.0, 0.5, 0.05)
    n = basis.n_coeffs
    rng = np.random.default_rng(7)
    mean = rng.normal(size=n) * 2e-6
    A = rng.normal(size=(n, n)) * 2e-7
    cov = A @ A.T
    s = np.linspace(basis.start, basis.end, 251)
    B = basis.matrix(s)
    res = uncertain_straightness(s, B, mean, cov, n_samples=8000, seed=11)
    draws = np.random.default_rng(99).multivariate_normal(mean, cov, 8000) @ B.T
    t = np.array([np.ptp(e - np.polyval(np.polyfit(s, e, 1), s)) for e in draws])
    e0 = B @ mean
    t0 = np.ptp(e0 - np.polyval(np.polyfit(s, e0, 1), s))
    assert res["value"] == pytest.approx(t0, rel=1e-9)
    assert res["u"] == pytest.approx(np.sqrt(np.mean((t - t0) ** 2)), rel=0.05)
    assert res["samples_mean"] == pytest.approx(t.mean(), rel=0.02)


def test_sampling_a_singular_covariance():
    # the gauge leaves the fit's covariance singular (round-off may make it slightly indefinite)
    v = np.array([1.0, -2.0, 0.5])
    cov = np.outer(v, v) - 1e-18 * np.eye(3)
    x = sample_gaussian(np.zeros(3), cov, 5000, np.random.default_rng(0))
    assert np.all(np.isfinite(x))
    np.testing.assert_allclose(np.cov(x.T), np.outer(v, v), atol=0.1)
    w = np.cross(v, [0.0, 0.0, 1.0])
    assert np.max(np.abs(x @ w)) < 1e-6  # nothing along the null direction


def _fake_fit(rng):
    basis = RailBasis.covering(-0.25, 0.25, 0.05)
    n = basis.n_coeffs
    A = rng.normal(size=(4 * n, 4 * n)) * 1e-7
    return types.SimpleNamespace(basis=basis, coeffs=rng.normal(size=(2, 2, n)) * 2e-6,
                                 cov=A @ A.T, waviness=0.0)


def test_deviation_bands_against_sampling():
    # σ of the deviations from the least-squares line, by linear propagation, against the
    # scatter of sampled profiles' deviations
    rng = np.random.default_rng(5)
    fit = _fake_fit(rng)
    s = np.linspace(fit.basis.start, fit.basis.end, 101)
    dev, sig = deviation_bands(fit, s)
    n = fit.basis.n_coeffs
    B = fit.basis.matrix(s)
    k = 3  # rail 2 horizontal
    c = sample_gaussian(fit.coeffs[1, 1], fit.cov[k * n:(k + 1) * n, k * n:(k + 1) * n], 20000,
                        rng)
    d = deviations(s, c @ B.T)
    np.testing.assert_allclose(dev[1, 1], deviations(s, B @ fit.coeffs[1, 1]), atol=1e-15)
    np.testing.assert_allclose(sig[1, 1], d.std(axis=0), rtol=0.03)


def test_rail_straightness_rows():
    fit = _fake_fit(np.random.default_rng(2))
    s = np.linspace(fit.basis.start, fit.basis.end, 101)
    rows = rail_straightness(fit, s, rail_y=(-0.17, 0.17), tolerance=1e-3, n_samples=200)
    assert [(r["rail"], r["side"], r["plane"]) for r in rows] == [
        (1, "−y", "vertical"), (1, "−y", "horizontal"), (2, "+y", "vertical"),
        (2, "+y", "horizontal")]
    for r in rows:
        p = 0 if r["plane"] == "vertical" else 1
        assert r["value"] == pytest.approx(
            straightness(s, fit.basis.matrix(s) @ fit.coeffs[r["rail"] - 1, p]))
        assert r["verdict"] == "pass"  # a 1 mm tolerance for µm profiles
