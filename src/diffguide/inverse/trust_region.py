r"""Newton's method on central differences in a box, with a trust radius: the search of the
structure's marginal likelihood (:mod:`.marginal`), for objectives of one to three unknowns
whose derivatives are not available (each value costs a linearisation of the fit's model).

**The differences follow the objective's scale.** The first stencil steps :data:`STEP`; each
later one half the conditional σ of each component that the last Hessian implies,
``½√(2/H_ii)`` (within [:data:`MIN_STEP`, :data:`STEP`]; the objective is a ``−2 log`` density,
so ``2H⁻¹`` is a covariance), and the search ends when Newton's predicted decrease is below
:data:`DECREASE_TOL`. A Newton step is at most a trust radius long (1 at first, doubled after a
step the quadratic model predicted well, up to :data:`MAX_RADIUS`); a component at a bound of
the box whose gradient points out of it is held there and the step taken in the others
(projected Newton), so that a search started far away slides along the bound rather than
stalling against it. The Hessian's eigenvalues are floored at 2 (:func:`floor`: the prior
``‖q‖²`` of the structure's objective; the data only add curvature).

The solver is a configuration, :class:`TrustRegionNewton`; :meth:`~TrustRegionNewton.solve`
returns a :class:`~.solution.Solution` with a :class:`TrustRegionState`.
"""

import logging
from collections.abc import Callable

import equinox as eqx
import numpy as np

from .._core.result import RESULTS
from .solution import Solution, finish

_log = logging.getLogger("diffguide")
#: Largest central-difference step (units of the unknowns: prior σ), the first iteration's.
STEP = 0.3
#: Smallest central-difference step (prior σ).
MIN_STEP = 0.02
#: Newton iterations at most; a step whose predicted decrease of the objective is below
#: :data:`DECREASE_TOL` is taken without a check and ends them.
MAX_ITER = 30
#: Largest trust radius of a Newton step (prior σ); the first is 1, doubled after a step the
#: quadratic model predicted well, cut to a step that fell short.
MAX_RADIUS = 4.0
DECREASE_TOL = 0.01


def stencil(f, q, h):
    """Value, gradient and Hessian of ``f`` at ``q`` by central differences (step ``h``, a
    number or one per component)."""
    n = q.size
    h = np.broadcast_to(np.asarray(h, float), (n,))
    f0 = f(q)
    g, H = np.zeros(n), np.zeros((n, n))
    fp, fm = np.zeros(n), np.zeros(n)
    for i in range(n):
        e = np.zeros(n)
        e[i] = h[i]
        fp[i], fm[i] = f(q + e), f(q - e)
        g[i] = (fp[i] - fm[i]) / (2 * h[i])
        H[i, i] = (fp[i] - 2 * f0 + fm[i]) / h[i] ** 2
    for i in range(n):
        for j in range(i + 1, n):
            e = np.zeros(n)
            e[i], e[j] = h[i], h[j]
            fpp, fmm = f(q + e), f(q - e)
            H[i, j] = H[j, i] = ((fpp - fp[i] - fp[j] + 2 * f0 - fm[i] - fm[j] + fmm)
                                 / (2 * h[i] * h[j]))
    return f0, g, H


def difference_steps(H, lo: float = MIN_STEP, hi: float = STEP):
    """Central-difference steps matched to the objective's scale: half the conditional σ of
    each component, ``½√(2/H_ii)``, within ``[lo, hi]``. A valley narrower than a fixed step
    (two strongly correlated unknowns) is otherwise seen smeared, and Newton stops short of
    its floor."""
    cond = np.sqrt(2.0 / np.maximum(np.diag(H), 2.0))
    return np.clip(0.5 * cond, lo, hi)


def _newton_step(H, g, q, lo, hi):
    """The Newton step ``−H⁻¹g`` over the components free to move: a component at a bound of
    the box whose gradient pushes it outward is held there (projected Newton); the step is
    taken in the others, so that the search slides along the bound instead of being clipped
    to a standstill against it."""
    held = ((q <= lo + 1e-9) & (g > 0)) | ((q >= hi - 1e-9) & (g < 0))
    free = ~held
    delta = np.zeros_like(q)
    if np.any(free):
        delta[free] = -np.linalg.solve(H[np.ix_(free, free)], g[free])
    return delta


def floor(H):
    """``H`` with its eigenvalues raised to the prior's 2 (difference noise aside, the data only
    add curvature)."""
    w, V = np.linalg.eigh(0.5 * (H + H.T))
    return (V * np.maximum(w, 2.0)) @ V.T


class TrustRegionState(eqx.Module):
    """The search's state at its estimate.

    Attributes:
        cov: ``2H⁻¹`` ``(n, n)``, ``H`` the last floored Hessian (the Laplace covariance of a
            ``−2 log`` density; the identity where the objective could not be evaluated).
        at_bound: per component, whether it ended at a bound of the (shrunk) box.
        radius: the trust radius (units of the unknowns).
        differences: the central-difference steps of the last stencil ``(n,)``.
    """

    cov: np.ndarray
    at_bound: tuple[bool, ...]
    radius: float
    differences: np.ndarray


