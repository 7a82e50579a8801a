r"""The structure by marginal likelihood: thickness and preload with the rails integrated out.

Estimating the structure ``q`` jointly with the rails ``θ`` (the joint posterior mode) is biased:
the rails' smoothness prior shrinks ``θ``, and a structure that makes the measured errors more
sensitive to the rails lets smaller rails explain the same data at a smaller penalty. On data
from a machine with a 50 mm table the joint mode put the table at 43 ± 5 mm and, with
straightness data, at 39 ± 4 mm; the rails' error doubled against a fit with the truth's
structure. The cure is the standard one for such scale-like parameters: estimate ``q`` from
the *marginal* likelihood, in which the rails are integrated out under their prior,

.. math::  -2\log p(y\,|\,q) = N'\log Q_q(λ)
           + \log\det\bigl(I + λ^{-1}L^{-1}J_θ(q)^{T}J_θ(q)L^{-T}\bigr),\qquad
           q̂ = \arg\min_q\; -2\log p(y\,|\,q) + ‖q‖²

(the model linearised in the rails at their current estimate, ``J_θ(q)`` its rail Jacobian at
structure ``q``, ``λΩ = λLLᵀ`` the rails' prior precision, the channel zeros and lead terms
projected out, the noise scale profiled out: :func:`marginal_score`; ``‖q‖²`` the structure's
prior, ``q`` in units of its prior σ). The prior's weight and shape are held while ``q`` moves
(the objective is then smooth in ``q``) and chosen again at ``q̂`` (the fit alternates).
The log-determinant is what the joint mode lacks: it
charges a structure for every direction in which it makes the data more sensitive to the rails.
``q`` has one or two components, so :func:`maximise_marginal` takes Newton steps on central
differences (:class:`.trust_region.TrustRegionNewton`); the curvature there gives the Laplace
approximation of ``q``'s posterior, ``Cov q = 2 H⁻¹`` (``H`` the Hessian of the objective above,
never below the prior's ``2I``).

**The differences follow the objective's scale.** The first stencil steps 0.3 prior σ; each
later one half the conditional σ of each component that the last Hessian implies (within
[:data:`.trust_region.MIN_STEP`, :data:`.trust_region.STEP`]), and the search ends when Newton's
predicted decrease of ``−2 log p`` is below :data:`.trust_region.DECREASE_TOL`. A Newton step is
at most a trust radius long (1 prior σ at first, doubled after a step the quadratic model
predicted well, up to :data:`.trust_region.MAX_RADIUS`); a component at a bound of the box whose gradient points out of it is held
there and the step taken in the others, so that a search started far away slides along the
bound rather than stalling against it. With thickness and preload strongly correlated the
objective is a narrow, curved valley. A fixed 0.3 step straddled it, and Newton stopped short of
its floor while reporting convergence. Seen on a 30 mm table measured at 15 points: the search
stopped at (−1.0, +2.1) prior σ (thickness 35 mm, preload 34 %), 2.3 above the objective at
(−1.5, 0.0), near the truth. On 10 noise seeds the thickness came back high every time
(z 1.1–2.8). With the adaptive steps the minimum is found: at or below the objective at the
truth and on a 9 × 9 grid.

**Never narrowed by data that scatter less than stated** (:func:`laplace`). Profiling the noise
scale makes the estimate independent of the stated σ, and takes the scatter left after the fit,
``ŝ² = Q/N'`` (:func:`marginal_parts`), for the noise. Where ``ŝ < 1`` that scatter may be no
noise at all but the model's own error, and the profiled curvature then claims a precision the
instruments never had. Seen: noise-free data simulated on a finer mesh left ``ŝ = 0.007`` and
put the thickness at 55.8 ± 0.31 mm, 19σ from the truth's 50 mm. So, like the rails' σ (widened
by ``√(χ²/dof)`` when above 1, never narrowed), ``Cov q`` is then the Laplace curvature of the
objective with the noise held at the stated σ (``scale2 = 1`` in :func:`marginal_score`),
taken at the profiled estimate: 55.8 ± 7.1 mm, the σ of the same data with noise of the stated σ
drawn on them (6.4–7.0 mm over 3 draws).

**The Laplace σ is checked, and widened where the objective is flatter** (:func:`widen`). The
objective need not be quadratic: a preload the data see only through a small, saturating
effect gives a score that rises steeply on one side and barely on the other. Along each
principal axis ``v_i`` of ``Cov q`` (σ ``σ_i``) the objective is evaluated at ``q̂ ± 2σ_i v_i``;
a Gaussian posterior rises by exactly 4 there. Where it rises by less, ``Δ < 4``, the σ that
the rise implies, ``2σ_i/√Δ``, replaces ``σ_i`` (never above the prior's 1; never narrowed).
Seen on the battery's 70 mm table (8 noise seeds): on 3 of them the Laplace σ called the preload
"determined" at 4.1–5.5 % ± 1.5–1.8 % against a truth of 8 %, while the objective rose by only
1.9–2.9 at +2σ (toward the truth) and 3.1–5.5 at +3σ.

Straight principal axes miss a *curved* valley: they leave its floor, and the objective rises
steeply there although along the floor it barely rises. So each parameter is also checked along
its **profile** — the least objective over the other parameters with that one held (a few
Newton steps) — at ``±2σ_i``, and again at twice the σ that implies, while it keeps rising
more slowly than its quadratic (up to :data:`PROFILE_PASSES` checks a side): the σ becomes half
the distance at which the profile rises by 4 (the likelihood-ratio interval), the correlations
kept. Seen on the 70 mm table measured at 15 points (seed 5): the preload came back
"determined" at 3.7 ± 0.9 % against a truth of 8 % (z −3.2), while its profile at the truth lay
only 1.9 above its least; now 3.7 ± 2.5 %, not determined.

**Data with no content** (:func:`carries_information`). With the noise scale profiled out the
score sees only the *shape* of ``y``: ``y → cy`` adds ``N' log c²`` whatever ``q`` (this is
what makes the structure independent of the scale of the stated σ). Data that are zero — every
reading 0, or each channel constant, so that nothing is left once the channel zeros and the lead
are removed — have no shape: ``y`` is then the model's round-off, ``N' log Q`` follows that
round-off (its differences between structures are of order ``N'``, unrelated to any data), and the
minimum and its curvature are artefacts; seen: all-zero readings gave a 76 ± 0.8 mm table and a
preload "determined by the data". Exactly zero data carry no information on the structure (with
straight rails every structure explains them; the profiled likelihood is then unbounded, ŝ → 0,
for every ``q``), so such data leave ``q`` at its prior with the prior's σ. "Zero" is judged to
round-off: ``‖y‖ ≤`` :data:`NULL_TOL` ``·max(√N', scale)``, against the stated σ (whitened units:
content below 1e-9 σ, which no instrument resolves, and which only a σ overstated a billionfold
reaches) and against ``scale``, the size of the numbers ``y`` is computed from (the round-off of
subtracting large channel zeros).
"""

