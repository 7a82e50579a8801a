r"""The rails' posterior where the model is not linear across it: randomised maximum likelihood.

The Gauss–Newton posterior ``H⁻¹`` takes the model's Jacobian at the estimate for the whole
posterior. That holds while every rolling element stays loaded: the joint errors are then all
but linear in µm-sized rails. Where rails are large enough that rows of rolling elements unload,
the Jacobian changes within the posterior's own spread: a row unloaded at the estimate carries
no information there, yet a sample one σ away loads it again. The bands then describe a
linearisation that does not hold a σ away.

**The check** (:func:`nonlinearity`). At :data:`PROBE` draws ``x_k ~ N(x̂, s²H⁻¹)`` (rails and
nuisances; the structure at its estimate; ``s`` below) the model is evaluated and compared with its
linearisation at ``x̂``: ``ν_k = ‖r(x_k) − r̂ − Ĵ(x_k − x̂)‖²`` (whitened: the χ² the
linearisation misses one posterior draw away). Below :data:`NU_TOL` ``·s²`` (a tenth of one
datum's χ²) the linear posterior stands.

**Randomised maximum likelihood** (Oliver, He & Reynolds 1996; Kitanidis 1995) otherwise: each
of :data:`N_SAMPLES` samples minimises the objective with its data and prior perturbed by their
own distributions,

.. math::  x_k = \arg\min_x ‖r(x) − ε_k‖² + (x − δ_k)ᵀP_c(x − δ_k),\qquad
           ε_k \sim N(0, Π),\ δ_k \sim N(0, P_c⁻¹),

``Π`` the projection that removes each channel's zero (profiled out of ``r``); both scaled by
the posterior's ``s = √max(1, χ²/dof)`` (:mod:`.posterior`): where the model does not explain
the data to their stated σ the posterior is ``s`` times wider, and it is at that spread that
the model must be linear (rows unload further out). For a linear
model the ``x_k`` are exact posterior draws; for a nonlinear one, the standard approximation.
Each is solved by :data:`GN_STEPS` Gauss–Newton steps from ``x̂``, the Jacobian taken again at
every step; the first step is the linear posterior's draw ``x_k^{(1)} = x̂ + Ĥ⁻¹(Ĵᵀε_k + P_cδ_k)``
(``x̂`` being the minimum). The *change* the re-linearised steps make is then measured against
those linear draws, which share the random numbers (a control variate: a handful of samples
then suffice):

.. math::  Δ = \mathrm{Cov}_k(x_k) − \mathrm{Cov}_k(x_k^{(1)}) + b\,bᵀ,\qquad
           b = \overline{x_k} − \overline{x_k^{(1)}},

and the covariance becomes ``Cov + Δ₊`` (``Δ₊``: ``Δ`` with its negative eigenvalues dropped —
the bands widen where the model's curvature spreads or shifts the posterior, never narrow;
``b bᵀ`` because the bands stay centred on the estimate while the posterior's mass moved).
"""

import dataclasses
import logging

import numpy as np

from .lm import spd

_log = logging.getLogger("diffguide")
#: Draws of the nonlinearity check.
PROBE = 2
#: Largest missed χ² (whitened) one posterior draw away for which the linear posterior stands.
NU_TOL = 0.1
#: Randomised-maximum-likelihood samples, and Gauss–Newton steps each.
N_SAMPLES = 16
GN_STEPS = 8
SEED = 20250528


@dataclasses.dataclass(frozen=True)
class Spread:
    """What :func:`nonlinear_spread` found. extra: covariance added to the rails-and-nuisances
    block ``(n_c, n_c)`` (µm²); nu: the check's missed χ² per draw; samples: RML samples taken
    (0: the linear posterior stands); failed: samples whose model failed (dropped)."""

    extra: np.ndarray
    nu: np.ndarray
    samples: int
    failed: int = 0

    def note(self) -> str:
        if not self.samples:
            return ""
        return (f"the model is not linear across the rails' posterior (χ² missed one draw away "
                f"{np.max(self.nu):.3g}): the bands from {self.samples} randomised-maximum-"
                "likelihood samples")


