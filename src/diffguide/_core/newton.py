r"""Newton's method with a backtracking line search on a convex potential, differentiated
implicitly.

The equilibria of diffguide are stationary points of convex potentials
:math:`Π(y) = ½yᵀKy − fᵀy + \sum_j φ(a_j(y))`. Plain Newton can overshoot into a region where
whole rows of elements are lifted off (a singular tangent); with an Armijo backtracking on ``Π``
every step decreases the potential and the iteration converges from any start. The loop is never
differentiated: a ``custom_jvp`` gives the derivatives of the root ``y*(θ)`` of the gradient
``g(y, θ) = ∂Π/∂y`` from the implicit function theorem, ``dy*/dθ = −(∂g/∂y)⁻¹ ∂g/∂θ``, with the
closed-form Hessian's Cholesky factor shared by every tangent (optimistix's ``ImplicitAdjoint``
with LU, used before, ran 10–40 times slower under ``jacfwd`` over many tangents). The rule is
written in differentiable operations on the root itself, so derivatives of every order are the
implicit function theorem's (:func:`_implicit_tangent`).
"""

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from .result import RESULTS

_ARMIJO = 1e-4
_HALVINGS = 40
#: Predicted decrease of Π, relative to |Π|, below which the Newton step is taken without the
#: line search (the Armijo test cannot tell such a change from round-off).
_SETTLED = 1e-8
#: The loop also stops when the next step, extrapolated from the last two full Newton steps as
#: ``s_k (s_k/s_{k-1})²`` (the quadratic rate), is below this fraction of ``tol``: the step that
#: would only confirm convergence (at round-off size) is not taken. A heuristic: it trusts the
#: quadratic rate for one step more, which a tangent that changes abruptly within the last step
#: breaks (a contrived 1-D potential whose branch 10⁶× softer begins 1 nm past the root stops
#: 2e-3 off at tol 1e-9). On the machines it is met with, contacts lifting off included, the
#: error stays below ``tol`` (rollers at 2 % preload, bumps to 12× the preload approach: 0.2
#: ``tol``, the equilibrium's default 1e-9 µm / µrad; ``test_newton_condensed.py``).
_PREDICTED = 1e-3


def _newton_loop(inputs):
    """The primal: damped Newton. Returns ``(y, (converged, steps))``."""
    potential, grad_hess, y0, args, max_steps, tol = inputs

    def body(state):
        y, size, _, _, k, p0 = state
        g, H = grad_hess(y, args)
        d = -jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(H), g)  # H is SPD
        # a singular tangent (everything lifted off) falls back to a gradient step
        finite = jnp.all(jnp.isfinite(d))
        d = jnp.where(finite, d, -g / jnp.maximum(jnp.max(jnp.abs(g)), 1e-300))
        slope = jnp.dot(g, d)
        slack = 1e-13 * jnp.abs(p0)

        # near the solution (a Newton step whose predicted decrease is round-off on Π) the full
        # step is taken without evaluating Π: the last iterations of a batch then skip the
        # line search altogether
        settled = finite & (-slope <= _SETTLED * jnp.abs(p0))

        def too_high(ts):
            t, p = ts
            return jnp.where(
                t > 1.0, ~settled, (p > p0 + _ARMIJO * t * slope + slack) & (t > 2.0**-_HALVINGS)
            )

        def shrink(ts):
            t, _ = ts
            return t * 0.5, potential(y + 0.5 * t * d, args)

        # from t = 2 with an infinite potential: the first pass evaluates the full step, so the
        # potential appears once in the compiled loop (it is most of the program)
        start = (jnp.full((), 2.0, y.dtype), jnp.full((), jnp.inf, y.dtype))
        t, p = jax.lax.while_loop(too_high, shrink, start)
        p = jnp.where(settled, p0 + 0.5 * slope, p)  # Π to second order (Hd = −g)
        newton = finite & (t >= 1.0)
        t = jnp.minimum(t, 1.0)
        step = t * d
        new_size = jnp.max(jnp.abs(step))
        # the convergence rate s_k/s_{k-1}, where both steps were full Newton steps
        rate = jnp.where(newton & state[3], new_size / size, jnp.inf)
        return y + step, new_size, rate, newton, k + 1, p

    def done(size, rate):
        return (size <= tol) | (size * rate**2 <= _PREDICTED * tol)

    def cond(state):
        _, size, rate, _, k, _ = state
        return ~done(size, rate) & (k < max_steps) & ~jnp.isnan(size)  # NaN ends the loop

    inf = jnp.asarray(jnp.inf, y0.dtype)
    init = (y0, inf, inf, jnp.asarray(False), jnp.asarray(0), potential(y0, args))
    y, size, rate, _, k, _ = jax.lax.while_loop(cond, body, init)
    return y, (done(size, rate), k)