import dataclasses
import logging

import numpy as np

from .._core.result import RESULTS
from .solution import Solution
from .trust_region import STEP, TrustRegionNewton, difference_steps, floor, stencil
from .weight import _Spectrum, ml_score

_log = logging.getLogger("diffguide")
#: Data whose norm is below this fraction of ``max(√N', scale)`` are zero to round-off
#: (:func:`carries_information`).
NULL_TOL = 1e-9
#: The Laplace σ is checked at this many σ along each principal axis (:func:`widen`).
CHECK_AT = 2.0
#: Newton steps of each profile's inner minimisation (:func:`widen`).
PROFILE_ITER = 4
#: Checks per side of a profile that keeps rising more slowly than its quadratic (:func:`widen`).
PROFILE_PASSES = 3


def carries_information(y, n_eff: int, scale: float = 0.0) -> bool:
    """Whether the whitened data ``y`` (nuisance terms projected out, ``n_eff`` values) differ
    from zero by more than round-off: ``‖y‖ > NULL_TOL · max(√n_eff, scale)``, ``scale`` the
    size (whitened) of the numbers ``y`` was computed from. Where False the data carry no
    information on the structure: the profiled score would only see their round-off (module
    docstring). Non-finite data are left to the caller's checks (True)."""
    norm = float(np.linalg.norm(np.asarray(y, float)))
    if not np.isfinite(norm):
        return True
    return bool(norm > NULL_TOL * max(np.sqrt(max(n_eff, 1)), float(scale)))


