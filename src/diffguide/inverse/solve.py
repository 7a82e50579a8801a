r"""Solving a :class:`~.problem.FitProblem`: the Gauss–Newton start, the structure stage, the
Levenberg–Marquardt passes with the outlier pass and the λ re-choice (``method="lm"``), or the
classical linear inversion (``method="linear"``).

Each LM pass minimises ``‖r(x)‖² + xᵀPx`` over the rails and nuisances at the current
structure (:class:`.lm.LevenbergMarquardt`); after it, merged values whose standardised
residual exceeds :data:`OUTLIER_Z` get zero weight (first two passes, at most 5 % of the rows),
the structure is estimated again when the data changed or the rails moved by more than 20 %
(:func:`.structure_stage.structure_stage`), and λ is re-chosen; the pass is repeated when any of
these moved (the weight by a factor 1.5 or more, the structure by 0.1 prior σ), four passes at
most.
"""

import dataclasses
import logging

import numpy as np

from .lm import LevenbergMarquardt, spd
from .problem import FitProblem
from .structure_stage import structure_stage
from .weight import WeightChoice

_log = logging.getLogger("diffguide")
#: Standardised residual beyond which a merged value is an outlier.
OUTLIER_Z = 5.0
#: Passes of LM (each followed by the outlier, structure and weight checks), at most.
MAX_PASSES = 4


@dataclasses.dataclass
class FitState:
    """The estimate while it is solved (host-side, updated in place by this module).

    Attributes:
        problem: the problem (its weights change with the outliers). x: the unknowns ``(n_x,)``.
        lin: ``(r, J, pred, ok, Jc)`` at ``x`` (:meth:`.FitProblem.linearise`; for the linear
            method, at ``x_lin``). x_lin: where the linear method linearised. choice, P, Pc:
            the weight choice, the penalty and its rail-and-nuisance block. cov_q, q_info: the
            structure's covariance (prior σ²) and its stage's note. steps, converged, message:
            LM's account. outliers: rows given zero weight. x_stage: ``x`` at the last stage.
    """

    problem: FitProblem
    x: np.ndarray
    lin: tuple
    x_lin: np.ndarray
    choice: WeightChoice = None
    P: np.ndarray = None
    Pc: np.ndarray = None
    cov_q: np.ndarray = None
    q_info: dict = dataclasses.field(default_factory=dict)
    steps: int = 0
    converged: bool = True
    message: str = "converged"
    outliers: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, int))
    x_stage: np.ndarray = None

    def set_choice(self, choice: WeightChoice) -> None:
        """Take the weight ``choice`` and its penalty."""
        self.choice = choice
        self.P = self.problem.penalty(choice)
        ic = self.problem.ic
        self.Pc = self.P[np.ix_(ic, ic)]


def start(problem: FitProblem) -> FitState:
    """Linearise at straight rails and the prior structure, choose λ there and take the
    Gauss–Newton step in the rails and nuisances. ``ValueError`` when the model fails there."""
    _log.info("fit: %d merged values in %d channels, %d rail + %d structural + %d lead "
              "unknowns; compiling the linearisation", problem.meas.n, problem.n_chan,
              problem.n_theta, problem.n_q, problem.n_l)
    x = np.zeros(problem.n_x)
    lin = problem.linearise(x)
    r, J = lin[0], lin[1]
    if not lin[3] or not np.all(np.isfinite(J)):
        raise ValueError("the machine equilibrium did not converge for straight rails at the "
                         "prior structure; check the machine configuration")
    st = FitState(problem=problem, x=x, lin=lin, x_lin=x.copy(), cov_q=np.eye(problem.n_q))
    st.set_choice(problem.choose(J, r, x, problem.weights))
    st.x[problem.ic] = _gn_start(st, r, J)  # Gauss–Newton start at the prior structure
    return st


def _gn_start(st: FitState, r, J):
    """The rails and nuisances one Gauss–Newton step from ``st.x`` (``r``, ``J`` given)."""
    ic, x = st.problem.ic, st.x
    Jc_ = J[:, ic]
    return x[ic] + np.linalg.solve(spd(Jc_.T @ Jc_ + st.Pc), -(Jc_.T @ r + st.Pc @ x[ic]))


def _structure(st: FitState) -> None:
    """The structure stage at ``st.x`` (``st.lin`` there); then the linearisation at ``q̂``."""
    _log.info("fit: the structure by marginal likelihood")
    r, J = st.lin[0], st.lin[1]
    st.x, st.cov_q, st.q_info = structure_stage(st.problem, st.x, r, J, st.problem.weights)
    st.lin = st.problem.linearise(st.x)


def solve_linear(st: FitState) -> FitState:
    """The classical linear inversion: the structure (if any) on the problem linearised at
    straight rails, then one Gauss–Newton solve there; ``st.lin`` stays the linearisation at
    ``x_lin`` (the residual at the solution is taken from it, :mod:`.posterior`)."""
    ic = st.problem.ic
    if st.problem.n_q:
        st.x[ic] = 0.0
        _structure(st)
        st.x[ic] = _gn_start(st, st.lin[0], st.lin[1])
        st.x_lin = st.x.copy()
        st.x_lin[ic] = 0.0
    return st


