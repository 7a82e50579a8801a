r"""Levenberg–Marquardt on a regularised least-squares objective ``‖r(x)‖² + xᵀPx``, one
linearisation per step, the damped normal equations solved in NumPy.

The damping follows Nielsen's gain-ratio rule (Madsen, Nielsen & Tingleff, *Methods for
non-linear least squares problems*, 2004, §3.2): with ``ρ`` the actual over the predicted
decrease of a step, an accepted step scales μ by ``max(1/3, 1 − (2ρ − 1)³)`` (μ falls where the
quadratic model holds, stays where it barely holds), a rejected one by ``ν`` (doubling ``ν``).
Marquardt's diagonal scaling ``D = diag(H)`` makes μ relative.

The solver is a configuration, :class:`LevenbergMarquardt` (``rtol``, ``max_steps``); its
:meth:`~LevenbergMarquardt.solve` returns a :class:`~.solution.Solution` (the estimate, a
:class:`~diffguide._core.result.RESULTS` code, the steps, :class:`LMState` at the estimate).
"""

import logging
from collections.abc import Callable
from typing import Any

import equinox as eqx
import numpy as np

from .._core.result import RESULTS
from .solution import Solution, finish

_log = logging.getLogger("diffguide.lm")
#: Floor of the noise scale ``ŝ²`` (objective per datum) in Levenberg–Marquardt's stop rule.
_SCALE_FLOOR = 1e-24
#: The first damping after a rejected Gauss–Newton step (relative to ``diag H``).
_MU_FIRST = 1e-3
#: Below this damping the step is taken as Gauss–Newton's (μ = 0).
_MU_MIN = 1e-9
#: Above this damping the objective cannot be decreased along any direction: stop.
_MU_MAX = 1e12
#: A trial point counts as no worse when its objective exceeds the current one by at most this
#: fraction (the model's equilibria are solved to a tolerance: its round-off).
_COST_RTOL = 1e-12
#: Consecutive accepted steps, each gaining less than ``_STALL_GAIN·rtol·ŝ²``, that end the
#: search when the Gauss–Newton decrement is below ``_STALL_DECREMENT·rtol·ŝ²`` (with the
#: default ``rtol`` = 1e-6: steps gaining < 1e-4 ŝ² while the linearisation promises < 0.03 ŝ²,
#: i.e. the quadratic model's optimum within 0.17 posterior σ in every direction).
_STALL_STEPS = 3
_STALL_GAIN = 1e2
_STALL_DECREMENT = 3e4


def spd(H):
    """``H`` symmetrised, ``(H + Hᵀ)/2``."""
    H = 0.5 * (H + H.T)
    return H


def _gn_decrement(H, g) -> float:
    """``−gᵀH⁻¹g``'s magnitude: the objective a full Gauss–Newton step would still gain (twice
    the quadratic model's decrease is ``gᵀH⁻¹g``); ``inf`` where ``H`` is singular."""
    try:
        return float(g @ np.linalg.solve(H, g))
    except np.linalg.LinAlgError:
        return np.inf


class LMState(eqx.Module):
    """Levenberg–Marquardt's state at its estimate ``x``.

    Attributes:
        residual: ``r(x)`` ``(n_r,)``. jacobian: ``∂r/∂x`` ``(n_r, n_x)``. aux: what the
        linearisation returned beside them (carried along). cost: ``‖r‖² + xᵀPx``.
        damping: Marquardt's μ (relative to ``diag H``; 0: a Gauss–Newton step).
    """

    residual: np.ndarray
    jacobian: np.ndarray
    aux: Any
    cost: float
    damping: float