def marginal_parts(J, y, Omega, lam: float) -> tuple[float, float]:
    """The two terms of the marginal likelihood of the whitened linearised problem ``y ≈ Jθ``
    under the prior precision ``λΩ`` (:mod:`.weight`): the quadratic form ``Q`` (``Q/N'`` is the
    noise variance the profile takes, ``ŝ²``; 1 where the data scatter as their stated σ say)
    and ``log det(I + λ⁻¹J̃ᵀJ̃)``. One SVD; :func:`score_of_parts` makes the score of them."""
    sp = _Spectrum(np.asarray(J, float), np.asarray(y, float), np.asarray(Omega, float))
    Q, logdet = sp.ml_parts(float(lam))
    return float(Q), float(logdet)


def score_of_parts(Q: float, logdet: float, n_eff: int, scale2: float | None = None) -> float:
    """``-2 log p(y | q)`` (up to a constant) from :func:`marginal_parts`: the noise scale
    profiled out, ``N' log Q + log det``; with ``scale2`` the noise variance (whitened units: 1 is
    the stated σ) held at that value instead, ``Q/s² + N' log s² + log det``."""
    if scale2 is None:
        return float(ml_score(Q, logdet, n_eff))
    return float(Q / scale2 + n_eff * np.log(scale2) + logdet)


def marginal_score(J, y, Omega, n_eff: int, lam: float, scale2: float | None = None) -> float:
    """``-2 log p(y | q)`` (up to a constant) of the whitened linearised problem ``y ≈ Jθ``
    under the prior precision ``λΩ``, the noise scale profiled out (:mod:`.weight`'s marginal
    likelihood at the given λ) or, with ``scale2``, held (:func:`score_of_parts`): smooth in
    ``J`` and ``y``, hence in ``q``."""
    return score_of_parts(*marginal_parts(J, y, Omega, lam), n_eff, scale2)


def widen(f, q, cov, lo, hi, at: float = CHECK_AT, grad=None):
    """``Cov q`` widened where the objective ``f`` (``-2 log p + ‖q‖²``) rises more slowly than
    its quadratic model (module docstring): along each eigenvector ``v_i`` of ``cov`` (σ ``σ_i``),
    at ``q ± at·σ_i v_i`` (clipped to ``[lo, hi]``, distance ``t``), a rise ``Δ`` implies the σ
    ``t/√Δ`` (``Δ ≤ 0``: no curvature at all); ``σ_i`` becomes the largest of itself and the two
    sides' implied σ, at most 1 (the prior's). With ``grad`` (``f``'s gradient at ``q``, where
    ``q`` is not ``f``'s minimum) the rise is counted from the tangent plane, ``f(q + d) − f(q)
    − grad·d``: the curvature's, not the slope's. Returns ``(cov, factors)``, ``factors`` the
    ratio new/old σ per axis (1 where unchanged)."""
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    sd = np.sqrt(np.maximum(w, 0.0))
    new = sd.copy()
    f0 = f(q)
    for i in range(len(sd)):
        for sign in (1.0, -1.0):
            qq = np.clip(q + sign * at * sd[i] * V[:, i], lo, hi)
            t = float(np.linalg.norm(qq - q))
            if t < 1e-9 * max(sd[i], 1e-300):
                continue
            with np.errstate(invalid="ignore"):
                rise = f(qq) - f0 - (0.0 if grad is None else float(grad @ (qq - q)))
            if np.isnan(rise):  # the model failed there: nothing learnt on that side
                continue
            implied = t / np.sqrt(rise) if rise > 0 else np.inf
            new[i] = max(new[i], min(implied, 1.0))
    cov = (V * new**2) @ V.T
    if q.size > 1:  # along each parameter, its profile (the valley may curve away from V)
        cov = _profile_widen(f, q, cov, lo, hi, at, grad is not None, f0)
    along = np.sqrt(np.maximum(np.einsum("ji,jk,ki->i", V, cov, V), 0.0))
    factors = np.where(sd > 0, along / np.where(sd > 0, sd, 1.0), 1.0)
    return cov, factors


