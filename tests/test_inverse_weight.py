"""The smoothness weight's criteria in closed form (diffguide.inverse.weight) against a direct
dense evaluation of the same quantities, and its behaviour where GCV degenerates."""

import numpy as np
import pytest

from diffguide.inverse.weight import _Spectrum, choose_weight, fixed_weight, project_out


def _problem(rng, n=60, k=25, decay=0.7):
    U, _ = np.linalg.qr(rng.standard_normal((n, k)))
    V, _ = np.linalg.qr(rng.standard_normal((k, k)))
    J = U @ np.diag(decay ** np.arange(k)) @ V.T
    A = rng.standard_normal((k, k))
    Omega = A @ A.T + k * np.eye(k)
    theta = rng.standard_normal(k)
    y = J @ theta + 0.01 * rng.standard_normal(n)
    return J, y, Omega


def _dense(J, y, Omega, lam, n_eff):
    """The same quantities by brute force: the influence matrix and the marginal covariance."""
    H = J.T @ J + lam * Omega
    A = J @ np.linalg.solve(H, J.T)
    res = y - A @ y
    edf = np.trace(A)
    gcv = n_eff * (res @ res) / (n_eff - edf) ** 2
    C = np.eye(len(y)) + J @ np.linalg.solve(Omega, J.T) / lam  # Cov y / s²
    Q = y @ np.linalg.solve(C, y)
    ml = n_eff * np.log(Q) + np.linalg.slogdet(C)[1]
    return edf, gcv, ml


@pytest.mark.parametrize("lam", [1e-6, 1e-3, 1.0, 30.0])
def test_closed_forms_match_dense_evaluation(lam):
    rng = np.random.default_rng(3)
    J, y, Omega = _problem(rng)
    sp = _Spectrum(J, y, Omega)
    edf, gcv, ml = _dense(J, y, Omega, lam, len(y))
    assert sp.edf(lam) == pytest.approx(edf, rel=1e-8)
    assert sp.score(lam, "gcv", len(y)) == pytest.approx(gcv, rel=1e-7)
    # the log-likelihood differs by a λ-independent constant only: compare differences
    edf2, gcv2, ml2 = _dense(J, y, Omega, 2 * lam, len(y))
    assert (sp.score(2 * lam, "ml", len(y)) - sp.score(lam, "ml", len(y))
            == pytest.approx(ml2 - ml, rel=1e-6, abs=1e-8))


def test_effective_parameters_bounded_and_ml_interior_where_gcv_degenerates():
    """Few informative directions (rank 3 of 40 unknowns, as one interferometer): GCV runs to
    the bottom of its range, the marginal likelihood stays interior; edf within [0, rank]."""
    rng = np.random.default_rng(5)
    n, k = 80, 40
    J = np.zeros((n, k))
    J[:, :3] = rng.standard_normal((n, 3))
    Omega = np.eye(k)
    y = J @ rng.standard_normal(k) + rng.standard_normal(n)
    ml = choose_weight(J, y, Omega, n, "ml")
    assert not ml.at_bound
    assert 0 <= ml.edf <= 3 + 1e-9
    g = choose_weight(J, y, Omega, n, "gcv")
    assert 0 <= g.edf <= 3 + 1e-9
    assert all(0 <= row[2] <= 3 + 1e-9 for row in ml.table)


def test_fixed_weight_and_projection():
    rng = np.random.default_rng(2)
    J, y, Omega = _problem(rng)
    f = fixed_weight(0.5, J, y, Omega, len(y))
    assert f.lam == 0.5 and f.criterion == "fixed"
    with pytest.raises(ValueError, match="lambda must be a finite number > 0"):
        fixed_weight(float("nan"), J, y, Omega, len(y))
    F = rng.standard_normal((len(y), 3))
    Jp, yp, rank = project_out(F, J, y)
    assert rank == 3 and np.abs(F.T @ Jp).max() < 1e-10 and np.abs(F.T @ yp).max() < 1e-10


def test_prior_shape_follows_the_data():
    """Direct noisy samples of one profile: a smooth truth (a quadratic) keeps the curvature
    prior (small κ); a rough one (independent coefficients) moves to a prior nearly flat in
    wavelength (large κ) — the marginal likelihood picks the spectrum the data show."""
    from diffguide.inverse import RailBasis
    from diffguide.inverse.weight import choose_prior

    b = RailBasis.covering(-0.5, 0.5, 0.05)
    s = np.linspace(-0.5, 0.5, 300)
    B = b.matrix(s)
    G2 = b.penalty_factor()[:, : b.n_coeffs][: (b.n_coeffs - 3) * 2]
    G0 = b.amplitude_factor()[:, : b.n_coeffs][: (b.n_coeffs - 3) * 3]
    rng = np.random.default_rng(11)
    smooth = B @ np.linalg.lstsq(B, 3 * s**2, rcond=None)[0] + 0.01 * rng.standard_normal(300)
    rough = B @ rng.standard_normal(b.n_coeffs) + 0.01 * rng.standard_normal(300)
    k_smooth = choose_prior(B / 0.01, smooth / 0.01, G2.T @ G2, G0.T @ G0, 300).kappa
    k_rough = choose_prior(B / 0.01, rough / 0.01, G2.T @ G2, G0.T @ G0, 300).kappa
    assert k_rough >= 1e3 * k_smooth, (k_smooth, k_rough)
