r"""The posterior of a solved fit: the rails' and nuisances' covariance given the structure,
the structure's own uncertainty carried in by the delta method, and the χ² account.

.. math::  \mathrm{Cov}\,c = s²H_c⁻¹ + G\,\mathrm{Cov}\,q\,Gᵀ,\qquad H_c = J_cᵀJ_c + P_c,
           \qquad G = ∂ĉ/∂q,

``G`` a secant over ``±σ_q`` along each structural unknown (:func:`structure_sensitivity`),
``s² = max(1, χ²/dof)`` (the bands widen when the model does not explain the data to their
stated σ, never narrow), ``χ²/dof = ‖r‖² / (N − n_channels − edf)``,
``edf = tr(H_c⁻¹J_cᵀJ_c) + tr(I − Cov q)``.

Two corrections follow, each only widening (neither changes the estimate, χ² or ``edf``):

- where the model is not linear across the rails' posterior (rows of rolling elements that
  unload within it), the spread and shift of randomised-maximum-likelihood samples re-linearised
  along the way (:mod:`.spread`; Levenberg–Marquardt fits only);
- in the directions the data do not determine, the prior's scale is floored between its own
  extrapolation and the content the fit found (:mod:`.bands`).
"""

import dataclasses
import logging

import numpy as np

from .bands import Floor, undetermined_floor
from .lm import spd
from .solve import FitState
from .spread import Spread, nonlinear_spread

_log = logging.getLogger("diffguide")
#: Half-step of :func:`structure_sensitivity`'s secant, within these limits (prior σ).
SECANT_STEP_LIMITS = (0.05, 1.0)


@dataclasses.dataclass(frozen=True)
class Posterior:
    """What :func:`posterior` returns. r: the whitened residual at the solution; cov_x:
    ``(n_x, n_x)`` covariance of all unknowns (µm², prior σ² for ``q``), scaled by
    ``sigma_scale²``; G: ``∂ĉ/∂q`` ``(len(ic), n_q)``; chi2, dof, edf, sigma_scale; floor:
    the undetermined directions' floor added to the rails' block (:mod:`.bands`)."""

    r: np.ndarray
    cov_x: np.ndarray
    G: np.ndarray
    chi2: float
    dof: float
    edf: float
    sigma_scale: float
    floor: Floor | None = None
    spread: Spread | None = None

    def notes(self) -> str:
        """What the bands' floor and spread did, for the fit's message (``""``: nothing)."""
        parts = [x.note() for x in (self.spread, self.floor) if x is not None]
        return "".join(f"; bands: {n}" for n in parts if n)


def posterior(st: FitState, method: str) -> Posterior:
    """The posterior of the solved state ``st`` (module docstring); for the linear method the
    residual is the linear model's at the solution."""
    p = st.problem
    ic, iq, n_q = p.ic, p.iq, p.n_q
    r, J = st.lin[0], st.lin[1]
    x, cov_q = st.x, st.cov_q
    if method == "linear":  # residuals of the linear model at the solution
        r = r + J[:, ic] @ (x[ic] - st.x_lin[ic])
    Jcc = J[:, ic]
    Hc = spd(Jcc.T @ Jcc + st.Pc)
    Hc_inv = np.linalg.inv(Hc)
    Hc_inv = 0.5 * (Hc_inv + Hc_inv.T)
    x_at = st.x_lin if method == "linear" else x  # where the model was linearised
    G = structure_sensitivity(st, x_at, Hc_inv)
    edf = float(np.trace(Hc_inv @ (Jcc.T @ Jcc))) + float(np.trace(np.eye(n_q) - cov_q))
    chi2 = float(r @ r)
    used = int(np.sum(p.weights > 0))
    dof = float(used - p.n_chan - edf)
    sigma_scale = float(np.sqrt(max(chi2 / dof, 1.0))) if dof > 0 else 1.0
    cov_x = np.zeros((p.n_x, p.n_x))
    cov_x[np.ix_(ic, ic)] = sigma_scale**2 * Hc_inv + G @ cov_q @ G.T
    cov_x[np.ix_(ic, iq)] = G @ cov_q
    cov_x[np.ix_(iq, ic)] = (G @ cov_q).T
    cov_x[np.ix_(iq, iq)] = cov_q
    spread = None
    if method == "lm":  # the model re-linearised across the posterior (:mod:`.spread`)
        spread = nonlinear_spread(st, sigma_scale)
        cov_x[np.ix_(ic, ic)] += spread.extra
        if spread.samples:
            _log.info("fit: %s", spread.note())
    nt = p.n_theta
    floor = undetermined_floor(p.rail_data(J, st.lin[0], x)[0], st.P[:nt, :nt], p.basis, p.Z,
                               p.Om_curv, p.Om_amp, x[:nt])
    cov_x[:nt, :nt] += floor.extra
    if floor.n_directions:
        _log.info("fit: %s", floor.note())
    return Posterior(r=r, cov_x=cov_x, G=G, chi2=chi2, dof=dof, edf=edf,
                     sigma_scale=sigma_scale, floor=floor, spread=spread)


def structure_sensitivity(st: FitState, x_at, Hc_inv):
    """``G = ∂ĉ/∂q`` at the solution ``x``, ``(len(ic), len(iq))``: how the rails and lead that
    minimise the objective move with each structural unknown, as a secant over ``±σ_q``.

    At each step ``q_v`` the rails are solved again on the model linearised there — one
    Gauss–Newton step from ``x_c``, ``ĉ(q_v) = x_c − H_v⁻¹(J_vᵀr_v + P_c x_c)``, the model being
    all but linear in the rails (``r_v = r(x_at(q_v)) + J_v·(x_c − x_at,c)``: ``x_at``, where
    the model was linearised, is ``x`` for Levenberg–Marquardt) — and ``G_i = (ĉ(q + h) −
    ĉ(q − h))/2h``. The half-step ``h`` is the unknown's posterior σ, ``√Cov q_ii``, within
    :data:`SECANT_STEP_LIMITS` and its bounds (one-sided at a bound). Where the model fails at a
    step the column is the Gauss–Newton ``−H_c⁻¹J_cᵀJ_q``, and a note is logged.
    """
    p = st.problem
    ic, iq, x, J = p.ic, p.iq, st.x, st.lin[1]
    out = np.empty((len(ic), len(iq)))
    for i, k in enumerate(iq):
        h = float(np.clip(np.sqrt(max(st.cov_q[i, i], 0.0)), *SECANT_STEP_LIMITS))
        a, b = max(x_at[k] - h, p.q_bounds[i, 0]), min(x_at[k] + h, p.q_bounds[i, 1])
        c = []
        for v in (a, b) if b > a else ():
            xv = x_at.copy()
            xv[k] = v
            r_v, J_v, _, ok_v, _ = p.linearise(xv)
            if not (ok_v and np.all(np.isfinite(J_v)) and np.all(np.isfinite(r_v))):
                break
            Jv = J_v[:, ic]
            r_v = r_v + Jv @ (x[ic] - x_at[ic])
            c.append(-np.linalg.solve(spd(Jv.T @ Jv + st.Pc), Jv.T @ r_v + st.Pc @ x[ic]))
        if len(c) == 2:
            out[:, i] = (c[1] - c[0]) / (b - a)
        else:
            _log.info("fit: %s: the structure's share of the rails' σ from the Gauss-Newton "
                      "term alone", "the model failed around the structure's estimate"
                      if b > a else "the unknown's bounds leave no room for a step")
            out[:, i] = -Hc_inv @ (J[:, ic].T @ J[:, k])
    return out
