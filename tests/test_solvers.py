"""The fit's solvers as objects (:class:`diffguide.inverse.lm.LevenbergMarquardt`,
:class:`diffguide.inverse.trust_region.TrustRegionNewton`) on problems whose minimum is known in
closed form: the value, the steps and the result code, and the codes of a solve that stops
short (step limit, no descent, a failed model)."""

import numpy as np
import pytest

from diffguide._core.result import RESULTS
from diffguide.inverse.lm import LevenbergMarquardt
from diffguide.inverse.trust_region import TrustRegionNewton

_T = np.linspace(0.0, 4.0, 9)
_A, _B = 2.0, -0.5  # the exact data's parameters: the least-squares minimum, residual 0


def _exponential(x):
    """Residuals ``a·e^{b t} − y`` of data ``y = 2 e^{−t/2}`` and their Jacobian."""
    a, b = x
    e = np.exp(b * _T)
    return a * e - _A * np.exp(_B * _T), np.stack([e, a * _T * e], axis=1), True, None


def test_levenberg_marquardt_finds_an_exponential_fits_exact_parameters():
    sol = LevenbergMarquardt(rtol=1e-6, max_steps=60).solve(
        _exponential, np.array([1.0, 0.0]), np.zeros((2, 2)))
    np.testing.assert_allclose(sol.value, [_A, _B], atol=1e-8)
    assert sol.result == RESULTS.successful and sol.converged and sol.message == "converged"
    assert 0 < sol.steps < 60
    np.testing.assert_allclose(sol.state.residual, 0.0, atol=1e-8)
    assert sol.state.jacobian.shape == (len(_T), 2)


def test_levenberg_marquardt_with_too_few_steps_says_so():
    x0 = np.array([1.0, 0.0])
    sol = LevenbergMarquardt(max_steps=2).solve(_exponential, x0, np.zeros((2, 2)))
    assert sol.result == RESULTS.nonlinear_max_steps_reached and not sol.converged
    assert sol.steps == 2 and "stopped after 2 steps" in sol.message
    r0 = _exponential(x0)[0]
    assert sol.state.cost <= float(r0 @ r0)  # the best point so far, never a worse one
    with pytest.raises(RuntimeError, match="stopped after 2 steps"):
        LevenbergMarquardt(max_steps=2).solve(_exponential, x0, np.zeros((2, 2)), throw=True)


def test_levenberg_marquardt_where_every_trial_fails_stagnates_at_the_start():
    """A model that fails at every trial point: the damping grows past its limit, the start
    is returned with ``RESULTS.stagnation``."""
    x0 = np.array([1.0, 0.0])
    r0, J0, _, _ = _exponential(x0)

    def failing(x):
        return r0, J0, False, None

    sol = LevenbergMarquardt().solve(failing, x0, np.zeros((2, 2)), at=(r0, J0, None))
    assert sol.result == RESULTS.stagnation and 0 < sol.steps < 60
    np.testing.assert_array_equal(sol.value, x0)


def test_a_solvers_settings_are_checked():
    with pytest.raises(ValueError, match="rtol"):
        LevenbergMarquardt(rtol=0.0)
    with pytest.raises(ValueError, match="max_steps"):
        TrustRegionNewton(max_steps=0)


_K = np.array([[3.0, 1.2], [1.2, 2.5]])  # eigenvalues ≥ 1: the floor 2 on H = 2K never binds
_M = np.array([0.7, -1.1])


def _quadratic(q):
    return float((q - _M) @ _K @ (q - _M)) + 3.0


def test_the_trust_region_finds_a_quadratics_minimiser_and_its_covariance():
    """``(q − m)ᵀK(q − m) + c``: the minimiser ``m``, and ``2H⁻¹ = K⁻¹`` exact (central
    differences are exact on a quadratic)."""
    sol = TrustRegionNewton().solve(_quadratic, np.zeros(2), np.array([[-5.0, 5.0]] * 2))
    np.testing.assert_allclose(sol.value, _M, atol=1e-9)
    np.testing.assert_allclose(sol.state.cov, np.linalg.inv(_K), rtol=1e-9)
    assert sol.result == RESULTS.successful and sol.steps > 0
    assert sol.state.at_bound == (False, False)


def test_the_trust_region_with_too_few_steps_or_a_failed_objective_says_so():
    far = np.array([[-5.0, 5.0]] * 2)
    sol = TrustRegionNewton(max_steps=1).solve(lambda q: _quadratic(q - 3.0), np.zeros(2), far)
    assert sol.result == RESULTS.nonlinear_max_steps_reached and sol.steps == 1
    assert np.linalg.norm(sol.value) == pytest.approx(1.0)  # one step, the first trust radius
    sol = TrustRegionNewton().solve(lambda q: np.inf, np.zeros(2), far)
    assert sol.result == RESULTS.nonfinite
    np.testing.assert_array_equal(sol.state.cov, np.eye(2))
