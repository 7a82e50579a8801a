r"""The structure stage of the fit: the structural unknowns ``q`` by marginal likelihood at the
current rails (:mod:`.marginal`), and their report.

``q̂ = argmin −2 log p(y | q) + ‖q‖²`` on the problem linearised in the rails and nuisances at
the current estimate, the prior's weight and shape (λ, κ) held at their choice there (a smooth
objective in ``q``; :mod:`.solve` re-chooses λ afterwards and repeats the stage if it moved).
Data with no content — zero to round-off once the channel zeros and the lead are removed —
leave ``q`` at its prior, value and σ (:func:`.marginal.carries_information`). When the data
scatter less than their stated σ, the structure's σ is taken at the stated σ (never narrowed by
a small scatter, like the rails' σ).
"""

import logging

import numpy as np

from .._core.result import RESULTS
from .marginal import (
    carries_information,
    laplace,
    marginal_parts,
    maximise_marginal,
    score_of_parts,
)
from .problem import FitProblem
from .structure import DETERMINED_RATIO, MachineFamily

_log = logging.getLogger("diffguide")


class _MarginalScore:
    """``−2 log p(y | q) + ‖q‖²`` at the rails and nuisances of ``x``, with each structure's
    terms ``(Q, log det, N')`` cached (one linearisation and one SVD per ``q``)."""

    def __init__(self, problem: FitProblem, x, weights, Om_fixed, lam: float):
        self.problem, self.x, self.Om_fixed, self.lam = problem, x, Om_fixed, lam
        self.used = int(np.sum(weights > 0))
        self.parts: dict = {}

    def parts_at(self, q):
        """The marginal likelihood's terms at structure ``q``, or None where the model failed."""
        key = np.asarray(q, float).tobytes()
        if key not in self.parts:
            p = self.problem
            xq = self.x.copy()
            xq[p.iq] = q
            r_q, J_q, _, ok_q, _ = p.linearise(xq)
            if not ok_q or not np.all(np.isfinite(J_q)):
                self.parts[key] = None
            else:  # the data in the total rail and lead unknowns
                Jt, yp, rank_f = p.rail_data(J_q, r_q, self.x)
                self.parts[key] = (*marginal_parts(Jt, yp, self.Om_fixed, self.lam),
                                   self.used - p.n_chan - rank_f)
        return self.parts[key]

    def __call__(self, q, scale2=None):
        p = self.parts_at(q)
        if p is None:
            return np.inf
        return score_of_parts(*p, scale2) + float(q @ q)


def _no_information(problem: FitProblem, x, r, J, weights) -> bool:
    """Whether the data are zero to round-off in the rail and nuisance unknowns (all-zero
    readings, constant channels): then they say nothing on the structure."""
    ic = problem.ic
    used = int(np.sum(weights > 0))
    _, yp0, rank0 = problem.rail_data(J, r, x)
    w0 = weights / np.asarray(problem.meas.sigma)
    scale = (float(np.linalg.norm(w0 * np.asarray(problem.meas.value)))
             + float(np.linalg.norm(r)) + float(np.linalg.norm(J[:, ic] @ x[ic])))
    if carries_information(yp0, used - problem.n_chan - rank0, scale):
        return False
    _log.info("fit: the data are zero to round-off (|y| = %.3g): the structure is the "
              "prior's", float(np.linalg.norm(yp0)))
    return True


def structure_stage(problem: FitProblem, x, r, J, weights):
    """The structure by marginal likelihood at the rails of ``x`` (``r``, ``J`` there; module
    docstring). Returns ``x`` with ``q`` replaced, ``Cov q`` (prior σ², ``(n_q, n_q)``) and a
    note (``iterations``, ``evaluations``, ``at_bound``, ``message``, ``noise_scale``, …)."""
    n_q, iq = problem.n_q, problem.iq
    if _no_information(problem, x, r, J, weights):
        out = x.copy()
        out[iq] = 0.0
        return out, np.eye(n_q), {
            "iterations": 0, "evaluations": 0, "at_bound": [False] * n_q,
            "message": ("the data carry no information on it (zero to round-off once the "
                        "channel zeros and the lead are removed): its value and σ are the "
                        "prior's")}
    c0 = problem.choose(J, r, x, weights, "ml")
    score = _MarginalScore(problem, x, weights, problem.Om_curv + c0.kappa * problem.Om_amp,
                           c0.lam)
    sol = maximise_marginal(score, x[iq], problem.q_bounds)
    q, cov = sol.value, sol.state.cov
    note = {"iterations": sol.steps, "at_bound": list(sol.state.at_bound),
            "message": sol.message, **sol.stats}
    p = score.parts_at(q)
    s2 = p[0] / max(p[2], 1) if p is not None else 1.0  # ŝ², the profiled noise variance
    note["noise_scale"] = float(np.sqrt(s2))
    if s2 < 1.0 and not sol.ended(RESULTS.nonfinite):
        # the data scatter less than their stated σ: the profiled score would take that
        # scatter, model error included, for the noise and narrow the structure's σ; like
        # the rails' σ, it is never narrowed below what the stated σ give (module docstring)
        cov, factors = laplace(lambda v: score(v, 1.0), q, cov, problem.q_bounds)
        note["widened"] = [float(a) for a in factors]
        _log.info("fit: the data scatter %.2g of their stated sigma: the structure's "
                  "sigma is taken at the stated sigma", float(np.sqrt(s2)))
    out = x.copy()
    out[iq] = q
    return out, cov, note


def structure_report(family: MachineFamily, q, cov_q, at_bound) -> dict:
    """Per structural unknown ``{value, sigma, sigma_log, prior_value, prior_range,
    prior_sigma_log, at_bound, determined}`` (thickness in m, preload as a fraction of C; σ of
    the value, ``sigma_log`` of its log) from ``q`` and ``Cov q`` (prior σ units)."""
    out = {}
    prior_sig = family.prior_sigma()
    values = family.values(q * prior_sig)
    for i, name in enumerate(family.names):
        pr = getattr(family.priors, name)
        sd_log = float(np.sqrt(max(cov_q[i, i], 0.0))) * prior_sig[i]
        lo, hi = family.bounds()[i]
        u = q[i] * prior_sig[i]
        out[name] = {
            "value": values[name],
            "sigma": values[name] * sd_log,
            "sigma_log": sd_log,
            "prior_value": pr.value,
            "prior_range": [pr.lo, pr.hi],
            "prior_sigma_log": float(prior_sig[i]),
            "at_bound": bool(at_bound[i] or u <= lo + 1e-6 or u >= hi - 1e-6),
        }
        # at the edge of the interpolation range the model is flat in the parameter: its σ
        # there says nothing, so the parameter is not determined
        out[name]["determined"] = bool(sd_log < DETERMINED_RATIO * prior_sig[i]
                                       and not out[name]["at_bound"])
    return out
