r"""Rail geometric error profiles: the rail's deviation from a straight line, per plane.

A profile maps the rail coordinate ``s`` (m, along X) to the rail's displacement
``(e_y(s), e_z(s))`` (m): horizontal (+Y) and vertical (+Z) straightness deviation of the rail's
running grooves. Profiles are ``eqx.Module`` pytrees, so every array field is differentiable.

The source paper's error (Majda 2012, eq. 4; garbled in the
printed text, read as the quadratic below, which reproduces the paper's Fig. 6):
:math:`i(x) = (Δ/2)\,(x/1000 + (x/1000)^2)`, ``x`` in mm, ``Δ = 0.05`` mm.
"""

import abc

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._core.types import Array, Float, ScalarLike

_PLANES = ("vertical", "horizontal")


def _check_plane(plane: str) -> None:
    if plane not in _PLANES:
        raise ValueError(f"plane must be one of {_PLANES}, got {plane!r}")


def _in_plane(value, plane: str):
    zero = jnp.zeros_like(value)
    return (zero, value) if plane == "vertical" else (value, zero)


class AbstractRailProfile(eqx.Module):
    """A rail straightness error profile ``s ↦ (e_y, e_z)`` (m → m)."""

    @abc.abstractmethod
    def __call__(self, s: Float[Array, "..."]) -> tuple[Float[Array, "..."], Float[Array, "..."]]:
        """Horizontal and vertical deviation (m) at rail coordinates ``s`` (m)."""


class StraightRail(AbstractRailProfile):
    """A perfect rail: zero deviation everywhere."""

    def __call__(self, s):
        zero = jnp.zeros_like(jnp.asarray(s, dtype=float))
        return zero, zero


class SinusoidalRail(AbstractRailProfile):
    """``e(s) = amplitude·sin(2π s / wavelength + phase)`` in one plane.

    Arguments:
        amplitude: (m). wavelength: (m), > 0. phase: (rad).
        plane: ``"vertical"`` (e_z) or ``"horizontal"`` (e_y).
    """

    amplitude: ScalarLike
    wavelength: ScalarLike
    phase: ScalarLike = 0.0
    plane: str = eqx.field(static=True, default="vertical")

    def __check_init__(self):
        _check_plane(self.plane)

    def __call__(self, s):
        s = jnp.asarray(s, dtype=float)
        value = self.amplitude * jnp.sin(2 * jnp.pi * s / self.wavelength + self.phase)
        return _in_plane(value, self.plane)


class PaperPolynomialRail(AbstractRailProfile):
    r"""Majda (2012) eq. 4: :math:`i(s) = (Δ/2)(s/L + (s/L)^2)` with ``L = 1 m`` (x/1000 in mm).

    Arguments:
        delta: Δ (m), 0.05 mm in the paper.
        plane: ``"vertical"`` or ``"horizontal"``.
    """

    delta: ScalarLike = 0.05e-3
    plane: str = eqx.field(static=True, default="vertical")

    def __check_init__(self):
        _check_plane(self.plane)

    def __call__(self, s):
        s = jnp.asarray(s, dtype=float)
        return _in_plane(0.5 * self.delta * (s + s**2), self.plane)


class BumpRail(AbstractRailProfile):
    """A smooth local bump ``e(s) = amplitude·exp(−((s − center)/width)²)`` in one plane.

    Arguments:
        amplitude: (m). center: (m). width: (m), > 0.
        plane: ``"vertical"`` or ``"horizontal"``.
    """

    amplitude: ScalarLike
    center: ScalarLike = 0.0
    width: ScalarLike = 0.05
    plane: str = eqx.field(static=True, default="vertical")

    def __check_init__(self):
        _check_plane(self.plane)

    def __call__(self, s):
        s = jnp.asarray(s, dtype=float)
        return _in_plane(
            self.amplitude * jnp.exp(-(((s - self.center) / self.width) ** 2)), self.plane
        )


def _basis(xp, u, n_coeffs: int):
    """:func:`bspline_basis` in the array namespace ``xp`` (``numpy`` or ``jax.numpy``)."""
    n_seg = n_coeffs - 3
    i = xp.clip(xp.floor(u), 0, n_seg - 1).astype(int)
    t = u - i
    w = xp.stack(
        [
            (1 - t) ** 3 / 6,
            (3 * t**3 - 6 * t**2 + 4) / 6,
            (-3 * t**3 + 3 * t**2 + 3 * t + 1) / 6,
            t**3 / 6,
        ],
        axis=-1,
    )
    return i, w


