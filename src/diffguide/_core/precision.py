"""float64 policy.

Micrometre effects on metre-scale geometry need float64. The library never changes the global JAX
configuration on import; the CLI, the tests and the notebooks call :func:`enable_x64`, and the
solvers call :func:`require_x64`, which fails with a clear message when float64 is off.
"""

import jax


def enable_x64() -> None:
    """Switch JAX to float64 (call once, before any array is created)."""
    jax.config.update("jax_enable_x64", True)


def x64_enabled() -> bool:
    """Whether JAX creates float64 arrays by default."""
    return bool(jax.config.read("jax_enable_x64"))


def require_x64(what: str) -> None:
    """Raise ``RuntimeError`` when float64 is off.

    In float32 the ~1e-7 relative resolution of metre-scale coordinates is ~0.1 µm, the size of
    the effects diffguide computes, and Newton solves in SI units do not meet their tolerance.
    """
    if not x64_enabled():
        raise RuntimeError(
            f"{what} needs float64, but JAX is in float32 mode (float32 gives errors of the order "
            "of 0.1 µm on metre-scale geometry). Call `diffguide.enable_x64()` (or "
            "`jax.config.update('jax_enable_x64', True)`) before creating any array."
        )
