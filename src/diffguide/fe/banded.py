r"""Block-tridiagonal SPD matrices of a structured mesh: layout, assembly, Cholesky, solve.

On a tensor grid every element joins nodes of two neighbouring grid lines at most. Numbering the
nodes line by line across the *shorter* side (one block per grid line of the longer side, ``nper``
nodes = ``6 nper`` DOF per block), the stiffness matrix is block-tridiagonal:

.. math::

    K = \begin{bmatrix} D_0 & C_0^T & & \\ C_0 & D_1 & C_1^T & \\ & C_1 & D_2 & \ddots \\
        & & \ddots & \ddots \end{bmatrix},
    \qquad D_i = D_i^T,\; C_i = K_{i+1,i}.

Its Cholesky factor is block-bidiagonal (no fill outside the band):

.. math::

    L_0 L_0^T = D_0, \qquad W_i = C_{i-1} L_{i-1}^{-T}, \qquad
    L_i L_i^T = D_i - W_i W_i^T \quad (i \ge 1),

and ``K X = B`` is solved by ``y_i = L_i^{-1}(B_i - W_i y_{i-1})`` forwards, then
``x_i = L_i^{-T}(y_i - W_{i+1}^T x_{i+1})`` backwards. The factor is stored as the inverses
``L_i⁻¹`` (:func:`inverse_factor`, recursive, LAPACK only on blocks of ≤ :data:`LEAF` rows) and
``W_i``, so that every step is a matrix product: ``≈ 5 n_b s³`` flops for ``n_b`` blocks of size
``s`` (a dense Cholesky costs ``(n_b s)³ / 3``), memory ``2 n_b s²`` instead of ``(n_b s)²``. The
loops are ``lax.scan`` over the blocks. Accuracy: the inverses of the triangular factors carry
``cond(L) = cond(K)^½``; measured against the dense Cholesky, ≤ 1e-12 relative on the table
meshes.

:func:`spd_solve` differentiates the solve as a linear solve (``lax.custom_linear_solve``): a
tangent or cotangent costs one more pair of sweeps, ``dX = K⁻¹(dB − dK X)``, with ``dK`` from the
block matrix–vector product, never from the derivative of the factorisation.

Rigid patches. :func:`block_layout` takes the interface map of
:mod:`diffguide.fe.condense`: nodes tied to a patch leave the interior block (their rows and
columns of ``D`` are replaced by the identity and decoupled, which leaves the other unknowns
exact and gives zero there), and the element entries that touch them go to the interior–interface
coupling ``K_ib`` (per block, ``(n_b, s, m)``) and to ``K_bb`` (``(m, m)``). Element matrices are
scattered straight into these arrays; the dense global matrix is never formed.

Every function takes an array module ``xp``: :mod:`jax.numpy` (default; ``lax.scan`` loops,
traceable) or :mod:`numpy` (eager, Python loops over the blocks; for concrete inputs, where
tracing and compiling would cost seconds for a one-time computation).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.types import Array, Float
from ._xp import memo


class BlockLayout(eqx.Module):
    """Static map from node DOF to the block-tridiagonal interior and the interface DOF.

    Build with :func:`block_layout`. NumPy index arrays (traced when passed through
    ``filter_jit``) and static sizes.

    Attributes:
        node_block, node_pos: (n_nodes,) block of each node and its position inside the block.
        owner: (n_nodes,) interface patch of each node, -1 for an interior node.
        slave_dof: (n_b, s) bool, DOF tied to a patch (identity rows of ``D``).
        n_blocks, block_size: number of blocks ``n_b`` and their size ``s = 6 nper`` (DOF).
        m: number of interface DOF.
        offsets, n_entries: offsets of ``D``, ``C``, ``K_ib``, ``K_bb`` in the flat storage and
            its total size.
    """

    node_block: np.ndarray
    node_pos: np.ndarray
    owner: np.ndarray
    slave_dof: np.ndarray
    n_blocks: int = eqx.field(static=True)
    block_size: int = eqx.field(static=True)
    m: int = eqx.field(static=True)
    offsets: tuple[int, int, int, int] = eqx.field(static=True)
    n_entries: int = eqx.field(static=True)

    def check(self, conn: np.ndarray) -> None:
        """``ValueError`` unless every element of ``conn`` (n_el, k) spans at most two
        neighbouring blocks (true on a tensor grid)."""
        blk = self.node_block[np.asarray(conn)]
        if np.any(blk.max(axis=1) - blk.min(axis=1) > 1):
            raise ValueError("an element joins nodes more than one block apart: not a tensor grid")

    def _dofs(self, conn, xp=jnp):
        """Per element DOF (n_el, 6k): slave flag, block, in-block index, interface index."""
        node = xp.repeat(xp.asarray(conn), 6, axis=1)
        d = xp.tile(xp.arange(6), conn.shape[1])
        own = xp.asarray(self.owner)[node]
        blk = xp.asarray(self.node_block)[node]
        loc = 6 * xp.asarray(self.node_pos)[node] + d
        return own >= 0, blk, loc, 6 * xp.maximum(own, 0) + d

    def matrix_index(self, conn, xp=jnp) -> Array:
        """Flat target (n_el, 6k, 6k) of each element-matrix entry in ``[D, C, K_ib, K_bb]``
        (raveled, concatenated); ``n_entries`` (out of range: dropped) for the entries the
        symmetric storage does not keep (upper block ``C^T`` and interface–interior ``K_bi``).
        Integer arithmetic on the connectivity, traceable (it runs inside the compiled
        condensation)."""
        sl, blk, loc, bi = self._dofs(conn, xp)
        s, m = self.block_size, self.m
        oD, oC, oB, oBB = self.offsets
        r = lambda a: a[:, :, None]
        c = lambda a: a[:, None, :]
        ii = ~r(sl) & ~c(sl)
        idx = xp.where(ii & (r(blk) == c(blk)), oD + (r(blk) * s + r(loc)) * s + c(loc), -1)
        idx = xp.where(ii & (r(blk) == c(blk) + 1), oC + (c(blk) * s + r(loc)) * s + c(loc), idx)
        idx = xp.where(~r(sl) & c(sl), oB + (r(blk) * s + r(loc)) * m + c(bi), idx)
        idx = xp.where(r(sl) & c(sl), oBB + r(bi) * m + c(bi), idx)
        return xp.where(idx < 0, self.n_entries, idx)

    def vector_index(self, conn, xp=jnp) -> Array:
        """Flat target (n_el, 6k) of each element-vector entry in ``[f_i (n_b s), f_b (m)]``."""
        sl, blk, loc, bi = self._dofs(conn, xp)
        s = self.block_size
        return xp.where(sl, self.n_blocks * s + bi, blk * s + loc)

    def node_index(self):
        """(n_nodes,) row of each node in the interior solution reshaped (n_b · nper, 6, ·)."""
        return self.node_block * (self.block_size // 6) + self.node_pos


def block_layout(n_lines_x: int, n_lines_y: int, owner: np.ndarray, n_patches: int) -> BlockLayout:
    """The :class:`BlockLayout` of a tensor grid with rigid patches.

    Args:
        n_lines_x, n_lines_y: number of grid lines along X and Y; node ``i * n_lines_y + j`` sits
            on lines ``xs[i]``, ``ys[j]`` (:class:`~diffguide.fe.mesh.TableMesh` numbering).
            Blocks run across the shorter side (one block per grid line of the longer side).
        owner: (n_nodes,) interface patch of each node, -1 for an interior node.
        n_patches: number of patches (interface DOF ``m = 6 n_patches``).
    """
    i, j = np.divmod(np.arange(n_lines_x * n_lines_y), n_lines_y)
    if n_lines_x >= n_lines_y:  # blocks = grid lines x = const (columns across Y)
        node_block, node_pos, nper = i, j, n_lines_y
    else:  # blocks = grid lines y = const
        node_block, node_pos, nper = j, i, n_lines_x
    owner = np.asarray(owner)
    nb, s, m = int(max(n_lines_x, n_lines_y)), 6 * nper, 6 * int(n_patches)
    slave = np.zeros((nb, nper), bool)
    slave[node_block, node_pos] = owner >= 0
    sizes = (nb * s * s, (nb - 1) * s * s, nb * s * m, m * m)
    return BlockLayout(
        node_block=node_block,
        node_pos=node_pos,
        owner=owner,
        slave_dof=np.repeat(slave, 6, axis=1),
        n_blocks=nb,
        block_size=s,
        m=m,
        offsets=tuple(int(v) for v in np.cumsum((0,) + sizes[:-1])),
        n_entries=int(sum(sizes)),
    )


def scatter_add(n: int, idx, values, xp=jnp):
    """A vector of length ``n`` holding the sums of ``values`` at the flat indices ``idx``
    (equal shapes); indices ``>= n`` are dropped."""
    idx, values = xp.ravel(idx), xp.ravel(values)
    if xp is np:
        return np.bincount(idx, weights=values, minlength=n + 1)[:n]
    return jnp.zeros(n, values.dtype).at[idx].add(values, mode="drop")


def scan(f, init, xs, xp=jnp, reverse: bool = False):
    """``jax.lax.scan(f, init, xs, reverse=reverse)``, or the same loop in Python for NumPy
    (``xs`` a tuple of arrays, ``f`` returning ``(carry, y)`` with ``y`` an array or a tuple)."""
    if xp is not np:
        return jax.lax.scan(f, init, xs, reverse=reverse)
    n = xs[0].shape[0]
    ys = [None] * n
    carry = init
    for i in range(n - 1, -1, -1) if reverse else range(n):
        carry, ys[i] = f(carry, tuple(x[i] for x in xs))
    if n and isinstance(ys[0], tuple):
        return carry, tuple(np.stack(c) for c in zip(*ys))
    return carry, np.stack(ys)


def assemble_blocks(layout: BlockLayout, parts, xp=jnp):
    """Scatter element matrices into the block storage.

    Args:
        layout: the :class:`BlockLayout`.
        parts: iterable of ``(conn, Ke, fe)``: element connectivity (n_el, n), element matrices
            (n_el, 6n, 6n) and vectors (n_el, 6n) in the interface-reduced DOF (slave nodes'
            DOF already mapped to their patch's reference point).

    Returns:
        ``D`` (n_b, s, s) with identity rows/columns at slave DOF, ``C`` (n_b - 1, s, s),
        ``K_ib`` (n_b, s, m), ``K_bb`` (m, m), ``f_i`` (n_b, s), ``f_b`` (m,).
    """
    nb, s, m = layout.n_blocks, layout.block_size, layout.m

    def index():
        return xp.concatenate([xp.ravel(layout.matrix_index(conn, xp)) for conn, _, _ in parts])

    if xp is np:  # the same for every thickness of a family
        inputs = jax.tree_util.tree_leaves(layout) + [conn for conn, _, _ in parts]
        idx = memo("matrix_index", inputs + list(layout.offsets), index)
    else:
        idx = index()
    vals = xp.concatenate([xp.ravel(Ke) for _, Ke, _ in parts])
    buf = scatter_add(layout.n_entries, idx, vals, xp)
    idx = xp.concatenate([xp.ravel(layout.vector_index(conn, xp)) for conn, _, _ in parts])
    fbuf = scatter_add(nb * s + m, idx, xp.concatenate([xp.ravel(fe) for _, _, fe in parts]), xp)
    oD, oC, oB, oBB = layout.offsets
    D = buf[oD:oC].reshape(nb, s, s)
    D = D + xp.asarray(layout.slave_dof, D.dtype)[:, :, None] * xp.eye(s, dtype=D.dtype)
    C = buf[oC:oB].reshape(nb - 1, s, s)
    Kib = buf[oB:oBB].reshape(nb, s, m)
    Kbb = buf[oBB:].reshape(m, m)
    return D, C, Kib, Kbb, fbuf[: nb * s].reshape(nb, s), fbuf[nb * s :]


def matvec(D: Float[Array, "nb s s"], C: Float[Array, "nb1 s s"], X: Float[Array, "nb s k"]):
    """``K X`` for the block-tridiagonal ``K`` of ``D``, ``C`` (``X`` in blocks, (n_b, s, k))."""
    Y = jnp.einsum("nij,njk->nik", D, X)
    Y = Y.at[1:].add(jnp.einsum("nij,njk->nik", C, X[:-1]))
    return Y.at[:-1].add(jnp.einsum("nji,njk->nik", C, X[1:]))


#: Largest diagonal block handed to LAPACK (``potrf``, ``trsm``) in :func:`inverse_factor`.
#: Threaded OpenBLAS ``trsm`` above ~32 and ``potrf`` above ~100 ran two orders of magnitude
#: slower per call on a loaded machine (threads spinning for cores); below these sizes it runs
#: single-threaded, and the flops go to matrix products instead.
LEAF = 32


def _lower_inverse(L: np.ndarray) -> np.ndarray:
    """``L⁻¹`` of a lower-triangular NumPy matrix, as ``((Lᵀ)⁻¹)ᵀ``: ``numpy.linalg`` has no
    triangular solver, and its LU with row pivoting applied to ``L`` itself swaps rows (it lost
    1e-10 relative on the table's blocks); applied to the upper-triangular ``Lᵀ`` it finds
    nothing to pivot or eliminate (every column is already zero below the diagonal), so the
    solve is plain back substitution."""
    return np.linalg.solve(L.T, np.eye(L.shape[0], dtype=L.dtype)).T


def inverse_factor(A: Float[Array, "n n"], xp=jnp) -> Float[Array, "n n"]:
    r"""``L⁻¹`` for the Cholesky factor ``L L^T = A`` of an SPD matrix, recursively:

    .. math::

        A = \begin{bmatrix} A_{11} & A_{21}^T \\ A_{21} & A_{22} \end{bmatrix}, \quad
        L_{21} = A_{21} L_{11}^{-T}, \quad
        L^{-1} = \begin{bmatrix} L_{11}^{-1} & 0 \\
            -L_{22}^{-1} L_{21} L_{11}^{-1} & L_{22}^{-1} \end{bmatrix}

    with ``L_22`` the factor of ``A_22 - L_21 L_21^T``; blocks of at most :data:`LEAF` rows
    go to LAPACK (``potrf``, then ``trsm`` against the identity). ``n³`` flops, mostly in
    matrix products."""
    n = A.shape[0]
    if n <= LEAF or xp is np:  # NumPy: one block (no compilation to save; fewer Python calls)
        L = xp.linalg.cholesky(A)
        eye = xp.eye(n, dtype=A.dtype)
        if xp is np:
            return _lower_inverse(L)
        return jax.lax.linalg.triangular_solve(L, eye, left_side=True, lower=True)
    k = n // 2
    M11 = inverse_factor(A[:k, :k], xp)
    L21 = A[k:, :k] @ M11.T
    M22 = inverse_factor(A[k:, k:] - L21 @ L21.T, xp)
    M21 = -(M22 @ (L21 @ M11))
    return xp.block([[M11, xp.zeros((k, n - k), A.dtype)], [M21, M22]])


def cholesky(D: Float[Array, "nb s s"], C: Float[Array, "nb1 s s"], xp=jnp):
    """Block Cholesky factor of the SPD block-tridiagonal ``K`` (module docstring), kept as
    ``(M, W)``: ``M`` (n_b, s, s) the inverses ``L_i⁻¹`` of the lower-triangular diagonal
    blocks (:func:`inverse_factor`), ``W`` (n_b - 1, s, s) the sub-diagonal blocks
    ``W_i = C_{i-1} L_{i-1}^{-T}``."""
    M0 = inverse_factor(D[0], xp)

    def step(Mp, DC):
        Di, Ci = DC
        W = Ci @ Mp.T
        Mi = inverse_factor(Di - W @ W.T, xp)
        return Mi, (Mi, W)

    _, (Ms, Ws) = scan(step, M0, (D[1:], C), xp)
    return xp.concatenate([M0[None], Ms]), Ws


def cho_solve(factor, B: Float[Array, "nb s k"], xp=jnp) -> Float[Array, "nb s k"]:
    """``K⁻¹ B`` from the :func:`cholesky` factor: forward sweep ``y_i = L_i⁻¹ (B_i - W_i
    y_{i-1})``, backward sweep ``x_i = L_i^{-T} (y_i - W_{i+1}^T x_{i+1})`` (matrix products)."""
    M, W = factor
    y0 = M[0] @ B[0]

    def fwd(yp, MWB):
        Mi, Wi, Bi = MWB
        y = Mi @ (Bi - Wi @ yp)
        return y, y

    _, ys = scan(fwd, y0, (M[1:], W, B[1:]), xp)
    y = xp.concatenate([y0[None], ys])
    xl = M[-1].T @ y[-1]

    def bwd(xn, MWy):
        Mi, Wn, yi = MWy
        x = Mi.T @ (yi - Wn.T @ xn)
        return x, x

    _, xs = scan(bwd, xl, (M[:-1], W, y[:-1]), xp, reverse=True)
    return xp.concatenate([xs, xl[None]])


def spd_solve(
    D: Float[Array, "nb s s"], C: Float[Array, "nb1 s s"], B: Float[Array, "nb s k"], xp=jnp
):
    """``K⁻¹ B`` for SPD block-tridiagonal ``K``, differentiated as a linear solve (module
    docstring): derivatives w.r.t. ``D``, ``C`` and ``B`` cost one more pair of sweeps."""
    if xp is np:
        return cho_solve(cholesky(D, C, np), B, np)
    factor = cholesky(jax.lax.stop_gradient(D), jax.lax.stop_gradient(C))
    return jax.lax.custom_linear_solve(
        lambda x: matvec(D, C, x),
        B,
        solve=lambda _, b: cho_solve(factor, b),
        symmetric=True,
    )
