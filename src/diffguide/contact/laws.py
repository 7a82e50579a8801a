r"""Rolling-element contact laws: Hertz ball in two grooves, Palmgren roller, the paper's Rivin
form.

Every law relates the *approach* ``a`` of one rolling element (m; the shortening of the distance
between the rail groove and the carriage groove along the element's load line, both contacts of
the element in series) to its force ``F`` (N) by a power law

.. math::  a = c\,F^{1/\alpha}, \qquad F = (a / c)^{\alpha},

with :math:`\alpha = 3/2` for point contacts (balls) and :math:`\alpha = 10/9` for line contacts
(rollers). The compression-only, smoothed force, tangent stiffness and energy of an element live in
:mod:`diffguide.contact.smoothing`; the elliptic Hertz solution in :mod:`diffguide.contact.hertz`.

References: K. L. Johnson, *Contact Mechanics* (1985), §4.2; B. J. Hamrock, D. Brewe,
J. Lubr. Technol. 105 (1983) 171; A. Palmgren, *Ball and Roller Bearing Engineering* (1959);
E. I. Rivin, *Stiffness and Damping in Mechanical Design* (1999); P. Majda, Precis. Eng. 36
(2012) 369, eq. (1).
"""

import abc

import equinox as eqx
import jax.numpy as jnp

from .._core.checks import concrete
from .._core.types import Array, Float, ScalarLike
from .hertz import ball_in_groove_compliance


class AbstractContactLaw(eqx.Module):
    """A power-law rolling-element contact: element approach ``a = c·F^(1/α)``."""

    @property
    @abc.abstractmethod
    def exponent(self) -> float:
        """Force exponent α in ``F ∝ a^α`` (3/2 for balls, 10/9 for rollers)."""

    @abc.abstractmethod
    def compliance(self) -> Float[Array, ""]:
        """Coefficient ``c`` (m / N^(1/α)) of the element approach ``a = c·F^(1/α)``."""

    def approach(self, force: Float[Array, "..."] | ScalarLike) -> Float[Array, "..."]:
        """Element approach (m) under a compressive force ``force`` ≥ 0 (N)."""
        return self.compliance() * jnp.asarray(force) ** (1.0 / self.exponent)

    def force(self, approach: Float[Array, "..."] | ScalarLike) -> Float[Array, "..."]:
        """Unsmoothed compression-only force (N) at element approach ``approach`` (m)."""
        a = jnp.asarray(approach)
        positive = a > 0
        safe = jnp.where(positive, a, 1.0)
        return jnp.where(positive, (safe / self.compliance()) ** self.exponent, 0.0)

    def stiffness_constant(self) -> Float[Array, ""]:
        """``K`` in ``F = K·a^α`` (N / m^α)."""
        return self.compliance() ** (-self.exponent)

    def preload_approach(self, force_per_element: ScalarLike) -> Float[Array, ""]:
        """Preload approach ``g₀`` (m) of an element carrying ``force_per_element`` (N)."""
        return self.approach(force_per_element)

    def resolved(self) -> "PowerLaw":
        """The same law with its coefficient evaluated once (the elliptic Hertz solve is not
        cheap): use inside solvers that evaluate the law many times. Differentiable."""
        return PowerLaw(self.compliance(), self.exponent)


class PowerLaw(AbstractContactLaw):
    """A law given directly by its coefficient: ``a = compliance·F^(1/exponent)``.

    Arguments:
        coefficient: ``c`` (m / N^(1/α)). power: α (static), > 1.
    """

    coefficient: Float[Array, ""]
    power: float = eqx.field(static=True)

    @property
    def exponent(self) -> float:
        return self.power

    def compliance(self) -> Float[Array, ""]:
        return jnp.asarray(self.coefficient)


def _check_positive(name: str, value: float, unit: str) -> None:
    if concrete(value) and not value > 0:
        raise ValueError(f"{name} must be > 0 {unit}, got {value!r}")


def _check_material(E: float, nu: float) -> None:
    _check_positive("E", E, "Pa")
    if concrete(nu) and not -1.0 < nu < 0.5:
        raise ValueError(f"nu (Poisson ratio) must be in (-1, 0.5), got {nu!r}")


def _check_groove(d: float, D: float) -> None:
    _check_positive("d (ball diameter)", d, "m")
    if concrete(d, D) and not D > d:
        raise ValueError(
            f"D (groove diameter) must exceed the ball diameter d = {d!r} m "
            f"(groove conformity D/d > 1, i.e. radius conformity r/d > 0.5), got D = {D!r} m"
        )


