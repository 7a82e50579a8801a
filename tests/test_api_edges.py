"""Edges of the Python API: bad arguments get a clear error naming the argument and its range;
documented limits (non-differentiable points) behave as documented."""

import types
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide import (
    SinusoidalRail,
    StraightRail,
    joint_errors,
    majda2012_machine,
    paper_variant,
    read_measurements,
    roll_spread,
)
from diffguide.inverse.basis import RailBasis
from diffguide.inverse.data import Measurements
from diffguide.inverse.fit import RailFit
from diffguide.machine.kinematics import error_field
from diffguide.studies.sensitivity import corner_roll

DATA = str(Path(__file__).parents[1] / "data" / "majda2012_measurements.csv")
X = np.array([-0.3, 0.0, 0.3])


@pytest.fixture(scope="module")
def machine():
    return majda2012_machine(nx=10, ny=6)


@pytest.fixture(scope="module")
def sweep(machine):
    return joint_errors(machine, paper_variant(3), X)


# --- error_field: the sweep index --------------------------------------------------------------


@pytest.mark.parametrize("index", [3, 8, 999, -4, -999])
def test_error_field_index_out_of_range_is_refused(machine, sweep, index):
    with pytest.raises(IndexError, match=r"index must be in -3 \.\. 2.*got"):
        error_field(machine, sweep, index)


def test_error_field_index_must_be_an_integer(machine, sweep):
    with pytest.raises(TypeError, match="index must be an integer"):
        error_field(machine, sweep, 1.0)


@pytest.mark.parametrize("index", [-1, np.int64(2), jnp.asarray(2)])
def test_error_field_last_position_by_any_integer(machine, sweep, index):
    # independent route: the control points are mesh nodes, and the node field there is the
    # point's joint error from the condensed point-recovery rows (JointErrors.errors)
    xy, field = error_field(machine, sweep, index)
    xy = np.asarray(xy)
    for j, p in enumerate(np.asarray(sweep.points_xy)):
        k = int(np.argmin(np.linalg.norm(xy - p, axis=1)))
        assert np.linalg.norm(xy[k] - p) < 1e-12
        np.testing.assert_allclose(field[k], sweep.errors[2, j], rtol=1e-9, atol=1e-15)


# --- joint_errors: rails and positions ---------------------------------------------------------


def test_joint_errors_single_rail_is_refused(machine):
    with pytest.raises(TypeError, match=r"rails must be a pair.*single PaperPolynomialRail"):
        joint_errors(machine, paper_variant(3)[0], [0.1])


def test_joint_errors_three_rails_is_refused(machine):
    with pytest.raises(ValueError, match="rails must be a pair.*got 3"):
        joint_errors(machine, (StraightRail(),) * 3, [0.1])


def test_joint_errors_non_rail_in_pair_is_refused(machine):
    with pytest.raises(TypeError, match=r"rails\[1\] must be a rail profile.*float"):
        joint_errors(machine, (StraightRail(), 3.0), [0.1])


def test_joint_errors_2d_positions_are_refused(machine):
    with pytest.raises(ValueError, match=r"positions must be a scalar or a 1-D.*\(2, 3\)"):
        joint_errors(machine, paper_variant(3), np.zeros((2, 3)))


def test_joint_errors_array_x_ref_is_refused(machine):
    with pytest.raises(ValueError, match=r"x_ref must be a scalar.*\(2,\)"):
        joint_errors(machine, paper_variant(3), [0.1], np.zeros(2))


def test_joint_errors_scalar_position_still_works(machine, sweep):
    je = joint_errors(machine, paper_variant(3), 0.3)
    assert je.errors.shape == (1,) + sweep.errors.shape[1:]
    np.testing.assert_allclose(je.errors[0], sweep.errors[2], rtol=1e-9, atol=1e-15)


# --- roll spread: derivative where D > 0, none at D = 0 ----------------------------------------


def test_roll_spread_derivative_on_a_synthetic_roll():
    # roll = a · pattern: D(a) = |a| · 1e6 · rms(pattern minus its row mean), by hand
    pattern = jnp.array([[1.0, -1.0, 0.0, 0.0], [2.0, 0.0, 0.0, -2.0]])
    c = 1e6 * np.sqrt(np.mean([1, 1, 0, 0, 4, 0, 0, 4]))  # row means are 0 here
    D = lambda a: roll_spread(a * pattern)  # noqa: E731
    D2 = lambda a: roll_spread(a * pattern, squared=True)  # noqa: E731
    assert float(D(-3e-6)) == pytest.approx(3e-6 * c)
    assert float(D2(-3e-6)) == pytest.approx((3e-6 * c) ** 2)
    assert float(jax.grad(D)(2e-6)) == pytest.approx(c)
    assert float(jax.grad(D)(-2e-6)) == pytest.approx(-c)
    assert np.isnan(float(jax.grad(D)(0.0)))  # documented: |a| has no derivative at 0
    assert float(jax.grad(D2)(0.0)) == 0.0
    assert float(jax.grad(D2)(2e-6)) == pytest.approx(2 * 2e-6 * c**2)


def test_roll_spread_gradient_through_the_model(machine):
    # the module docstring's claim, checked against a central difference at D > 0, and its
    # stated limit at perfect rails (D = 0)
    x = np.array([-0.3, 0.1, 0.3])

    def D(a, squared=False):
        rails = (SinusoidalRail(a, 0.37), StraightRail())
        return roll_spread(corner_roll(joint_errors(machine, rails, x)), squared=squared)

    a, h = 2e-6, 2e-7
    g = float(jax.grad(D)(a))
    fd = (float(D(a + h)) - float(D(a - h))) / (2 * h)
    assert np.isfinite(g) and g > 0
    assert g == pytest.approx(fd, rel=1e-4)
    assert float(D(0.0)) == 0.0
    assert np.isnan(float(jax.grad(D)(0.0)))
    assert float(jax.grad(lambda a: D(a, squared=True))(0.0)) == 0.0


