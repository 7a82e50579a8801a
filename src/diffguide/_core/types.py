"""Shape-annotated array aliases shared by all modules (jaxtyping)."""

from jaxtyping import Array, ArrayLike, Bool, Float, Int

Scalar = Float[Array, ""]
ScalarLike = float | Float[ArrayLike, ""]

__all__ = ["Array", "ArrayLike", "Bool", "Float", "Int", "Scalar", "ScalarLike"]