class TrustRegionNewton(eqx.Module):
    """Minimise a smooth objective over a box by Newton steps on central differences, each
    at most a trust radius long (module docstring).

    Arguments:
        step: the first and largest central-difference step (units of the unknowns), > 0;
            the box is shrunk by it on each side (the stencil stays inside).
        max_steps: Newton iterations at most, >= 1.
        decrease_tol: the predicted decrease of the objective below which a step ends the
            search, > 0.
        max_radius: the largest trust radius, >= 1.
    """

    step: float = eqx.field(static=True, default=STEP)
    max_steps: int = eqx.field(static=True, default=MAX_ITER)
    decrease_tol: float = eqx.field(static=True, default=DECREASE_TOL)
    max_radius: float = eqx.field(static=True, default=MAX_RADIUS)

    def __check_init__(self):
        if not self.step > 0:
            raise ValueError(f"step must be > 0, got {self.step!r}")
        if not (isinstance(self.max_steps, (int, np.integer)) and self.max_steps >= 1):
            raise ValueError(f"max_steps must be an integer >= 1, got {self.max_steps!r}")
        if not self.decrease_tol > 0:
            raise ValueError(f"decrease_tol must be > 0, got {self.decrease_tol!r}")
        if not self.max_radius >= 1:
            raise ValueError(f"max_radius must be >= 1, got {self.max_radius!r}")

    def solve(self, fn: Callable, x0, bounds, *, throw: bool = False) -> Solution:
        """Minimise ``fn(q)`` (a number; ``inf`` or ``nan`` where it cannot be evaluated) from
        ``x0`` over the box ``bounds`` ``(n, 2)`` shrunk by :attr:`step` on each side.

        Returns a :class:`~.solution.Solution`: ``value`` the estimate, ``result``
        ``successful``, ``nonlinear_max_steps_reached``, ``stagnation`` (no step along the
        Newton direction decreased ``fn`` while the model promised a decrease of more than
        10·``decrease_tol``) or ``nonfinite`` (``fn`` failed around the estimate), ``steps``
        the iterations, ``message``, ``state`` a :class:`TrustRegionState`. ``throw``: raise
        ``RuntimeError`` (the message) unless successful.
        """
        h = self.step
        q = np.asarray(x0, float).copy()
        bounds = np.asarray(bounds, float)
        lo, hi = bounds[:, 0] + h, bounds[:, 1] - h
        q = np.clip(q, lo, hi)
        result, message, iterations = RESULTS.successful, "converged", 0
        cov = np.eye(q.size)
        steps = np.full(q.size, float(h))
        radius = 1.0  # trust radius of a Newton step
        for it in range(1, self.max_steps + 1):
            iterations = it
            with np.errstate(invalid="ignore"):  # inf − inf where the model failed
                f0, g, H = stencil(fn, q, steps)
            if not (np.isfinite(f0) and np.all(np.isfinite(g)) and np.all(np.isfinite(H))):
                result, cov = RESULTS.nonfinite, np.eye(q.size)
                message = ("the model failed near the structure estimate; its uncertainty "
                           "is the prior's")
                break
            Hf = floor(H)
            cov = 2.0 * np.linalg.inv(Hf)
            delta = _newton_step(Hf, g, q, lo, hi)
            norm = float(np.linalg.norm(delta))
            if norm > radius:
                delta *= radius / norm
            decrease = -float(g @ delta) - 0.5 * float(delta @ Hf @ delta)  # the model's, ≥ 0
            new_steps = np.minimum(difference_steps(H), h)
            rescaled = bool(np.any(new_steps < steps / 1.5))  # the stencil was too coarse
            _log.info("fit: structure iteration %d, score %.6g, step %.3g (prior sigma), "
                      "predicted decrease %.3g", it, f0, norm, decrease)
            if decrease < self.decrease_tol and not rescaled:  # the quadratic model is good
                q = np.clip(q + delta, lo, hi)  # for this step: take it (else a short first
                break  # step left q at the start: an artefact of this rule)
            for _ in range(5):
                q_new = np.clip(q + delta, lo, hi)
                f_new = fn(q_new)
                if f_new <= f0:
                    break
                delta *= 0.5
            else:  # no decrease along the Newton direction: a finer stencil may see one
                radius = max(float(np.linalg.norm(delta)), STEP)
                if rescaled:
                    steps = new_steps
                    continue
                if decrease > 10 * self.decrease_tol:
                    result = RESULTS.stagnation
                    message = ("no step decreased the marginal likelihood's objective "
                               "further")
                break
            taken = q_new - q
            model = -float(g @ taken) - 0.5 * float(taken @ Hf @ taken)
            length = float(np.linalg.norm(taken))
            if length >= 0.99 * radius and f0 - f_new >= 0.75 * model:  # the model held to
                radius = min(2.0 * radius, self.max_radius)  # the radius: trust it further
            elif length < 0.99 * radius:
                radius = max(length, STEP)
            steps = new_steps
            q = q_new
        else:
            result = RESULTS.nonlinear_max_steps_reached
            message = f"stopped after {self.max_steps} Newton iterations"
        at_bound = tuple(bool(a or b) for a, b in zip(q <= lo + 1e-9, q >= hi - 1e-9))
        return finish(q, result, TrustRegionState(cov, at_bound, radius, steps), iterations,
                      message, throw=throw)