def bspline_basis(u: Float[Array, "..."], n_coeffs: int) -> tuple[Array, Array]:
    """Uniform cubic B-spline basis at knot-space coordinates ``u`` (segment ``i`` is ``[i, i+1)``).

    Returns ``(index, weights)``: the first of the four coefficients that act at ``u`` and their
    weights, shapes ``(...,)`` and ``(..., 4)``. Outside ``[0, n_coeffs − 3]`` the end segment's
    cubic is continued (smooth extrapolation).
    """
    return _basis(jnp, u, n_coeffs)


def bspline_matrix(s, start: float, spacing: float, n_coeffs: int) -> np.ndarray:
    """Dense collocation matrix ``B[i, k]`` of the uniform cubic B-spline at points ``s`` (m).

    Evaluated in NumPy (the same formula as :func:`bspline_basis`): eager JAX operations here
    would compile a small program for every new length of ``s``."""
    u = (np.asarray(s, dtype=float) - start) / spacing
    idx, w = _basis(np, u, n_coeffs)
    B = np.zeros((len(u), n_coeffs))
    for k in range(4):
        np.add.at(B, (np.arange(len(u)), idx + k), w[:, k])
    return B


def knot_grid(start: float, end: float, spacing: float) -> tuple[float, float, int]:
    """The uniform cubic B-spline knots that cover ``[start, end]`` (m) at ``spacing`` (m):
    ``(start, spacing, n_coeffs)``, with ``n_coeffs − 3 = ⌈(end − start)/spacing⌉ ≥ 1`` knot
    intervals (the last knot at or just beyond ``end``)."""
    if not spacing > 0:
        raise ValueError(f"spacing (knot spacing) must be > 0 m, got {spacing!r}")
    n_seg = max(int(np.ceil((end - start) / spacing - 1e-9)), 1)
    return float(start), float(spacing), n_seg + 3


def knot_centres(start: float, spacing: float, n_coeffs: int) -> np.ndarray:
    """Rail coordinate ``s`` (m) at the centre of each coefficient's basis function,
    ``s₀ + (k − 1)h`` (where a cubic B-spline reproducing a line has coefficient ``k`` equal to
    the line)."""
    return start + (np.arange(n_coeffs) - 1.0) * spacing


#: Largest number of spline segments :meth:`SplineRail.fit` builds (bounded memory).
MAX_SEGMENTS = 5000


class SplineRail(AbstractRailProfile):
    r"""Rail deviation as uniform cubic B-splines in both planes (C² smooth).

    :math:`e(s) = \sum_k c_k\,B_3((s - s_0)/h - k + 1)` over knots ``s₀ + i·h``, ``i = 0 … n−3``
    (``n`` coefficients per plane). The coefficients (m) are the natural unknowns of the
    identification and differentiable.

    Arguments:
        start: first knot ``s₀`` (m). spacing: knot spacing ``h`` (m), > 0.
        vertical: coefficients of ``e_z`` (m), shape ``(n,)``, ``n ≥ 4``.
        horizontal: coefficients of ``e_y`` (m), shape ``(n,)``.
    """

    start: float = eqx.field(static=True)
    spacing: float = eqx.field(static=True)
    vertical: Float[Array, " n"]
    horizontal: Float[Array, " n"]

    def __check_init__(self):
        if not self.spacing > 0:
            raise ValueError(f"spacing (knot spacing) must be > 0 m, got {self.spacing!r}")
        n = np.shape(self.vertical)
        if len(n) != 1 or n[0] < 4 or np.shape(self.horizontal) != n:
            raise ValueError(
                "vertical and horizontal must be 1-D coefficient arrays of the same length >= 4, "
                f"got shapes {n} and {np.shape(self.horizontal)}"
            )

    @property
    def n_coeffs(self) -> int:
        return np.shape(self.vertical)[0]

    @property
    def end(self) -> float:
        """Last knot (m)."""
        return self.start + (self.n_coeffs - 3) * self.spacing

    def __call__(self, s):
        s = jnp.asarray(s, dtype=float)
        idx, w = bspline_basis((s - self.start) / self.spacing, self.n_coeffs)
        # both planes' four active coefficients in one gather (a small traced program)
        c = jnp.stack([jnp.asarray(self.horizontal), jnp.asarray(self.vertical)])
        e = jnp.sum(c[:, idx[..., None] + jnp.arange(4)] * w, axis=-1)
        return e[0], e[1]

    @classmethod
    def fit(
        cls,
        s,
        vertical,
        horizontal,
        *,
        spacing: float | None = None,
        start: float | None = None,
        end: float | None = None,
        smoothing: float = 1e-9,
    ) -> "SplineRail":
        """Spline through sampled deviations (m at ``s`` in m), by least squares.

        The knot spacing defaults to the median sample spacing (the spline then interpolates
        the samples); a tiny second-difference penalty (``smoothing``, relative) makes the
        coefficients unique where samples are sparse. ``start``/``end`` extend the knot range
        beyond the samples (the spline continues the end cubic there).
        """
        s = np.asarray(s, dtype=float)
        order = np.argsort(s)
        s = s[order]
        if spacing is None:
            steps = np.diff(s)
            steps = steps[steps > 0]
            if steps.size == 0:
                raise ValueError("at least two distinct positions s are needed to fit a rail")
            spacing = float(np.median(steps))
        lo = s[0] if start is None else min(start, s[0])
        hi = s[-1] if end is None else max(end, s[-1])
        if not (hi - lo) / spacing <= MAX_SEGMENTS:
            raise ValueError(
                f"the knot spacing {spacing:.3g} m over {hi - lo:.3g} m would need more than "
                f"{MAX_SEGMENTS} spline segments; samples closer than "
                f"{(hi - lo) / MAX_SEGMENTS:.3g} m "
                "are not supported"
            )
        lo, spacing, n = knot_grid(lo, hi, spacing)
        B = bspline_matrix(s, lo, spacing, n)
        D = np.diff(np.eye(n), 2, axis=0)
        lam = smoothing * np.trace(B.T @ B) / max(np.trace(D.T @ D), 1.0)
        A = B.T @ B + lam * D.T @ D
        coeffs = [
            np.linalg.solve(A, B.T @ np.asarray(v, dtype=float)[order])
            for v in (vertical, horizontal)
        ]
        return cls(float(lo), float(spacing), jnp.asarray(coeffs[0]), jnp.asarray(coeffs[1]))


