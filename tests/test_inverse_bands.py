"""The floor on the rails' bands where the data see nothing (diffguide.inverse.bands), checked
on small problems against closed forms and sampling, without a machine."""

import numpy as np
import pytest

from diffguide.inverse.bands import MIN_WAVELENGTH_KNOTS, undetermined_floor, wavelengths
from diffguide.inverse.basis import RailBasis, null_space_basis


def _problem(lam=1e-2, kappa=1e3):
    basis = RailBasis.covering(-0.5, 0.5, 0.05)
    C, _ = basis.gauge_functionals((True, True))
    Z = null_space_basis(C, basis.size)
    G2, G0 = basis.penalty_factor() @ Z, basis.amplitude_factor() @ Z
    Om_curv, Om_amp = G2.T @ G2, G0.T @ G0
    return basis, Z, Om_curv, Om_amp, lam * (Om_curv + kappa * Om_amp)


def _plane_mean_square(basis, Z, cov, rng, n=4000):
    """Mean square per plane of profiles drawn from ``N(0, cov)`` (θ, µm): by sampling."""
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    th = (V * np.sqrt(np.maximum(w, 0.0))) @ rng.standard_normal((len(w), n))
    B = basis.matrix(basis.grid(201))
    c = (Z @ th).reshape(2, 2, basis.n_coeffs, n)
    return np.mean(np.einsum("sk,rpkn->rpsn", B, c) ** 2, axis=(0, 2, 3))


def test_wavelength_of_a_sinusoid():
    """A direction that is a sinusoid of wavelength L (least-squares on the knots) is read as L
    (the curvature-to-amplitude ratio of a sine is (2π/L)⁴), to a few per cent."""
    basis, Z, Om_curv, Om_amp, _ = _problem()
    s = basis.grid(801)
    B = basis.matrix(s)
    for L in (0.2, 0.32, 0.5):
        c = np.zeros((2, 2, basis.n_coeffs))
        c[0, 1] = np.linalg.lstsq(B, np.sin(2 * np.pi * s / L), rcond=None)[0]
        theta = np.linalg.lstsq(Z, c.ravel(), rcond=None)[0]
        got = wavelengths(basis, Z, Om_curv, Om_amp, theta[:, None])[0]
        assert abs(got / L - 1) < 0.05, (L, got)


def test_data_that_see_everything_change_nothing():
    """Every direction determined (a strong identity Jacobian): no floor, no extra covariance."""
    basis, Z, Om_curv, Om_amp, P = _problem()
    J = 1e3 * np.eye(Z.shape[1])
    fl = undetermined_floor(J, P, basis, Z, Om_curv, Om_amp, np.ones(Z.shape[1]))
    assert fl.n_directions == 0 and not np.any(fl.extra)


def test_blind_data_get_the_hierarchical_scale():
    """Data that see nothing: the long-wave directions (≥ MIN_WAVELENGTH_KNOTS knot spacings)
    are all undetermined; profiles drawn from the widened posterior carry, per plane, the mean
    square of the log-uniform hyperprior between the prior's extrapolation ``E`` and the
    fitted content ``R²``, ``(R² − E)/ln(R²/E)`` — E by sampling the prior over those
    directions, R² of the fitted profiles, both independent of the module's own sums."""
    rng = np.random.default_rng(3)
    basis, Z, Om_curv, Om_amp, P = _problem()
    n = Z.shape[1]
    J = np.zeros((5, n))
    cov = np.linalg.inv(P)
    theta = 30.0 * rng.standard_normal(n) / np.sqrt(np.arange(1, n + 1))  # the "fit"
    fl = undetermined_floor(J, P, basis, Z, Om_curv, Om_amp, theta)
    assert fl.n_directions > 0
    assert np.all(fl.wavelengths_m >= MIN_WAVELENGTH_KNOTS * basis.spacing)
    # the selected directions: P-orthonormal eigenvectors of P itself are any P-orthonormal set;
    # reproduce the selection from the extra covariance's range instead
    w, V = np.linalg.eigh(fl.extra)
    keep = w > 1e-12 * w.max()
    Vs = V[:, keep]
    Psel = Vs @ np.linalg.solve(Vs.T @ P @ Vs, Vs.T)  # the prior restricted to that subspace
    E = _plane_mean_square(basis, Z, Psel, rng)
    B = basis.matrix(basis.grid(201))
    c = (Z @ theta).reshape(2, 2, basis.n_coeffs)
    R2 = np.mean(np.einsum("sk,rpk->rps", B, c) ** 2, axis=(0, 2))
    np.testing.assert_allclose(fl.prior_rms_um**2, E, rtol=0.1)
    np.testing.assert_allclose(fl.visible_rms_um**2, R2, rtol=1e-9)
    assert np.all(R2 > E)
    expected = (R2 - E) / np.log(R2 / E)
    got = _plane_mean_square(basis, Z, Psel @ P @ (cov + fl.extra) @ P @ Psel, rng)
    np.testing.assert_allclose(got, expected, rtol=0.15)


@pytest.mark.parametrize("scale", [1.0, 1e-3])
def test_never_narrows(scale):
    """The floor only adds (a positive semi-definite extra), whatever the fitted content: with
    the fitted profiles smaller than the prior's extrapolation nothing is added."""
    rng = np.random.default_rng(4)
    basis, Z, Om_curv, Om_amp, P = _problem()
    n = Z.shape[1]
    J = rng.standard_normal((40, n))
    fl = undetermined_floor(J, P, basis, Z, Om_curv, Om_amp,
                            scale * rng.standard_normal(n))
    prior_scale = np.abs(np.linalg.inv(P)).max()
    assert np.linalg.eigvalsh(fl.extra).min() >= -1e-9 * prior_scale
    small = undetermined_floor(J, P, basis, Z, Om_curv, Om_amp, np.zeros(n))
    assert np.abs(small.extra).max() <= 1e-9 * prior_scale