class LevenbergMarquardt(eqx.Module):
    """Levenberg–Marquardt on ``‖r(x)‖² + xᵀPx`` with Marquardt's diagonal scaling and
    Nielsen's damping rule (module docstring); one linearisation per step (the fit's model is
    nearly linear in µm-sized rail errors, so the Gauss–Newton step, μ = 0, is tried first).

    Stops, converged, when the Gauss–Newton decrement ``gᵀH⁻¹g`` (the objective a full step
    would still gain on the model linearised here) is below ``rtol·ŝ²`` — a change of the
    objective far below the noise scale means nothing statistically — or when
    :data:`_STALL_STEPS` accepted steps in a row each gained little while the decrement is
    statistically negligible (where the
    objective is flat along a curved valley — a small λ, a direction the data barely see — the
    linearisation promises more than the model holds, its weak directions within the Jacobian's
    round-off: steps realise a small fraction of it at any damping, and without this rule LM
    crawls to its step limit). The two stalled-rule thresholds are :data:`_STALL_GAIN` and
    :data:`_STALL_DECREMENT` times ``rtol·ŝ²``. ``ŝ²`` is the objective per datum at the
    current point (≈ 1 when the stated σ are right; with σ all stated 10⁹× too large it is
    10⁻¹⁸, and the rule stays the same rule), floored at :data:`_SCALE_FLOOR` (data that are
    zero to round-off stop at once).

    Arguments:
        rtol: the stopping tolerance, relative to the noise scale ``ŝ²`` (dimensionless), > 0.
        max_steps: steps at most (each one linearisation), >= 0.
    """

    rtol: float = eqx.field(static=True, default=1e-6)
    max_steps: int = eqx.field(static=True, default=60)

    def __check_init__(self):
        if not self.rtol > 0:
            raise ValueError(f"rtol must be > 0, got {self.rtol!r}")
        if not (isinstance(self.max_steps, (int, np.integer)) and self.max_steps >= 0):
            raise ValueError(f"max_steps must be an integer >= 0, got {self.max_steps!r}")

    def solve(self, fn: Callable, x0, penalty, *, at: tuple | None = None,
              throw: bool = False) -> Solution:
        """Minimise ``‖r(x)‖² + xᵀPx`` from ``x0``.

        Arguments:
            fn: ``fn(x) -> (r, J, ok, aux)``: the residual ``(n_r,)`` and its Jacobian
                ``(n_r, n_x)`` at ``x``, whether the model converged there, and anything to
                carry along with them (returned in :attr:`LMState.aux`).
            x0: the start ``(n_x,)``.
            penalty: ``P`` ``(n_x, n_x)``, symmetric positive semi-definite.
            at: ``(r, J, aux)`` at ``x0`` where the caller has them (else ``fn(x0)``).
            throw: raise ``RuntimeError`` (the message) unless the solve converged.

        Returns a :class:`~.solution.Solution`: ``value`` the estimate (the best point found),
        ``result`` ``successful``, ``nonlinear_max_steps_reached`` or ``stagnation`` (the
        damping reached :data:`_MU_MAX`: no direction decreases the objective), ``steps``,
        ``message``, ``state`` an :class:`LMState`, ``stats`` ``{"rejected": steps not
        taken}``.
        """
        x, P = np.asarray(x0), penalty
        if at is None:
            r, J, _, aux = fn(x)
        else:
            r, J, aux = at
        cost = float(r @ r + x @ P @ x)
        mu, nu, stalled, rejected = 0.0, 2.0, 0, 0

        def done(result, steps, message):
            return finish(x, result, LMState(r, J, aux, cost, mu), steps, message,
                          {"rejected": rejected}, throw=throw)

        for step in range(1, self.max_steps + 1):
            tol = self.rtol * max(cost / max(len(r), 1), _SCALE_FLOOR)
            H = spd(J.T @ J + P)
            g = J.T @ r + P @ x
            decrement = _gn_decrement(H, g)
            if decrement < tol:
                return done(RESULTS.successful, step - 1, "converged")
            try:
                delta = -np.linalg.solve(H + mu * np.diag(np.diag(H)), g)
            except np.linalg.LinAlgError:
                mu, nu, rejected = max(mu * nu, _MU_FIRST), 2 * nu, rejected + 1
                continue
            predicted = float(-2 * g @ delta - delta @ H @ delta)  # the quadratic model's
            r_t, J_t, ok_t, aux_t = fn(x + delta)
            cost_t = (float(r_t @ r_t + (x + delta) @ P @ (x + delta))
                      if ok_t and np.all(np.isfinite(J_t)) else np.inf)
            rho = (cost - cost_t) / predicted if predicted > 0 else -np.inf
            _log.debug("LM step %d: cost %.12g, trial %.12g, GN decrement %.3g (tol %.3g), "
                       "mu %.3g, gain ratio %.3g", step, cost, cost_t, decrement, tol, mu, rho)
            if cost_t <= cost * (1 + _COST_RTOL):
                gain = cost - cost_t
                x, r, J, aux, cost = x + delta, r_t, J_t, aux_t, cost_t
                stalled = stalled + 1 if (gain < _STALL_GAIN * tol
                                          and decrement < _STALL_DECREMENT * tol) else 0
                if stalled >= _STALL_STEPS:
                    return done(RESULTS.successful, step, "converged")
                mu *= max(1 / 3, 1 - (2 * min(max(rho, 0.0), 1.0) - 1) ** 3)
                mu = 0.0 if mu < _MU_MIN else mu
                nu = 2.0
            else:
                mu, nu, rejected = max(mu * nu, _MU_FIRST), 2 * nu, rejected + 1
                if mu > _MU_MAX:
                    return done(RESULTS.stagnation, step, (
                        "Levenberg-Marquardt cannot decrease the objective further (the "
                        "damping reached 1e12); the best estimate so far is returned"))
        return done(RESULTS.nonlinear_max_steps_reached, self.max_steps, (
            f"Levenberg-Marquardt stopped after {self.max_steps} steps without meeting its "
            "tolerance; the best estimate so far is returned"))
