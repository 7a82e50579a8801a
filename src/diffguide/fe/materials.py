"""Linear elastic isotropic materials for the table: cast iron (default) and steel, each value
defined here with its source (:mod:`diffguide.presets` offers them by name).

A :class:`Material` holds Young's modulus ``E`` (Pa), Poisson's ratio ``nu`` (-) and density
``rho`` (kg/m³). The numeric fields are ordinary pytree leaves, so ``E`` may be a traced array
(differentiate the table w.r.t. it with ``eqx.tree_at`` or by building a new ``Material``).
"""

import equinox as eqx
import jax.numpy as jnp

from .._core.types import Array, ScalarLike


def _is_concrete_number(x) -> bool:
    return isinstance(x, (int, float))


class Material(eqx.Module):
    """Isotropic linear elastic material.

    Args:
        E: Young's modulus in Pa, > 0.
        nu: Poisson's ratio, in (-1, 0.5).
        rho: density in kg/m³, >= 0.
        name: label used in messages and plots.
    """

    E: ScalarLike
    nu: ScalarLike
    rho: ScalarLike
    name: str = eqx.field(static=True, default="material")

    def __check_init__(self):
        if _is_concrete_number(self.E) and not self.E > 0:
            raise ValueError(f"Material.E must be > 0 Pa, got {self.E}")
        if _is_concrete_number(self.nu) and not -1.0 < self.nu < 0.5:
            raise ValueError(f"Material.nu must be in (-1, 0.5), got {self.nu}")
        if _is_concrete_number(self.rho) and not self.rho >= 0:
            raise ValueError(f"Material.rho must be >= 0 kg/m³, got {self.rho}")

    @property
    def G(self) -> Array:
        """Shear modulus ``G = E / (2 (1 + nu))`` in Pa."""
        return jnp.asarray(self.E) / (2.0 * (1.0 + jnp.asarray(self.nu)))


def cast_iron() -> Material:
    """Grey cast iron EN-GJL-250: E 103-118 GPa (EN 1561), ν 0.26, 7200 kg/m³; E = 110 GPa."""
    return Material(E=110e9, nu=0.26, rho=7200.0, name="cast iron")


def steel() -> Material:
    """Structural steel: E 210 GPa, ν 0.3, 7850 kg/m³."""
    return Material(E=210e9, nu=0.3, rho=7850.0, name="steel")


#: Grey cast iron EN-GJL-250 (:func:`cast_iron`).
CAST_IRON = cast_iron()
#: Structural steel (:func:`steel`).
STEEL = steel()

MATERIALS = {"cast_iron": CAST_IRON, "steel": STEEL}


def material(name: str) -> Material:
    """Look up a material by name (``"cast_iron"`` or ``"steel"``)."""
    try:
        return MATERIALS[name]
    except KeyError:
        raise ValueError(f"material must be one of {sorted(MATERIALS)}, got {name!r}") from None