@functools.partial(jax.custom_jvp, nondiff_argnums=(0, 1, 2, 3))
def _implicit_solve(potential, grad_hess, max_steps, tol, y0, args):
    """``(y*, converged, steps)``: the minimiser of ``potential`` from ``y0``. Its derivative is
    the implicit function theorem's, ``ẏ = −H⁻¹ (∂g/∂args)·ȧrgs`` with ``H = ∂²Π/∂y²`` at
    ``y*`` (the closed form of ``grad_hess``, SPD at a minimum: one Cholesky factor for all
    tangents); ``y0`` has no influence on ``y*``."""
    y, (converged, steps) = _newton_loop((potential, grad_hess, y0, args, max_steps, tol))
    return y, converged, steps


def _implicit_tangent(grad_hess, y, args, args_dot):
    """``ẏ = −H⁻¹ (∂g/∂args)·ȧrgs`` at the root ``y`` of ``g``.

    Written without ``stop_gradient``: ``y`` here carries the implicit derivative itself (the
    callers pass the custom-differentiated root), so differentiating this tangent again — a
    Hessian, ``jvp`` of ``grad`` — gives ``d(ẏ) = −H⁻¹(Ḣ ẏ + d(∂g/∂args)·ȧrgs)`` with
    ``Ḣ = ∂H/∂y·ẏ + ∂H/∂args·ȧrgs``: derivatives of every order follow from the implicit
    function theorem applied again (a first derivative costs the same: the extra terms only
    appear when the tangent itself is differentiated)."""
    # H and ∂g/∂args·ȧrgs from one trace of grad_hess (the unused Ḣ is dropped by the compiler)
    (_, H), (g_dot, _) = jax.jvp(lambda a: grad_hess(y, a), (args,), (args_dot,))
    return -jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(H), g_dot)


@_implicit_solve.defjvp
def _implicit_solve_jvp(potential, grad_hess, max_steps, tol, primals, tangents):
    y0, args = primals
    _, args_dot = tangents
    y, converged, steps = _implicit_solve(potential, grad_hess, max_steps, tol, y0, args)
    y_dot = _implicit_tangent(grad_hess, y, args, args_dot)
    zero = np.zeros((), dtype=jax.dtypes.float0)
    return (y, converged, steps), (
        y_dot,
        np.broadcast_to(zero, jnp.shape(converged)),
        np.broadcast_to(zero, jnp.shape(steps)),
    )


@functools.partial(jax.custom_jvp, nondiff_argnums=(0,))
def implicit_root(grad_hess: Callable, y: jax.Array, args) -> jax.Array:
    """``y`` itself — a minimiser of a convex potential found by other means (a reduced
    problem, say) — with the derivative of the implicit function theorem w.r.t. ``args``:
    ``ẏ = −H⁻¹ (∂g/∂args)·ȧrgs``, ``(g, H) = grad_hess(y, args)`` (as in
    :func:`solve_equilibrium`); ``y``'s own tangent is ignored."""
    return y


@implicit_root.defjvp
def _implicit_root_jvp(grad_hess, primals, tangents):
    y, args = primals
    _, args_dot = tangents
    # the root again (same value), so that a derivative of this rule sees y's implicit tangent
    # rather than the tangent of however y was found
    y = implicit_root(grad_hess, y, args)
    return y, _implicit_tangent(grad_hess, y, args, args_dot)


def solve_equilibrium(
    potential: Callable,
    grad_hess: Callable,
    y0: jax.Array,
    args,
    *,
    tol: float = 1e-9,
    max_steps: int = 60,
    throw: bool = False,
) -> tuple[jax.Array, RESULTS, jax.Array]:
    """Minimise the convex ``potential(y, args)``; derivatives w.r.t. ``args`` are implicit.

    Arguments:
        potential: ``(y, args) -> Π`` (scalar).
        grad_hess: ``(y, args) -> (∂Π/∂y, ∂²Π/∂y²)`` (closed forms compile far faster than
            ``jax.hessian``); must be global functions or ``functools.partial`` of them.
        y0: starting point. args: everything the potential depends on (a pytree).
        tol: stop when the largest Newton step component is below ``tol`` (units of ``y``),
            or when the next one, extrapolated from the last two full Newton steps with the
            quadratic rate, ``s_k (s_k/s_{k−1})²``, is below ``10⁻³ tol`` (it would be a
            round-off-sized confirmation).
        max_steps: Newton step limit.
        throw: raise (``eqx.error_if``, also under ``jit``) when the solve fails, instead of
            reporting it in ``result`` only. Under ``vmap`` one failure fails the whole batch,
            so batched callers leave it off and read ``result`` per item.

    Returns:
        ``(y, result, steps)``: the minimiser, the result code — ``RESULTS.successful``,
        ``nonfinite`` (an iterate became inf or NaN) or ``nonlinear_max_steps_reached`` — and
        the steps taken.
    """
    y, converged, steps = _implicit_solve(potential, grad_hess, max_steps, tol, y0, args)
    finite = jnp.all(jnp.isfinite(jax.lax.stop_gradient(y)))
    result = RESULTS.where(
        converged,
        RESULTS.successful,
        RESULTS.where(
            finite, RESULTS.nonlinear_max_steps_reached, RESULTS.nonfinite
        ),
    )
    if throw:
        y = result.error_if(y, result != RESULTS.successful)
    return y, result, steps
