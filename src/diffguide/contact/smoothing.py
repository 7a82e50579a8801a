r"""Compression-only element force, tangent stiffness and energy, smoothed over a length ε.

A rolling element carries force only while its approach ``a`` is positive. The kink of
``max(a, 0)`` is replaced by a C¹ ramp over ``|a| < ε`` (the quadratic, "Huber-type" softplus):

.. math::

    r_ε(a) = \begin{cases} 0 & a ≤ -ε \\ (a+ε)^2/(4ε) & |a| < ε \\ a & a ≥ ε \end{cases},
    \qquad F(a) = K\,r_ε(a)^{α},

so that the force equals the unsmoothed law *exactly* for ``a ≥ ε`` (at preload when
``ε < g₀``), is *exactly* zero for ``a ≤ −ε`` (a lifted-off element), and is continuously
differentiable everywhere. Its energy :math:`φ(a) = \int_{-∞}^{a} F` is convex (F is
non-decreasing), which makes the total potential of a preloaded guideway convex.
Powers of ``r`` use the double-``where`` so that no derivative of any order is NaN at ``r = 0``.
"""

import jax.numpy as jnp

from .._core.types import Array, Float, ScalarLike


def ramp(a: Float[Array, "..."], eps: ScalarLike) -> Float[Array, "..."]:
    """The C¹ smooth ``max(a, 0)``: ``r_ε(a)`` above (m, for ``a`` and ``eps`` in m)."""
    quad = (a + eps) ** 2 / (4.0 * eps)
    return jnp.where(a >= eps, a, jnp.where(a <= -eps, 0.0, quad))


def ramp_slope(a: Float[Array, "..."], eps: ScalarLike) -> Float[Array, "..."]:
    """``dr_ε/da``: 0, ``(a+ε)/(2ε)``, 1 on the three pieces."""
    return jnp.where(a >= eps, 1.0, jnp.where(a <= -eps, 0.0, (a + eps) / (2.0 * eps)))


def _pow(r, p: float):
    """``r**p`` for ``r > 0``; half-integer exponents (the ball law's 1/2, 3/2, 5/2, 4) as square
    roots and products, several times cheaper than the general ``exp(p·log r)``."""
    twice = 2.0 * p
    if twice == round(twice) and 0 <= twice <= 16:
        n = int(round(twice))
        whole = r ** (n // 2) if n // 2 else jnp.ones_like(r)
        return whole * jnp.sqrt(r) if n % 2 else whole
    return r**p


def _safe_pow(r, p):
    positive = r > 0
    return jnp.where(positive, _pow(jnp.where(positive, r, 1.0), p), 0.0)


def element_force(a, K, alpha: float, eps) -> Float[Array, "..."]:
    """Smoothed compression-only force ``F = K·r_ε(a)^α`` (N); ``a``, ``eps`` in m."""
    return K * _safe_pow(ramp(a, eps), alpha)


def element_stiffness(a, K, alpha: float, eps) -> Float[Array, "..."]:
    """Tangent stiffness ``dF/da = K·α·r^(α−1)·r'`` (N/m)."""
    return K * alpha * _safe_pow(ramp(a, eps), alpha - 1.0) * ramp_slope(a, eps)


def element_energy(a, K, alpha: float, eps) -> Float[Array, "..."]:
    r"""Element energy :math:`φ(a) = \int_{-∞}^a F` (J), closed form on each piece.

    .. math::

        φ = \frac{K (a+ε)^{2α+1}}{(4ε)^α (2α+1)} \;(|a|<ε), \qquad
        φ = \frac{2Kε^{α+1}}{2α+1} + \frac{K}{α+1}\bigl(a^{α+1} - ε^{α+1}\bigr) \;(a ≥ ε).
    """
    inside = K * _safe_pow(a + eps, 2 * alpha + 1) / ((4 * eps) ** alpha * (2 * alpha + 1))
    at_eps = 2 * K * eps ** (alpha + 1) / (2 * alpha + 1)
    above = at_eps + K / (alpha + 1) * (_safe_pow(a, alpha + 1) - eps ** (alpha + 1))
    return jnp.where(a >= eps, above, jnp.where(a <= -eps, 0.0, inside))
