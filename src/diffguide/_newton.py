r"""Newton's method with a backtracking line search on a convex potential, then an optimistix
polish that carries the implicit derivatives.

The equilibria of diffguide are stationary points of convex potentials
:math:`Π(y) = ½yᵀKy − fᵀy + \sum_j φ(a_j(y))`. Plain Newton can overshoot into a region where
whole rows of elements are lifted off (a singular tangent); with an Armijo backtracking on ``Π``
every step decreases the potential and the iteration converges from any start. The converged
point then seeds ``optimistix.root_find(Newton)`` on the residual, which takes one or two steps,
returns the result code and gives derivatives by implicit differentiation (``ImplicitAdjoint``):
the damped loop itself is wrapped in ``stop_gradient`` and never differentiated.
"""

from collections.abc import Callable

import jax
import jax.numpy as jnp
import optimistix as optx

_ARMIJO = 1e-4
_HALVINGS = 40


def damped_newton(
    potential: Callable,
    grad_hess: Callable,
    y0: jax.Array,
    args,
    *,
    max_steps: int = 60,
    tol: float = 1e-9,
) -> jax.Array:
    """Minimise a convex ``potential(y, args)`` by Newton steps with Armijo backtracking.

    ``grad_hess(y, args)`` returns the gradient and Hessian of the potential (closed forms are
    much cheaper to compile than ``jax.hessian``). Stops when the largest Newton step component
    is below ``tol`` (in the units of ``y``) or after ``max_steps``. Not differentiable by
    design (see the module docstring).
    """
    args = jax.lax.stop_gradient(args)

    def newton_step(y):
        g, H = grad_hess(y, args)
        d = -jnp.linalg.solve(H, g)
        # a singular tangent (everything lifted off) falls back to a gradient step
        ok = jnp.all(jnp.isfinite(d))
        d = jnp.where(ok, d, -g / jnp.maximum(jnp.max(jnp.abs(g)), 1e-300))
        return g, d

    def body(state):
        y, _, k = state
        g, d = newton_step(y)
        p0 = potential(y, args)
        slope = jnp.dot(g, d)
        slack = 1e-13 * jnp.abs(p0)

        def shrink(ts):
            t, _ = ts
            return t * 0.5, None

        def too_high(ts):
            t, _ = ts
            return (potential(y + t * d, args) > p0 + _ARMIJO * t * slope + slack) & (
                t > 2.0**-_HALVINGS
            )

        t, _ = jax.lax.while_loop(too_high, shrink, (jnp.asarray(1.0, y.dtype), None))
        step = t * d
        return y + step, jnp.max(jnp.abs(step)), k + 1

    def cond(state):
        _, size, k = state
        return (size > tol) & (k < max_steps)

    y, _, _ = jax.lax.while_loop(cond, body, (y0, jnp.asarray(jnp.inf, y0.dtype), 0))
    return jax.lax.stop_gradient(y)


def solve_equilibrium(
    potential: Callable,
    grad_hess: Callable,
    residual: Callable,
    y0: jax.Array,
    args,
    *,
    rtol: float = 1e-10,
    atol: float = 1e-10,
    max_steps: int = 60,
    polish_steps: int = 20,
    throw: bool = False,
) -> optx.Solution:
    """Damped Newton on ``potential`` (with ``grad_hess``, see :func:`damped_newton`), then
    ``optx.root_find(Newton)`` on ``residual``.

    ``residual(y, args)`` must vanish where ``potential`` is stationary (a scaled gradient). The
    returned ``optx.Solution`` carries the result code of the polish and differentiates
    implicitly with respect to ``args``.
    """
    start = damped_newton(potential, grad_hess, y0, args, max_steps=max_steps, tol=atol * 10)
    return optx.root_find(
        residual,
        optx.Newton(rtol=rtol, atol=atol),
        start,
        args=args,
        max_steps=polish_steps,
        throw=throw,
    )
