r"""Prediction from a fit: the σ of the joint errors a fitted model predicts.

.. math::  σ_e(x) = \sqrt{\mathrm{diag}\bigl(J(x)\,\mathrm{Cov}\,c\,J(x)ᵀ\bigr)},\qquad
           J = ∂E(x)/∂c,

``c`` the fitted rails' spline coefficients (m) with their posterior covariance
(:attr:`.fit.RailFit.cov`, the structure's uncertainty carried in), ``E`` the machine's joint
errors (m, rad).
"""

import jax
import jax.numpy as jnp
import numpy as np

from ..guideway.rails import SplineRail
from ..machine.kinematics import joint_errors


def error_sigma(machine, fit, x, point: int) -> np.ndarray:
    """σ of the joint errors at point index ``point`` (m, rad), ``(n_pos, 6)``, at table
    positions ``x`` (m): the rails' posterior covariance pushed through the model's Jacobian
    (one forward-mode pass over the spline coefficients; the structure's own uncertainty enters
    only through the rails' covariance). ``machine`` is the machine the fit describes (its
    fitted structure); ``fit`` a :class:`~.fit.RailFit`."""
    n = fit.basis.n_coeffs
    start, spacing = fit.basis.start, fit.basis.spacing

    def errors(c):
        c = c.reshape(2, 2, n)
        rails = tuple(SplineRail(start, spacing, c[r, 0], c[r, 1]) for r in range(2))
        return joint_errors(machine, rails, x).errors[:, point, :]

    J = np.asarray(jax.jacfwd(errors)(jnp.asarray(np.asarray(fit.coeffs).reshape(-1))))
    return np.sqrt(np.maximum(np.einsum("pek,kl,pel->pe", J, np.asarray(fit.cov), J), 0.0))