def _profile(f, q, i, t, cov, lo, hi, iters: int = PROFILE_ITER):
    """The least value of ``f`` over the components other than ``i``, with ``q_i = t``: a few
    Newton steps (central differences, half the conditional σ of ``cov``) from the point the
    quadratic model predicts, ``q_o − P_oo⁻¹P_oi(t − q_i)`` (``P = cov⁻¹``); ``nan`` where the
    model failed."""
    other = np.arange(q.size) != i
    P = np.linalg.inv(cov)
    Poo = P[np.ix_(other, other)]
    h = difference_steps(2.0 * Poo)
    lo_o, hi_o = lo[other] + h, hi[other] - h
    u = q.copy()
    u[i] = t
    u[other] = np.clip(q[other] - np.linalg.solve(Poo, P[other, i] * (t - q[i])), lo_o, hi_o)

    def sub(v):
        w = u.copy()
        w[other] = v
        return f(w)

    with np.errstate(invalid="ignore"):
        best = sub(u[other])
        for _ in range(iters):
            f0, g, H = stencil(sub, u[other], h)
            if not (np.isfinite(f0) and np.all(np.isfinite(g)) and np.all(np.isfinite(H))):
                break
            step = -np.linalg.solve(floor(H), g)
            norm = float(np.linalg.norm(step))
            if norm > 1.0:
                step /= norm
            v = np.clip(u[other] + step, lo_o, hi_o)
            fv = sub(v)
            if not fv < best:
                break
            u[other], best = v, fv
            if norm < 0.1 * float(np.min(h)):
                break
    return best if np.isfinite(best) else np.nan


def _profile_widen(f, q, cov, lo, hi, at, tangent: bool, f0):
    """``cov`` with each parameter's σ widened to what its profile implies: at ``q_i ± at·σ_i``
    the profile (:func:`_profile`) of a Gaussian objective rises by ``at²``; a rise ``Δ`` implies
    ``at·σ_i/√Δ``; the σ becomes the largest of itself and the two sides', at most 1, the
    correlations kept (``D cov D``). ``tangent``: ``q`` is not ``f``'s minimum, so the rise is the
    profile's curvature, ``(p₊ + p₋)/2 − p₀``, on both sides."""
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    new = sd.copy()
    for i in range(q.size):
        d = at * sd[i]
        d = min(d, q[i] - lo[i], hi[i] - q[i]) if tangent else d
        if not d > 1e-9 * max(sd[i], 1e-300):
            continue
        if tangent:
            sides = [float(q[i] + d), float(q[i] - d)]
            p = [_profile(f, q, i, t, cov, lo, hi) for t in sides]
            rise = 0.5 * (p[0] + p[1]) - _profile(f, q, i, q[i], cov, lo, hi)
            if not np.isnan(rise):
                new[i] = max(new[i], min(d / np.sqrt(rise) if rise > 0 else np.inf, 1.0))
            continue
        for sign in (1.0, -1.0):
            # the distance where the profile rises by at²: each pass checks at ``at`` times
            # the σ the last implied (a profile flatter further out widens it again)
            dist, sd_side = d, sd[i]
            for _ in range(PROFILE_PASSES):
                t = float(np.clip(q[i] + sign * dist, lo[i], hi[i]))
                dist = abs(t - q[i])
                if dist < 1e-9 * max(sd[i], 1e-300):
                    break
                rise = _profile(f, q, i, t, cov, lo, hi) - f0
                if np.isnan(rise):  # the model failed there: nothing learnt on that side
                    break
                implied = min(dist / np.sqrt(rise) if rise > 0 else np.inf, 1.0)
                if implied <= 1.05 * sd_side:
                    break
                sd_side = implied
                new[i] = max(new[i], implied)
                if implied >= 1.0:
                    break
                dist = at * implied
    D = np.where(sd > 0, new / np.where(sd > 0, sd, 1.0), 1.0)
    return cov * D[:, None] * D[None, :]


