r"""Hertz point contact of two elastic bodies with aligned principal curvatures, exact solution.

For relative curvature sums :math:`A ≤ B` (:math:`A = 1/(2R_a)`, :math:`B = 1/(2R_b)`, with
:math:`1/R = 1/R_1 + 1/R_2` in each principal plane, concave surfaces negative) and the contact
modulus :math:`1/E^* = (1-ν_1^2)/E_1 + (1-ν_2^2)/E_2`, the contact ellipse has semi-axes
:math:`a ≥ b` (``a`` along the direction of ``A``), eccentricity :math:`e^2 = 1 - b^2/a^2`, and
(Johnson, *Contact Mechanics*, eqs. 3.68–3.72, 4.21):

.. math::

    \frac{B}{A} = \frac{E(e)/(1-e^2) - K(e)}{K(e) - E(e)},\qquad
    a^3 = \frac{3F\,(K-E)}{2π E^* A\,e^2},\qquad
    δ = \frac{3 F K(e)}{2π a E^*},

with ``K`` and ``E`` the complete elliptic integrals of the first and second kind. Hence
``δ = c·F^(2/3)``. ``K`` and ``E`` are computed by the arithmetic–geometric mean, ``e`` by
bisection on ``ln(a/b)`` with one Newton step on top, so the result is differentiable in the
geometry (implicit function theorem) as well as in the force.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np

from .._core.checks import concrete
from .._core.types import Array, Float, ScalarLike

_AGM_STEPS = 12  # quadratic convergence: 12 steps reach float64 for b/a down to ~1e-30
_BISECT_STEPS = 80


def elliptic_ke(ratio: Float[Array, "..."]) -> tuple[Float[Array, "..."], Float[Array, "..."]]:
    r"""Complete elliptic integrals ``K(m)``, ``E(m)`` for ``m = 1 − ratio²``, ``0 < ratio ≤ 1``.

    ``ratio = b/a = √(1−m)`` is the complementary modulus, which keeps full accuracy for the very
    elongated ellipses of conforming grooves (``m → 1``). Gauss's AGM:
    :math:`K = π / (2\,\mathrm{AGM}(1, \sqrt{1-m}))`,
    :math:`E = K\,(1 - \sum_n 2^{n-1} c_n^2)` with :math:`c_0^2 = m`.
    """
    a = jnp.ones_like(ratio)
    b = ratio
    total = 0.5 * (1.0 - ratio**2)  # 2^{-1} c_0^2
    weight = 0.5
    for _ in range(_AGM_STEPS):
        c = 0.5 * (a - b)
        a, b = 0.5 * (a + b), jnp.sqrt(a * b)
        weight = weight * 2.0
        total = total + weight * c**2
    K = jnp.pi / (2.0 * a)
    return K, K * (1.0 - total)


def _k_minus_e_over_m(ratio):
    """``(K − E)/m`` and ``K`` for ``m = 1 − ratio²``, with the circular limit π/4, π/2."""
    near_circle = ratio > 1.0 - 1e-6
    safe = jnp.where(near_circle, 0.5, ratio)
    K, E = elliptic_ke(safe)
    m = 1.0 - safe**2
    general = (K - E) / m
    # series about m = 0: K = π/2 (1 + m/4), (K − E)/m = π/4 (1 + 3m/8)
    m_true = 1.0 - ratio**2
    circle_kme = jnp.pi / 4 * (1 + 3 * m_true / 8)
    circle_K = jnp.pi / 2 * (1 + m_true / 4)
    return jnp.where(near_circle, circle_kme, general), jnp.where(near_circle, circle_K, K)


def _curvature_ratio(log_ab):
    """``B/A`` as a function of ``t = ln(a/b)`` (increasing from 1 at t = 0)."""
    ratio = jnp.exp(-log_ab)  # b/a
    kme, K = _k_minus_e_over_m(ratio)
    m = 1.0 - ratio**2
    E = K - kme * m
    # (E/(1-m) - K)/(K - E) = (E/ratio² - K)/(kme·m)
    return (E / ratio**2 - K) / (kme * m)


def _ellipticity_value(target):
    """Bisection on ``t ∈ [0, 40]`` and one Newton step (round-off accuracy), not differentiated."""
    lo = jnp.zeros_like(target)
    hi = jnp.full_like(target, 40.0)

    def body(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        above = _curvature_ratio(jnp.maximum(mid, 1e-7)) > target
        return jnp.where(above, lo, mid), jnp.where(above, mid, hi)

    lo, hi = jax.lax.fori_loop(0, _BISECT_STEPS, body, (lo, hi))
    t0 = jnp.maximum(0.5 * (lo + hi), 1e-7)
    g, dg = jax.jvp(_curvature_ratio, (t0,), (jnp.ones_like(t0),))
    t = t0 - (g - target) / dg
    return jnp.where(target <= 1.0 + 1e-12, 0.0, t)


@jax.custom_jvp
def _ellipticity(target):
    return _ellipticity_value(jax.lax.stop_gradient(target))


@_ellipticity.defjvp
def _ellipticity_jvp(primals, tangents):
    # implicit function theorem on g(t) = B/A: ṫ = (B/A)˙ / g'(t), with t the root itself (so a
    # derivative of this tangent differentiates t again: every order is the implicit one)
    (target,), (target_dot,) = primals, tangents
    t = _ellipticity(target)
    circle = target <= 1.0 + 1e-12
    _, dg = jax.jvp(_curvature_ratio, (jnp.where(circle, 1.0, t),), (jnp.ones_like(t),))
    return t, jnp.where(circle, 0.0, target_dot / dg)


def ellipticity(curvature_ratio: ScalarLike) -> Float[Array, ""]:
    """``ln(a/b)`` of the contact ellipse for a curvature ratio ``B/A ≥ 1``.

    Bisection on ``t = ln(a/b) ∈ [0, 40]`` and one Newton step for the value; derivatives of
    every order from the implicit function theorem, ``dt/d(B/A) = 1/g'(t)`` with
    ``g(t) = B/A`` (0 at the circle, ``B/A = 1``).
    """
    return _ellipticity(jnp.asarray(curvature_ratio, dtype=float))


def point_contact(
    force: ScalarLike, A: ScalarLike, B: ScalarLike, E_star: ScalarLike
) -> dict[str, Float[Array, ""]]:
    """Hertz elliptical point contact.

    Arguments:
        force: normal force (N), ≥ 0.
        A, B: relative curvature sums (1/m), ``0 < A ≤ B`` (``A = B = 1/(2R)`` for a sphere of
            radius ``R`` on a flat).
        E_star: contact modulus (Pa).

    Returns:
        dict with ``approach`` (m), ``a``, ``b`` (semi-axes, m; ``a`` along the direction of
        ``A``), ``p0`` (peak pressure, Pa).
    """
    force = jnp.asarray(force, dtype=float)
    t = ellipticity(jnp.asarray(B) / jnp.asarray(A))
    ratio = jnp.exp(-t)
    kme, K = _k_minus_e_over_m(ratio)
    a = (3.0 * force * kme / (2.0 * jnp.pi * E_star * A)) ** (1.0 / 3.0)
    b = a * ratio
    delta = 3.0 * force * K / (2.0 * jnp.pi * a * E_star)
    p0 = 3.0 * force / (2.0 * jnp.pi * a * b)
    return {"approach": delta, "a": a, "b": b, "p0": p0}


def ball_in_groove_compliance(d, D, E, nu) -> Float[Array, ""]:
    """``c₁`` (m / N^(2/3)) with ``δ = c₁·F^(2/3)`` for one ball–groove contact.

    Ball of diameter ``d`` (m) in a straight groove of diameter ``D > d`` (m), same material
    (``E`` in Pa, ``nu``) on both sides: ``E* = E / (2(1 − ν²))``, ``B = 1/d`` (rolling
    direction), ``A = 1/d − 1/D`` (across the groove).
    """
    if concrete(d, D, E, nu):  # a constant of the model: computed once, not traced
        return jnp.asarray(_ball_in_groove_compliance_np(float(d), float(D), float(E), float(nu)))
    E_star = E / (2.0 * (1.0 - nu**2))
    A = 1.0 / d - 1.0 / D
    B = 1.0 / d
    return point_contact(1.0, A, B, E_star)["approach"]


def _ke_np(ratio: float) -> tuple[float, float]:
    """:func:`elliptic_ke` in NumPy (the same AGM steps)."""
    a, b = 1.0, ratio
    total, weight = 0.5 * (1.0 - ratio**2), 0.5
    for _ in range(_AGM_STEPS):
        c = 0.5 * (a - b)
        a, b = 0.5 * (a + b), np.sqrt(a * b)
        weight *= 2.0
        total += weight * c**2
    K = np.pi / (2.0 * a)
    return K, K * (1.0 - total)


def _kme_np(ratio: float) -> tuple[float, float]:
    """:func:`_k_minus_e_over_m` in NumPy."""
    if ratio > 1.0 - 1e-6:
        m = 1.0 - ratio**2
        return np.pi / 4 * (1 + 3 * m / 8), np.pi / 2 * (1 + m / 4)
    K, E = _ke_np(ratio)
    return (K - E) / (1.0 - ratio**2), K


def _curvature_ratio_np(log_ab: float) -> float:
    ratio = np.exp(-log_ab)
    kme, K = _kme_np(ratio)
    m = 1.0 - ratio**2
    return ((K - kme * m) / ratio**2 - K) / (kme * m)


@functools.lru_cache(maxsize=64)
def _ball_in_groove_compliance_np(d: float, D: float, E: float, nu: float) -> float:
    """:func:`ball_in_groove_compliance` for concrete inputs, in NumPy float64: the same
    bisection and Newton step as :func:`ellipticity` (its derivative by a central difference;
    the step corrects ~1e-16 so that changes nothing), then :func:`point_contact` at F = 1 N.
    A constant of the model computed once per geometry instead of ~10³ traced operations in
    every compiled function that uses the contact law."""
    E_star = E / (2.0 * (1.0 - nu**2))
    A = 1.0 / d - 1.0 / D
    B = 1.0 / d
    target = B / A
    if target <= 1.0 + 1e-12:
        t = 0.0
    else:
        lo, hi = 0.0, 40.0
        for _ in range(_BISECT_STEPS):
            mid = 0.5 * (lo + hi)
            if _curvature_ratio_np(max(mid, 1e-7)) > target:
                hi = mid
            else:
                lo = mid
        t0 = max(0.5 * (lo + hi), 1e-7)
        h = 1e-5 * max(t0, 1e-3)
        dg = (_curvature_ratio_np(t0 + h) - _curvature_ratio_np(t0 - h)) / (2 * h)
        t = t0 - (_curvature_ratio_np(t0) - target) / dg
    ratio = np.exp(-t)
    kme, K = _kme_np(ratio)
    a = (3.0 * kme / (2.0 * np.pi * E_star * A)) ** (1.0 / 3.0)
    return float(3.0 * K / (2.0 * np.pi * a * E_star))


def hamrock_brewe(force, A, B, E_star) -> dict[str, Float[Array, ""]]:
    """Hamrock–Brewe (1983) approximation of :func:`point_contact`, for comparison.

    ``k = a/b ≈ α^(2/π)``, ``E ≈ 1 + 0.5968/α``, ``K ≈ π/2 + (π/2 − 1) ln α`` with ``α = B/A``;
    ``δ = 𝒦 (9/(2𝓔 R)) ^(1/3) (F/(π k E'))^(2/3)`` in their notation (``E' = 2E*``,
    ``1/R = 2(A + B)``).
    """
    alpha = jnp.asarray(B) / jnp.asarray(A)
    k = alpha ** (2.0 / jnp.pi)
    Ee = 1.0 + 0.5968 / alpha
    Ke = jnp.pi / 2 + (jnp.pi / 2 - 1.0) * jnp.log(alpha)
    R = 1.0 / (2.0 * (A + B))
    E_prime = 2.0 * E_star
    delta = Ke * (9.0 / (2.0 * Ee * R) * (force / (jnp.pi * k * E_prime)) ** 2) ** (1.0 / 3.0)
    return {"approach": delta}
