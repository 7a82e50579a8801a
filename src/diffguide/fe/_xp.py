"""Small array helpers written once for an array module ``xp`` (:mod:`jax.numpy` or
:mod:`numpy`): the element and condensation formulas of :mod:`diffguide.fe` use them so that
the same code runs traced (JAX) or eagerly (NumPy)."""

import hashlib

import jax.numpy as jnp
import numpy as np


def place(block, idx, n: int, xp=jnp):
    """An (..., n, n) matrix holding ``block`` (..., k, k) at rows and columns ``idx``."""
    P = np.zeros((len(idx), n))
    P[np.arange(len(idx)), list(idx)] = 1.0
    return xp.asarray(P.T) @ block @ P


def block_diag(blocks, xp=jnp):
    """(..., n, b, b) -> (..., n b, n b): the block-diagonal matrix of the ``n`` blocks."""
    n, b = blocks.shape[-3], blocks.shape[-1]
    T = xp.einsum("ij,...iab->...iajb", np.eye(n), blocks)
    return xp.reshape(T, T.shape[:-4] + (n * b, n * b))


def congruence(K, blocks, xp=jnp):
    """``Tᵀ K T`` with ``T`` the block-diagonal matrix of ``blocks`` (..., n, b, b) and ``K``
    (..., n b, n b) (batched matrix products)."""
    T = block_diag(blocks, xp)
    return xp.swapaxes(T, -1, -2) @ K @ T


_MEMO: dict = {}


def memo(name: str, inputs, compute, size: int = 2):
    """``compute()`` remembered under ``name`` and the bytes of ``inputs`` (NumPy arrays and
    numbers), the ``size`` latest per name: for the NumPy path's thickness-independent parts
    (element matrices ``K₁``, ``K₃`` of a mesh, scatter indices of a layout), which a family of
    condensations at several thicknesses shares. The results must not be modified in place."""
    h = hashlib.sha256(name.encode())
    for a in inputs:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    key = (name, h.digest())
    if key in _MEMO:
        return _MEMO[key]
    mine = [k for k in _MEMO if k[0] == name]
    for k in mine[: max(0, len(mine) - size + 1)]:
        del _MEMO[k]
    _MEMO[key] = out = compute()
    return out