def _channel_projection(problem):
    """``ε ↦ Πε``: a whitened data perturbation less what each channel's zero absorbs (the zero
    is the channel's weighted mean misfit, weights ``w/σ²``)."""
    sigma = np.asarray(problem.meas.sigma, float)
    w = problem.weights / sigma**2
    chan, n_chan = problem.chan, problem.n_chan
    den = np.maximum(np.bincount(chan, w, n_chan), 1e-300)

    def project(eps):
        d = eps * sigma * (problem.weights > 0)
        o = np.bincount(chan, w * d, n_chan) / den
        return (d - o[chan]) / sigma * (problem.weights > 0)

    return project


def _linearise_c(st, xc):
    """``(r, J_c)`` at the rails and nuisances ``xc`` (structure at ``st.x``), or None."""
    p = st.problem
    xf = st.x.copy()
    xf[p.ic] = xc
    r, J, _, ok, _ = p.linearise(xf)
    if not ok or not (np.all(np.isfinite(r)) and np.all(np.isfinite(J))):
        return None
    return r, J[:, p.ic]


def nonlinearity(st, draws, r0, J0) -> np.ndarray:
    """``ν_k = ‖r(x_k) − r̂ − Ĵ(x_k − x̂)‖²`` at the rails-and-nuisances ``draws`` ``(k, n_c)``
    (module docstring); ``inf`` where the model failed."""
    xc0 = st.x[st.problem.ic]
    out = []
    for xk in draws:
        lin = _linearise_c(st, xk)
        out.append(np.inf if lin is None else float(np.sum((lin[0] - r0 - J0 @ (xk - xc0))**2)))
    return np.array(out)


def nonlinear_spread(st, scale: float = 1.0, *, n_samples: int = N_SAMPLES,
                     seed: int = SEED) -> Spread:
    """The covariance (µm², rails and nuisances) to add to the Gauss–Newton posterior
    ``scale² H⁻¹`` where the model is not linear across it (module docstring); ``scale`` is the
    posterior's ``√max(1, χ²/dof)``: the samples are drawn at the spread the bands have."""
    p = st.problem
    ic = p.ic
    xc0 = st.x[ic]
    r0, J0 = st.lin[0], st.lin[1][:, ic]
    Pc = st.Pc
    Lp = np.linalg.cholesky(spd(Pc))
    project = _channel_projection(p)
    rng = np.random.default_rng(seed)
    n = len(ic)
    eps = [scale * project(rng.standard_normal(len(r0))) for _ in range(n_samples)]
    delta = [scale * np.linalg.solve(Lp.T, rng.standard_normal(n)) for _ in range(n_samples)]

    def step(x, r, J, e, d):
        g = J.T @ (r - e) + Pc @ (x - d)
        return x - np.linalg.solve(spd(J.T @ J + Pc), g)

    first = np.array([step(xc0, r0, J0, e, d) for e, d in zip(eps, delta)])
    nu = nonlinearity(st, first[:PROBE], r0, J0)
    if np.all(nu < NU_TOL * scale**2):
        return Spread(np.zeros((n, n)), nu, 0)
    _log.info("fit: the model is not linear across the rails' posterior (missed chi2 %s); "
              "randomised maximum likelihood, %d samples", np.array2string(nu, precision=3),
              n_samples)
    lin_samples, samples, failed = [], [], 0
    for x1, e, d in zip(first, eps, delta):
        x = x1
        for _ in range(GN_STEPS):
            lin = _linearise_c(st, x)
            if lin is None:
                x = None
                break
            x = step(x, lin[0], lin[1], e, d)
        if x is None or not np.all(np.isfinite(x)):
            failed += 1
            continue
        lin_samples.append(x1)
        samples.append(x)
    if len(samples) < 3:
        return Spread(np.zeros((n, n)), nu, 0, failed)
    X, X1 = np.array(samples), np.array(lin_samples)
    b = X.mean(axis=0) - X1.mean(axis=0)
    D = np.cov(X.T) - np.cov(X1.T) + np.outer(b, b)
    w, V = np.linalg.eigh(spd(D))
    extra = (V * np.maximum(w, 0.0)) @ V.T
    return Spread(spd(extra), nu, len(samples), failed)
