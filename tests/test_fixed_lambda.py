"""Fixed weights converge: Levenberg–Marquardt (:mod:`diffguide.inverse.lm`) on regularised
problems built here — a curved valley, an under-determined nonlinear problem with a tiny
penalty — against SciPy's trust-region solver of the same objective; the fit's linearisation
cache never hands back one taken at another structure or weights; and the battery's
interferometer-only case with a fixed λ of 1e-5 and 1e-3 (issue 28: 60 steps unconverged)."""

import types

import numpy as np
import pytest
from scipy.optimize import least_squares

from diffguide.inverse.lm import LevenbergMarquardt
from diffguide.inverse.solve import _RailLinearisation


def _lm(fun, jac, x0, P, rtol=1e-6, max_steps=60):
    def linearise(x):
        return fun(x), jac(x), True, None

    sol = LevenbergMarquardt(rtol=rtol, max_steps=max_steps).solve(linearise, x0, P)
    x, r = sol.value, sol.state.residual
    return x, float(r @ r + x @ P @ x), sol.converged, sol.steps, sol.message


def _scipy(fun, jac, x0, P):
    """The same objective ``‖r‖² + xᵀPx`` as one least-squares problem, by SciPy's TRF."""
    L = np.linalg.cholesky(P + 1e-300 * np.eye(len(x0))).T
    res = least_squares(lambda x: np.concatenate([fun(x), L @ x]), x0,
                        jac=lambda x: np.vstack([jac(x), L]), xtol=1e-15, ftol=1e-15,
                        gtol=1e-15, max_nfev=10000)
    return res.x, 2 * res.cost


def test_a_curved_valley_converges_to_the_minimum():
    """Rosenbrock's valley as residuals ``(1 − x₀, 10(x₁ − x₀²))`` with a small ridge."""
    def fun(x):
        return np.array([1 - x[0], 10 * (x[1] - x[0] ** 2)])

    def jac(x):
        return np.array([[-1.0, 0.0], [-20 * x[0], 10.0]])

    P = 1e-4 * np.eye(2)
    x0 = np.array([-1.2, 1.0])
    x, cost, converged, steps, msg = _lm(fun, jac, x0, P)
    xs, cost_s = _scipy(fun, jac, x0, P)
    assert converged and steps < 60, msg
    assert cost == pytest.approx(cost_s, rel=1e-6, abs=1e-12)
    np.testing.assert_allclose(x, xs, atol=1e-3)


@pytest.mark.parametrize("n", [30, 60])
@pytest.mark.parametrize("lam", [1e-8, 1e-5, 1e-3])
def test_a_nearly_linear_problem_with_a_tiny_penalty(lam, n):
    """``n`` data, 50 unknowns (under- and over-determined), a weak quadratic nonlinearity
    (the fit's model is nearly linear in µm-sized rails), a curvature-like penalty ``λDᵀD``:
    converged within the step limit and at SciPy's objective, to far below the noise scale."""
    rng = np.random.default_rng(2)
    m = 50
    A = rng.normal(size=(n, m)) / np.sqrt(m)
    B = rng.normal(size=(n, m)) / np.sqrt(m)
    y = A @ rng.normal(size=m) + rng.normal(size=n)
    D = np.diff(np.eye(m), 2, axis=0)
    P = lam * D.T @ D + 1e-10 * np.eye(m)

    def fun(x):
        return A @ x + 0.05 * (B @ x) ** 2 - y

    def jac(x):
        return A + 0.1 * (B @ x)[:, None] * B

    x0 = np.zeros(m)
    _, cost, converged, steps, msg = _lm(fun, jac, x0, P)
    _, cost_s = _scipy(fun, jac, x0, P)
    assert converged and steps < 60, msg
    assert cost <= cost_s * (1 + 0.03 / n) + 1e-10  # the stall rule's promise: < 0.03 ŝ²


def test_a_step_limit_is_reported_as_not_converged():
    def fun(x):
        return np.array([1 - x[0], 10 * (x[1] - x[0] ** 2)])

    def jac(x):
        return np.array([[-1.0, 0.0], [-20 * x[0], 10.0]])

    _, _, converged, steps, msg = _lm(fun, jac, np.array([-1.2, 1.0]), 1e-4 * np.eye(2),
                                      max_steps=2)
    assert not converged and steps == 2 and "stopped after 2 steps" in msg


def test_the_linearisation_cache_is_keyed_on_structure_and_weights():
    """A linearisation kept at rails ``x_c`` is not reused once the structure or the weights
    changed (it was keyed on the rails alone)."""
    calls = []

    def linearise(x):
        calls.append(x.copy())
        r = np.full(3, float(x.sum()))
        return r, np.ones((3, 3)), r, True, None

    problem = types.SimpleNamespace(ic=np.array([0, 2]), weights=np.ones(3),
                                    linearise=linearise)
    st = types.SimpleNamespace(problem=problem, x=np.array([0.0, 0.0, 0.0]))
    cache = _RailLinearisation(st)
    cache(np.array([1.0, 2.0]))  # a trial point at structure q = 0
    st.x = np.array([1.0, 0.0, 2.0])
    assert cache.at(st.x)[0][0] == 3.0 and len(calls) == 1  # the kept one: same everything
    st.x = np.array([1.0, 0.5, 2.0])  # the structure moved
    assert cache.at(st.x)[0][0] == 3.5 and len(calls) == 2
    problem.weights = np.array([1.0, 0.0, 1.0])  # an outlier set aside
    st.x = np.array([1.0, 0.0, 2.0])
    cache.at(st.x)
    assert len(calls) == 3


@pytest.mark.parametrize("lam", [1e-5, 1e-3])
def test_interferometer_only_with_a_fixed_lambda_converges(lam):
    from battery import cases

    from diffguide.inverse import fit_rails

    case = cases.CASES["interferometer_only"]()
    meas = cases.measurements(case)
    points = dict(zip(meas.point_names, map(tuple, np.asarray(meas.points_xy, float))))
    fit = fit_rails(cases.fit_machine(points), meas, lam=lam)
    assert fit.converged, fit.message
    assert fit.steps < 60 and fit.lam == lam
    assert 0.5 < fit.chi2_dof < 1.5
    assert not any(v["at_bound"] for v in fit.structure.values())
