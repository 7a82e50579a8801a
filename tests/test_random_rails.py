"""Random rails: the Gaussian-process model keeps its RMS and correlation length (statistically),
mounting classes stay within their tolerances, lines are exact, draws are reproducible."""

import numpy as np
import pytest

from diffguide.guideway.rails import SplineRail, bspline_matrix
from diffguide.studies.random_rails import (
    MOUNTING_CLASSES,
    GaussianRailModel,
    MountingTolerance,
    RailBatch,
    correlation,
    default_knots,
    linear_coefficients,
    sample_rails,
)


def _profiles(batch: RailBatch, s, plane="vertical"):
    B = bspline_matrix(s, batch.start, batch.spacing, batch.n_coeffs)
    return np.einsum("sk,brk->brs", B, getattr(batch, plane))  # (n_samples, 2, n_s)


@pytest.mark.parametrize("kernel", ["squared_exponential", "matern52"])
@pytest.mark.parametrize("corr", [0.1, 0.2])
def test_rms_and_correlation_length(kernel, corr):
    sigma = 5e-6
    model = GaussianRailModel(sigma, corr, kernel)
    batch = sample_rails(123, 3000, model)
    s = np.linspace(-0.5, 0.5, 51)  # the visited range, inside the knots
    lag = int(round(corr / (s[1] - s[0])))
    for plane in ("vertical", "horizontal"):
        e = _profiles(batch, s, plane).reshape(-1, s.size)  # both rails: 6000 profiles
        # ensemble RMS at every point: σ within 4 % (sampling error ~1 % at 6000 draws)
        rms = np.sqrt(np.mean(e**2, axis=0))
        np.testing.assert_allclose(rms, sigma, rtol=0.04)
        # correlation at lag ℓ and 2ℓ: the kernel's values within 0.03
        for k in (lag, 2 * lag):
            c = np.mean(e[:, :-k] * e[:, k:]) / np.mean(e**2)
            assert abs(c - correlation(k * (s[1] - s[0]), corr, kernel)) < 0.03, (plane, k, c)
    # the rails and planes are independent
    v, h = _profiles(batch, s, "vertical"), _profiles(batch, s, "horizontal")
    assert abs(np.mean(v[:, 0] * v[:, 1])) / sigma**2 < 0.05
    assert abs(np.mean(v * h)) / sigma**2 < 0.05


def test_correlation_length_is_where_the_kernel_says():
    assert correlation(0.2, 0.2) == pytest.approx(np.exp(-0.5))
    assert correlation(0.0, 0.2, "matern52") == 1.0
    assert correlation(0.2, 0.2, "matern52") == pytest.approx(
        (1 + np.sqrt(5) + 5 / 3) * np.exp(-np.sqrt(5))
    )


def test_planes_and_straight():
    batch = sample_rails(0, 5, GaussianRailModel(1e-6, 0.2, planes=("vertical",)))
    assert np.any(batch.vertical != 0) and np.all(batch.horizontal == 0)
    straight = sample_rails(0, 3, None, None)
    assert np.all(straight.vertical == 0) and np.all(straight.horizontal == 0)
    assert np.all(sample_rails(0, 2, GaussianRailModel(0.0, 0.2)).vertical == 0)


def test_draws_are_reproducible():
    model = GaussianRailModel(5e-6, 0.2)
    a = sample_rails(7, 4, model, "size25-ZA")
    b = sample_rails(np.random.default_rng(7), 4, model, "size25-ZA")
    np.testing.assert_array_equal(a.vertical, b.vertical)
    np.testing.assert_array_equal(a.horizontal, b.horizontal)
    assert not np.array_equal(a.vertical, sample_rails(8, 4, model, "size25-ZA").vertical)


def test_linear_coefficients_give_an_exact_line():
    start, spacing, n = default_knots()
    assert (start, spacing, n) == (-0.6, 0.025, 51)
    c = linear_coefficients(start, spacing, n, 3e-6, -5e-6)
    rail = SplineRail(start, spacing, c, np.zeros(n))
    s = np.linspace(start, start + (n - 3) * spacing, 37)
    _, ez = rail(s)
    np.testing.assert_allclose(ez, 3e-6 + (-8e-6) * (s - start) / 1.2, atol=1e-18)


@pytest.mark.parametrize("name", ["precision", "size25-ZO"])
def test_mounting_within_tolerance(name):
    tol = MOUNTING_CLASSES[name]
    batch = sample_rails(1, 2000, None, name)
    s = np.linspace(batch.start, batch.end, 25)
    h, v = _profiles(batch, s, "horizontal"), _profiles(batch, s, "vertical")
    # rail 1 is the reference; rail 2 is a straight line in each plane
    assert np.all(h[:, 0] == 0) and np.all(v[:, 0] == 0)
    np.testing.assert_allclose(np.diff(h[:, 1], 2, axis=-1), 0, atol=1e-18)
    np.testing.assert_allclose(np.diff(v[:, 1], 2, axis=-1), 0, atol=1e-18)
    # the distance between the rails varies by at most P; the height difference stays within S1
    spread = h[:, 1].max(axis=-1) - h[:, 1].min(axis=-1)
    assert spread.max() <= tol.parallelism * (1 + 1e-12)
    assert spread.max() > 0.8 * tol.parallelism  # uniform: the tolerance is used
    assert np.abs(v[:, 1]).max() <= tol.height * (1 + 1e-12)
    assert np.abs(v[:, 1]).max() > 0.9 * tol.height


def test_catalogue_classes_are_ordered():
    zo, za, zb = (MOUNTING_CLASSES[k] for k in ("size25-ZO", "size25-ZA", "size25-ZB"))
    assert zo.parallelism > za.parallelism > zb.parallelism
    assert zo.height > za.height > zb.height
    assert MOUNTING_CLASSES["none"].parallelism == 0


def test_batch_indexing():
    batch = sample_rails(3, 6, GaussianRailModel(5e-6, 0.2))
    assert len(batch) == 6 and len(batch[2:5]) == 3
    r1, r2 = batch.rails(4)
    s = np.linspace(-0.5, 0.5, 9)
    np.testing.assert_allclose(r2(s)[1], _profiles(batch, s)[4, 1], rtol=1e-12, atol=1e-20)
    np.testing.assert_allclose(r1(s)[0], _profiles(batch, s, "horizontal")[4, 0],
                               rtol=1e-12, atol=1e-20)
    with pytest.raises(ValueError, match="slice"):
        batch[1]


def test_bad_arguments():
    with pytest.raises(ValueError, match="rms"):
        GaussianRailModel(-1e-6, 0.2)
    with pytest.raises(ValueError, match="correlation_length"):
        GaussianRailModel(1e-6, 0.0)
    with pytest.raises(ValueError, match="kernel"):
        GaussianRailModel(1e-6, 0.2, "gauss")
    with pytest.raises(ValueError, match="planes"):
        GaussianRailModel(1e-6, 0.2, planes=("up",))
    with pytest.raises(ValueError, match="parallelism"):
        MountingTolerance(-1e-6, 0.0)
    with pytest.raises(ValueError, match="mounting"):
        sample_rails(0, 2, None, "size99")
    with pytest.raises(ValueError, match="n_samples"):
        sample_rails(0, 0, None)
    with pytest.raises(ValueError, match="shape"):
        RailBatch(-0.6, 0.025, np.zeros((3, 51)), np.zeros((3, 51)))