#: Default width (m) of a rail joint's step: the rise of the smoothed step (see :func:`joint_ramp`).
JOINT_WIDTH = 5e-3


def joint_ramp(s, joints, width: float = JOINT_WIDTH, xp=jnp):
    r"""Unit steps at the rail joints ``joints`` (m), smoothed over ``width`` (m).

    :math:`H(u) = 6u^5 - 15u^4 + 10u^3` with ``u = clip((s − s_j)/w + 1/2, 0, 1)``: 0 before
    ``s_j − w/2``, 1 after ``s_j + w/2``, twice continuously differentiable (the contact solve
    and its gradients see no kink). Returns ``(..., len(joints))``, the last axis per joint.
    Evaluated in ``xp`` (:mod:`jax.numpy`, or :mod:`numpy` for the fit's matrices).
    """
    s = xp.asarray(s, dtype=float)[..., None]
    u = xp.clip((s - xp.asarray(joints, dtype=float)) / width + 0.5, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u**2)


class SteppedRail(AbstractRailProfile):
    r"""A :class:`SplineRail` with a step at each rail joint: where two rail segments meet, the
    running grooves of the next segment sit a little higher or to the side.

    :math:`e(s) = e_{spline}(s) + \sum_j h_j\,H((s - s_j)/w)` per plane (:func:`joint_ramp`).

    Arguments:
        spline: the smooth part. joints: joint positions ``s_j`` (m), static. width: the
            step's rise ``w`` (m), static. vertical_steps, horizontal_steps: step heights
            ``h_j`` (m), shape ``(len(joints),)``.
    """

    spline: SplineRail
    joints: tuple[float, ...] = eqx.field(static=True)
    width: float = eqx.field(static=True)
    vertical_steps: Float[Array, " j"]
    horizontal_steps: Float[Array, " j"]

    def __check_init__(self):
        if not self.width > 0:
            raise ValueError(f"width (of a rail joint's step) must be > 0 m, got {self.width!r}")
        n = (len(self.joints),)
        if np.shape(self.vertical_steps) != n or np.shape(self.horizontal_steps) != n:
            raise ValueError(
                f"vertical_steps and horizontal_steps must have shape {n} (one per joint), got "
                f"{np.shape(self.vertical_steps)} and {np.shape(self.horizontal_steps)}"
            )

    def __call__(self, s):
        ey, ez = self.spline(s)
        H = joint_ramp(s, self.joints, self.width)
        h, v = jnp.asarray(self.horizontal_steps), jnp.asarray(self.vertical_steps)
        return ey + H @ h, ez + H @ v


def basis_rail(start: float, spacing: float, vertical, horizontal, joints=(),
               width: float = JOINT_WIDTH) -> "SplineRail | SteppedRail":
    """The rail of one coefficient vector per plane: the spline's ``n`` coefficients followed by
    one step height per joint (m), as the fit's unknowns are laid out
    (:class:`~diffguide.inverse.basis.RailBasis`); a :class:`SplineRail` without joints."""
    if not joints:
        return SplineRail(start, spacing, vertical, horizontal)
    n = np.shape(vertical)[0] - len(joints)
    return SteppedRail(SplineRail(start, spacing, vertical[:n], horizontal[:n]), tuple(joints),
                       float(width), vertical[n:], horizontal[n:])