class _RailLinearisation:
    """The linearisation in the rails and nuisances only, at the structure of ``st.x``;
    the full linearisations of the latest trial points kept (LM's accepted point is one),
    keyed on the whole unknown vector — structure included — and the rows' weights, so that
    one taken before the structure or the outlier weights changed is never reused."""

    def __init__(self, st: FitState):
        self.st, self.recent = st, {}

    def key(self, xf) -> bytes:
        """The cache key of the full unknowns ``xf`` under the current weights."""
        return np.asarray(xf, float).tobytes() + self.st.problem.weights.tobytes()

    def __call__(self, xc):
        """``(r, J_c, ok, (pred, Jc))`` at the rails and nuisances ``xc`` (the linearisation
        :class:`.lm.LevenbergMarquardt` takes; ``J_c`` the rail-and-nuisance columns)."""
        ic = self.st.problem.ic
        xf = self.st.x.copy()
        xf[ic] = xc
        out = self.st.problem.linearise(xf)
        if len(self.recent) > 4:
            self.recent.clear()
        self.recent[self.key(xf)] = out
        r, J, pred, ok, Jc = out
        return r, (J[:, ic] if J is not None else None), ok, (pred, Jc)

    def at(self, x):
        """The kept full linearisation at ``x`` (all unknowns), else a new one."""
        full = self.recent.get(self.key(x))
        return full if full is not None else self.st.problem.linearise(x)


def solve_lm(st: FitState, rtol: float, max_steps: int, reject_outliers: bool) -> FitState:
    """Levenberg–Marquardt through the model, from the Gauss–Newton start (module docstring)."""
    problem, ic = st.problem, st.problem.ic
    st.lin = problem.linearise(st.x)
    if not (bool(st.lin[3]) and np.all(np.isfinite(st.lin[1]))):  # GN start too far: zero
        st.x[ic] = 0.0
        st.lin = problem.linearise(st.x)
    if problem.n_q:  # the structure at the Gauss–Newton rails
        st.x_stage = st.x.copy()
        _structure(st)
    linearise_c = _RailLinearisation(st)
    for passes in range(1, MAX_PASSES + 1):
        _lm_pass(st, linearise_c, rtol, max_steps, passes)
        if passes >= MAX_PASSES:
            break
        redo = reject_outliers and passes <= 2 and _reject_outliers(st)
        redo = _restructure(st, redo) or redo
        redo = _rechoose(st) or redo
        if not redo:
            break
    return st


def _lm_pass(st: FitState, linearise_c, rtol, max_steps, passes) -> None:
    ic = st.problem.ic
    r, J, pred, _, Jc = st.lin
    x0 = st.x[ic].copy()
    sol = LevenbergMarquardt(rtol=rtol, max_steps=max_steps).solve(
        linearise_c, x0, st.Pc, at=(r, J[:, ic], (pred, Jc)))
    xc, n, message = sol.value, sol.steps, sol.message
    st.x[ic] = xc
    st.steps += n
    st.converged, st.message = sol.converged, message
    if not np.array_equal(xc, x0):  # else st.lin, taken at st.x, still holds
        st.lin = linearise_c.at(st.x)
    r = st.lin[0]
    _log.info("fit: pass %d, %d LM steps, chi2 %.4g, lambda %.3g (kappa %g): %s", passes, n,
              float(r @ r), st.choice.lam, st.choice.kappa, message)


def _reject_outliers(st: FitState) -> bool:
    """Zero weight for the merged values beyond :data:`OUTLIER_Z` standardised residuals (at
    most 5 % of the rows); whether any were rejected (then ``st.lin`` is taken again)."""
    problem, ic = st.problem, st.problem.ic
    r, J = st.lin[0], st.lin[1]
    weights = problem.weights
    scale = np.sqrt(max(_chi2_dof(J[:, ic], r, st.Pc, weights, problem.n_chan), 1.0))
    bad = np.flatnonzero((weights > 0) & (np.abs(r) > OUTLIER_Z * scale))
    if not (bad.size and bad.size <= 0.05 * problem.meas.n):
        return False
    weights = weights.copy()
    weights[bad] = 0.0
    st.outliers = np.union1d(st.outliers, bad)
    st.problem = problem.with_weights(weights)
    r, J, pred, _, Jc = st.problem.linearise(st.x)
    st.lin = (r, J, pred, st.lin[3], Jc)
    return True


def _restructure(st: FitState, redo: bool) -> bool:
    """The structure again when the data changed (``redo``) or the rails moved far from where
    it was estimated (a nonlinear model: the linearisation there no longer holds); whether
    it moved by more than 0.1 prior σ."""
    problem, ic, iq = st.problem, st.problem.ic, st.problem.iq
    x = st.x
    if not problem.n_q or not (redo or np.linalg.norm(x[ic] - st.x_stage[ic])
                               > 0.2 * max(np.linalg.norm(x[ic]), 1e-12)):
        return False
    q_old, st.x_stage = x[iq].copy(), x.copy()
    _structure(st)
    return bool(np.max(np.abs(st.x[iq] - q_old)) > 0.1)


def _rechoose(st: FitState) -> bool:
    """λ re-chosen at the estimate (unless given); whether it moved by a factor 1.5 or more."""
    if st.problem.lam is not None:
        return False
    r, J = st.lin[0], st.lin[1]
    new = st.problem.choose(J, r, st.x, st.problem.weights)
    moved = bool(abs(np.log(new.lam / st.choice.lam)) >= np.log(1.5))
    st.set_choice(new)
    return moved


def _chi2_dof(J, r, P, weights, n_chan):
    """``χ²/dof`` of the rails-and-nuisance problem (``dof = N_used − n_chan − edf``)."""
    H = spd(J.T @ J + P)
    edf = float(np.trace(np.linalg.solve(H, J.T @ J)))
    dof = np.sum(weights > 0) - n_chan - edf
    return float(r @ r / dof) if dof > 0 else 1.0
