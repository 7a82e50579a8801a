r"""Small rigid-body motions: the transfer ``u + θ × d`` of a motion from one point to another.

A small rigid motion is ``(u, θ)`` (translation, m; rotation, rad) at a point; at a point offset
by ``d`` (m) the same rigid motion is ``(u + θ × d, θ)``. In matrix form

.. math::  \begin{bmatrix}u'\\θ'\end{bmatrix} =
           \begin{bmatrix}I & -[d]_×\\ 0 & I\end{bmatrix}\begin{bmatrix}u\\θ\end{bmatrix},
           \qquad [d]_× w = d × w.
"""

import jax.numpy as jnp
import numpy as np

from .types import Array, Float


def skew(v: Float[Array, "... 3"], xp=jnp) -> Float[Array, "... 3 3"]:
    """``[v]×``: the matrix with ``skew(v) @ w = v × w``; ``xp`` the array module
    (:mod:`jax.numpy`, or :mod:`numpy` for eager evaluation)."""
    v = xp.asarray(v)
    zero = xp.zeros_like(v[..., 0])
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    rows = [
        xp.stack([zero, -z, y], axis=-1),
        xp.stack([z, zero, -x], axis=-1),
        xp.stack([-y, x, zero], axis=-1),
    ]
    return xp.stack(rows, axis=-2)


def rigid_transfer(d: Float[Array, "... 3"], xp=jnp) -> Float[Array, "... 6 6"]:
    """The ``6 × 6`` map of a small rigid motion ``(u, θ)`` at a point to the point offset by
    ``d`` (m): ``(u + θ × d, θ)`` (module docstring); ``xp`` as for :func:`skew`."""
    d = xp.asarray(d)
    eye3 = xp.broadcast_to(xp.eye(3, dtype=d.dtype), d.shape[:-1] + (3, 3))
    top = xp.concatenate([eye3, -skew(d, xp)], axis=-1)
    bottom = xp.concatenate([xp.zeros_like(eye3), eye3], axis=-1)
    return xp.concatenate([top, bottom], axis=-2)


def transfer(motion: Float[Array, "... 6"], d: Float[Array, "... 3"]) -> Float[Array, "... 6"]:
    """A small rigid motion ``(u, θ)`` moved to the point offset by ``d``: ``(u + θ × d, θ)``
    (units: ``u`` and ``θ × d`` alike, e.g. m and rad with ``d`` in m). NumPy in, NumPy out
    (float64 whatever JAX's mode); JAX arrays otherwise."""
    xp = np if isinstance(motion, np.ndarray) and isinstance(d, np.ndarray) else jnp
    theta = motion[..., 3:]
    u = motion[..., :3] + xp.cross(theta, d)  # broadcasts motion and d
    return xp.concatenate([u, xp.broadcast_to(theta, u.shape)], axis=-1)
