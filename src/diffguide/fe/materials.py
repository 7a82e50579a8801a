"""Linear elastic isotropic materials for the table: cast iron (default) and steel.

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


from .. import presets  # noqa: E402  (imports nothing from diffguide at import time)

#: Grey cast iron EN-GJL-250 (:func:`diffguide.presets.cast_iron`).
CAST_IRON = presets.cast_iron()
#: Structural steel (:func:`diffguide.presets.steel`).
STEEL = presets.steel()

MATERIALS = {"cast_iron": CAST_IRON, "steel": STEEL}


def material(name: str) -> Material:
    """Look up a material by name (``"cast_iron"`` or ``"steel"``)."""
    try:
        return MATERIALS[name]
    except KeyError:
        raise ValueError(f"material must be one of {sorted(MATERIALS)}, got {name!r}") from None