# --- points are static: a traced point is refused ---------------------------------------------


def test_point_position_is_not_differentiable_as_documented():
    def f(px):
        return majda2012_machine(nx=10, ny=6, points={"Q": (px, 0.1)}).points_xy[0, 0]

    with pytest.raises(TypeError, match="control point 'Q' is traced"):
        jax.jacfwd(f)(0.2)
    assert "not differentiable" in majda2012_machine.__doc__


# --- Measurements repr --------------------------------------------------------------------------


def test_measurements_repr_is_short_and_says_what_it_holds():
    meas = read_measurements(DATA)
    text = repr(meas)
    assert len(text) < 300 and "\n" not in text
    # the bundled file: 36 positions x 5 points x 2 quantities (P1-P4 EAX/EBX by level, P5
    # EBX/ECX by interferometer): 360 rows, 10 channels; one raw reading per data line
    with open(DATA) as fh:
        n_lines = sum(1 for line in fh if line.strip() and not line.startswith("#")) - 1
    assert f"readings={n_lines}," in text
    for part in ("rows=360", "channels=10", "positions=36 (-350..350 mm)", "'P5'", DATA):
        assert part in text, part
    assert str(meas) == text


def test_measurements_repr_from_arrays():
    meas = Measurements.from_arrays(
        {"A": (0.0, 0.0), "B": (0.1, 0.0)},
        [0.0, 0.1, 0.1],
        ["A", "A", "B"],
        ["EAX", "EAX", "EBX"],
        [1e-6, 2e-6, 3e-6],
        1e-7,
    )
    assert repr(meas) == (
        "Measurements(rows=3, channels=2, positions=2 (0..100 mm), points=('A', 'B'), "
        "readings=0, source='<arrays>')"
    )


# --- RailFit.profiles / to_dataframe: scalar and non-finite s -----------------------------------


@pytest.fixture(scope="module")
def stub_fit():
    rng = np.random.default_rng(3)
    basis = RailBasis(-0.4, 0.1, 11)
    A = rng.normal(size=(44, 44)) * 1e-7
    fit = types.SimpleNamespace(
        basis=basis,
        coeffs=rng.normal(size=(2, 2, 11)) * 1e-6,
        cov=A @ A.T,
        waviness=0.1e-6,
    )
    fit.profiles = lambda s: RailFit.profiles(fit, s)
    return fit


def _scipy_profiles(fit, s):
    # independent: scipy's B-spline with the knots of the uniform grid (basis k centred at
    # start + (k − 1)h, so knot j at start + (j − 3)h)
    from scipy.interpolate import BSpline

    b = fit.basis
    t = b.start + (np.arange(b.n_coeffs + 4) - 3.0) * b.spacing
    B = BSpline.design_matrix(np.atleast_1d(s), t, 3).toarray()
    n = b.n_coeffs
    val = np.einsum("sk,rpk->rps", B, fit.coeffs)
    sig = np.empty_like(val)
    for k in range(4):
        C = fit.cov[k * n : (k + 1) * n, k * n : (k + 1) * n]
        sig[k // 2, k % 2] = np.sqrt(np.einsum("sk,kl,sl->s", B, C, B) + fit.waviness**2)
    return val, sig


def test_profiles_scalar_s_gives_scalar_shaped_arrays(stub_fit):
    val, sig = RailFit.profiles(stub_fit, 0.13)
    assert val.shape == sig.shape == (2, 2)
    ref_val, ref_sig = _scipy_profiles(stub_fit, 0.13)
    np.testing.assert_allclose(val, ref_val[..., 0], rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(sig, ref_sig[..., 0], rtol=1e-12)


def test_profiles_1d_s_matches_scipy(stub_fit):
    s = np.linspace(-0.4, 0.4, 17)
    val, sig = RailFit.profiles(stub_fit, list(s))
    assert val.shape == sig.shape == (2, 2, 17)
    ref_val, ref_sig = _scipy_profiles(stub_fit, s)
    np.testing.assert_allclose(val, ref_val, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(sig, ref_sig, rtol=1e-12)


@pytest.mark.parametrize("s", [np.nan, [0.0, np.nan], [np.inf], -np.inf])
def test_profiles_non_finite_s_is_refused(stub_fit, s):
    with pytest.raises(ValueError, match="s must be finite"):
        RailFit.profiles(stub_fit, s)


def test_profiles_2d_s_is_refused(stub_fit):
    with pytest.raises(ValueError, match=r"s must be a scalar or a 1-D.*\(2, 2\)"):
        RailFit.profiles(stub_fit, np.zeros((2, 2)))


def test_to_dataframe_scalar_s_gives_one_row_per_rail(stub_fit):
    pytest.importorskip("pandas")
    df = RailFit.to_dataframe(stub_fit, 0.13)
    assert list(df.rail) == [1, 2]
    np.testing.assert_allclose(df.s_mm, [130.0, 130.0])
    ref_val, ref_sig = _scipy_profiles(stub_fit, 0.13)
    np.testing.assert_allclose(df.vertical_um, ref_val[:, 0, 0] * 1e6, rtol=1e-12)
    np.testing.assert_allclose(df.horizontal_sigma_um, ref_sig[:, 1, 0] * 1e6, rtol=1e-12)
    with pytest.raises(ValueError, match="s must be finite"):
        RailFit.to_dataframe(stub_fit, [np.nan])
