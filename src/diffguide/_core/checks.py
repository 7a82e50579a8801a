"""Parameter checks that run on concrete values and stand aside for traced ones (inside
``jit``/``vmap``/``grad``, where the caller's concrete inputs were already checked)."""

import jax


def concrete(*values) -> bool:
    """Whether the values can be checked now (none is a JAX tracer)."""
    return not any(isinstance(v, jax.core.Tracer) for v in values)