class HertzBall(AbstractContactLaw):
    r"""A ball of diameter ``d`` between two straight grooves of diameter ``D`` (rail, carriage).

    Each ball–groove contact is an elliptical Hertz contact with relative curvatures
    ``2/d`` in the rolling direction and ``2/d − 2/D`` across it, solved exactly with complete
    elliptic integrals (:func:`~diffguide.contact.hertz.ball_in_groove_compliance`). The element
    has two such contacts in series, so its approach is twice the approach of one contact.

    Arguments:
        d: ball diameter (m).
        D: groove diameter (m), ``D > d``; conformity ``D/d`` (1.01–1.08 in guideways).
        E: Young's modulus of ball and grooves (Pa).
        nu: Poisson ratio of ball and grooves.
    """

    d: float
    D: float
    E: float = 210e9
    nu: float = 0.3

    def __check_init__(self):
        _check_groove(self.d, self.D)
        _check_material(self.E, self.nu)

    @property
    def exponent(self) -> float:
        return 1.5

    def contact_compliance(self) -> Float[Array, ""]:
        """``c₁`` of one ball–groove contact, ``δ = c₁·F^(2/3)`` (m / N^(2/3))."""
        return ball_in_groove_compliance(self.d, self.D, self.E, self.nu)

    def compliance(self) -> Float[Array, ""]:
        return 2.0 * self.contact_compliance()


class RivinBall(AbstractContactLaw):
    r"""The source paper's ball law (Majda 2012, eq. 1, after Rivin), kept to reproduce the paper.

    Per contact, in SI units:

    .. math::  δ(F) = 1.41\,η\,\sqrt[3]{F^2 \frac{2D-d}{d\,D}}\,\Bigl(\frac{2(1-ν^2)}{E}\Bigr)^{2/3}

    and the element's approach is ``2δ`` (the paper's gap ``g − 2δ``). For the paper's numbers
    (d = 3 mm, D = 1.01 d, η = 1.412) it gives about 5.4× the approach of full Hertz theory
    (2.7 µm against 0.50 µm per contact at 10 N): the form is a rough, conservative estimate.

    Arguments:
        d: ball diameter (m).
        D: groove diameter (m), ``D > d``.
        E: Young's modulus (Pa).
        nu: Poisson ratio.
        eta: the paper's conformity factor η (1 for a ball on a flat; 1.412 in the paper).
    """

    d: float
    D: float
    E: float = 210e9
    nu: float = 0.3
    eta: float = 1.412

    def __check_init__(self):
        _check_groove(self.d, self.D)
        _check_material(self.E, self.nu)
        _check_positive("eta", self.eta, "")

    @property
    def exponent(self) -> float:
        return 1.5

    def contact_compliance(self) -> Float[Array, ""]:
        """``c₁`` of one contact, ``δ = c₁·F^(2/3)`` (m / N^(2/3))."""
        geom = (2 * self.D - self.d) / (self.d * self.D)
        return jnp.asarray(
            1.41 * self.eta * geom ** (1 / 3) * (2 * (1 - self.nu**2) / self.E) ** (2 / 3)
        )

    def compliance(self) -> Float[Array, ""]:
        return 2.0 * self.contact_compliance()


class PalmgrenRoller(AbstractContactLaw):
    r"""A cylindrical roller of effective length ``length`` between two flat raceways (Palmgren).

    Per contact, in the formula's own units (mm, N):
    :math:`δ = 3.84·10^{-5}\,F^{0.9} / l^{0.8}`; two contacts in series per element, so
    ``F ∝ a^(10/9)``. Palmgren's constant holds for steel (E ≈ 210 GPa, ν ≈ 0.3).

    Arguments:
        length: effective (contact) length of the roller (m).
    """

    length: float

    def __check_init__(self):
        _check_positive("length (roller length)", self.length, "m")

    @property
    def exponent(self) -> float:
        return 10.0 / 9.0

    def contact_compliance(self) -> Float[Array, ""]:
        """``c₁`` of one contact, ``δ = c₁·F^0.9`` (m / N^0.9)."""
        l_mm = self.length * 1e3
        return jnp.asarray(1e-3 * 3.84e-5 / l_mm**0.8)

    def compliance(self) -> Float[Array, ""]:
        return 2.0 * self.contact_compliance()
