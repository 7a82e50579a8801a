r"""Rail geometric error profiles: the rail's deviation from a straight line, per plane.

A profile maps the rail coordinate ``s`` (m, along X) to the rail's displacement
``(e_y(s), e_z(s))`` (m): horizontal (+Y) and vertical (+Z) straightness deviation of the rail's
running grooves. Profiles are ``eqx.Module`` pytrees, so every array field is differentiable.

The source paper's error (Majda 2012, eq. 4; garbled in its text, read as in SPEC §3):
:math:`i(x) = (Δ/2)\,(x/1000 + (x/1000)^2)`, ``x`` in mm, ``Δ = 0.05`` mm.
"""

import abc

import equinox as eqx
import jax.numpy as jnp

from ._types import Array, Float, ScalarLike

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
