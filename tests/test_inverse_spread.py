"""The rails' posterior re-linearised across its spread (diffguide.inverse.spread), on toy
problems whose posterior is known by quadrature: a linear model is left alone; a model whose
slope drops across the posterior (a row of rolling elements unloading) gets the width and the
shift of the true posterior, which the Gauss-Newton σ at the estimate misses."""

import types

import numpy as np

from diffguide.inverse import spread

#: Each row's gain: the one unknown moves the rows differently (a constant would be the
#: channel's zero, profiled out as in the fit).
GAIN = np.array([1.0, -1.0, 0.5, -0.5])


def _residual(f, x, y, sigma):
    d = GAIN * f(x) - y
    return (d - d.mean()) / sigma


def _state(f, df, y, sigma, prior_prec, x_hat):
    """A FitState-like object with one unknown (rails), one channel whose zero is profiled
    out, and the residual ``r_i = (g_i f(x) − y_i − o)/σ``."""
    n = len(y)

    def linearise(x):
        xv = float(x[0])
        J = GAIN * df(xv) / sigma
        return _residual(f, xv, y, sigma), (J - J.mean())[:, None], 0 * y, True, None

    meas = types.SimpleNamespace(sigma=np.full(n, sigma))
    problem = types.SimpleNamespace(ic=np.array([0]), iq=np.array([], int), meas=meas,
                                    weights=np.ones(n), chan=np.zeros(n, int), n_chan=1,
                                    linearise=linearise)
    x = np.array([x_hat])
    return types.SimpleNamespace(problem=problem, x=x, lin=linearise(x),
                                 Pc=np.array([[prior_prec]]))


def _mode(f, y, sigma, prior_prec, grid):
    obj = np.array([np.sum(_residual(f, g, y, sigma) ** 2) + prior_prec * g * g for g in grid])
    return grid[int(np.argmin(obj))], obj


def test_a_linear_model_keeps_its_gauss_newton_posterior():
    y = np.array([1.0, -1.2, 0.4, -0.6])
    st = _state(lambda x: 2.0 * x, lambda x: 2.0, y, 0.1, 1.0, 0.5)
    out = spread.nonlinear_spread(st)
    assert out.samples == 0 and not np.any(out.extra)
    assert np.all(out.nu < 1e-20)


def test_a_slope_that_drops_across_the_posterior_widens_the_band():
    """``f(x) = x`` for x > 0, ``0.05 x`` below (the stiffness a row loses when it unloads);
    the estimate sits just above the kink, so the Gauss–Newton σ is the steep side's. The
    posterior by quadrature is wider and reaches into the flat side: the widened variance
    (GN + spread) lies nearer the quadrature's second moment about the estimate than the GN
    variance does, and is at least twice the GN variance."""
    def f(x):
        return np.where(x > 0, x, 0.05 * x)

    def df(x):
        return 1.0 if x > 0 else 0.05

    sigma, prec = 0.3, 0.05
    y = GAIN * 0.05 + np.array([0.02, -0.03, 0.01, 0.0])
    grid = np.linspace(-20.0, 5.0, 50001)
    x_hat, obj = _mode(f, y, sigma, prec, grid)
    w = np.exp(-0.5 * (obj - obj.min()))
    w /= w.sum()
    second = float(np.sum(w * (grid - x_hat) ** 2))  # the posterior's spread about x̂
    st = _state(f, df, y, sigma, prec, x_hat)
    J = st.lin[1]
    gn = 1.0 / float((J.T @ J)[0, 0] + prec)
    out = spread.nonlinear_spread(st, n_samples=64)
    assert out.samples > 0
    widened = gn + float(out.extra[0, 0])
    assert widened >= 2 * gn, (gn, widened, second)
    assert abs(np.log(widened / second)) < abs(np.log(gn / second)), (gn, widened, second)