def laplace(f, q, cov0, bounds):
    """``Cov q = 2H⁻¹`` of the objective ``f`` at ``q`` (its Hessian by central differences,
    each step half the conditional σ that ``cov0`` and then the Hessian itself imply, within
    [:data:`.trust_region.MIN_STEP`, :data:`.trust_region.STEP`]; eigenvalues floored at the
    prior's), widened by :func:`widen` where ``f`` rises more slowly than that. For an objective other than the one
    the search minimised (its gradient at ``q`` not zero), the rise is counted from its tangent
    plane at ``q``: its curvature, not its slope. Returns ``(cov, factors)``."""
    bounds = np.asarray(bounds, float)
    steps = difference_steps(2.0 * np.linalg.inv(cov0))
    for _ in range(3):
        with np.errstate(invalid="ignore"):
            _, g, H = stencil(f, q, steps)
        if not (np.all(np.isfinite(H)) and np.all(np.isfinite(g))):
            return np.eye(q.size), np.ones(q.size)
        new = np.minimum(difference_steps(H), STEP)
        if np.all(np.abs(np.log(new / steps)) < np.log(1.5)):
            break
        steps = new
    cov = 2.0 * np.linalg.inv(floor(H))
    return widen(f, q, cov, bounds[:, 0], bounds[:, 1], grad=g)


class _Counted:
    """``score`` with its values at points already evaluated kept (:func:`widen` starts where
    the search stopped) and the points counted."""

    def __init__(self, score):
        self.score, self.seen = score, {}

    def __call__(self, v):
        key = np.asarray(v, float).tobytes()
        if key not in self.seen:
            self.seen[key] = float(self.score(v))
        return self.seen[key]


def maximise_marginal(score, q0, bounds, *,
                      solver: TrustRegionNewton = TrustRegionNewton()) -> Solution:
    """Minimise ``score(q)`` (``-2 log p(y|q) + ‖q‖²``) over the box ``bounds`` (``(n, 2)``,
    prior-σ units) by Newton steps on central differences (``solver``,
    :class:`.trust_region.TrustRegionNewton`), then widen its Laplace covariance where the
    objective is flatter than its quadratic model (:func:`widen`).

    Returns the solver's :class:`~.solution.Solution` with ``state.cov`` the covariance,
    ``Cov q = 2H⁻¹`` at ``q`` (at most the prior's ``I``; the prior's ``I`` when the score could
    not be evaluated around ``q``, ``result`` ``nonfinite``) widened, and ``stats``
    ``{"evaluations": distinct points evaluated, "widened": σ factor per principal axis}``
    (``widened`` absent where the score failed).
    """
    bounds = np.asarray(bounds, float)
    f = _Counted(score)
    sol = solver.solve(f, q0, bounds)
    cov, stats = sol.state.cov, {}
    if not sol.ended(RESULTS.nonfinite):
        cov, factors = widen(f, sol.value, cov, bounds[:, 0], bounds[:, 1])
        stats["widened"] = [float(x) for x in factors]
        if np.any(factors > 1.0 + 1e-9):
            _log.info("fit: the structure's Laplace σ widened by %s along its principal axes "
                      "(the objective rises more slowly than its quadratic model)",
                      ", ".join(f"{x:.2f}" for x in factors))
    stats["evaluations"] = len(f.seen)
    cov = 0.5 * (cov + cov.T)
    return dataclasses.replace(sol, state=dataclasses.replace(sol.state, cov=cov),
                               stats=stats)
