"""Static condensation of the table onto rigid patches (carriages, screw nut) and control points.

Interfaces. Each :class:`RigidPatch` has a reference point ``p_ref`` (for a carriage: the centre
of its top face, on the plate underside ``z = -t/2``) and a rectangular footprint; every plate
node in the footprint is a slave of the reference point (master–slave, exact rigid tie):

    u_node = u_ref + θ_ref × (p_node - p_ref),     θ_node = θ_ref.

The interface DOF ``u_b`` are the 6 DOF ``(ux, uy, uz, rx, ry, rz)`` of each patch reference
point, patches in the caller's order: ``u_b[6 p + k]`` (m, rad); m = 6 n_patches.

With the remaining (interior) node DOF ``u_i`` and the table's own loads (gravity, surface
loads), the static equations ``[[K_ii, K_ib], [K_bi, K_bb]] [u_i, u_b] = [f_i, f_b + F_b]``
condense to

    K u_b = f + F_b,   K = K_bb - K_bi K_ii⁻¹ K_ib,   f = f_b - K_bi K_ii⁻¹ f_i,

where ``F_b`` (N, N·m) is the wrench the carriages / the nut apply *to the table* at each
reference point (moments about ``p_ref``). ``K`` is the free-floating table's: symmetric, positive
semi-definite with the 6 rigid-body modes in its null space. The interior follows as
``u_i = K_ii⁻¹ (f_i - K_ib u_b)``.

Control points P = (x, y) on the top surface: the motion of the material point at the top
surface, ``u_P = Σ N_k (u_k + θ_k × o)`` with ``o = (t/2) n`` (n the element normal, +Z), and the
rotation ``θ_P = Σ N_k θ_k`` (bilinear shell shape functions ``N_k`` of the quad containing P;
exact nodal values when P is on a node). ``[u_P, θ_P] = R u_b + r0`` with ``r0`` the part due to
the table's own loads with the interfaces held at zero.
"""

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.caches import active_caches
from .._core.compat import outside_traces
from .._core.precision import require_x64
from .._core.rigid import rigid_transfer
from .._core.types import Array, Float, ScalarLike
from . import banded
from . import cache as table_cache
from ._xp import congruence
from .assemble import PlateSection, as_arrays, element_arrays_xp
from .mesh import TableMesh
from .shell import shell_frame, shell_natural_coords, shell_shape


class RigidPatch(eqx.Module):
    """A rigid interface: a footprint of plate nodes tied to one reference point.

    Args:
        x, y: reference point and footprint centre (m).
        half_x, half_y: footprint half-lengths along X and Y (m), > 0.
        z: reference point height (m); ``None`` (default) = the plate underside ``-t/2``
            (follows the thickness when differentiating).
        name: label.
    """

    x: float = eqx.field(static=True)
    y: float = eqx.field(static=True)
    half_x: float = eqx.field(static=True)
    half_y: float = eqx.field(static=True)
    z: float | None = eqx.field(static=True, default=None)
    name: str = eqx.field(static=True, default="")

    def __check_init__(self):
        for k in ("half_x", "half_y"):
            if not getattr(self, k) > 0:
                raise ValueError(f"RigidPatch.{k} must be > 0 m, got {getattr(self, k)}")

    @property
    def box(self) -> tuple[float, float, float, float]:
        x, y, hx, hy = self.x, self.y, self.half_x, self.half_y
        return (x - hx, x + hx, y - hy, y + hy)


def patch_lines(patches: Sequence[RigidPatch]) -> tuple[list[float], list[float]]:
    """Grid lines (x values, y values; m) at the footprint edges and centres of ``patches``."""
    lx, ly = [], []
    for p in patches:
        x0, x1, y0, y1 = p.box
        lx += [x0, p.x, x1]
        ly += [y0, p.y, y1]
    return lx, ly


class CondensedTable(eqx.Module):
    """The table condensed onto its interfaces (see the module docstring for the equations).

    Attributes:
        K: (m, m) condensed stiffness (N/m, N/rad, N·m/rad), free-floating (6 rigid modes).
        f: (m,) condensed table loads (N, N·m) at the interface DOF.
        R: (6 n_points, m) control-point motion per interface DOF; rows ``6 j + k``, k in
            (ux, uy, uz, rx, ry, rz) of point j.
        r0: (6 n_points,) control-point motion due to the table loads with ``u_b = 0``.
        node_modes: (n_nodes, 6, m) node DOF per interface DOF (mid-surface nodes).
        node_u0: (n_nodes, 6) node DOF due to the table loads with ``u_b = 0``.
        ref_points: (n_patches, 3) reference points (m).
        nodes: (n_nodes, 3) mesh node coordinates (m), mid-surface, in ``node_modes`` order.
    """

    K: Float[Array, "m m"]
    f: Float[Array, " m"]
    R: Float[Array, "np6 m"]
    r0: Float[Array, " np6"]
    node_modes: Float[Array, "n 6 m"]
    node_u0: Float[Array, "n 6"]
    ref_points: Float[Array, "p 3"]
    nodes: Float[Array, "n 3"]

    def interface_loads(self, u_b: Float[Array, " m"]) -> Float[Array, " m"]:
        """Wrench applied to the table at the reference points, ``F_b = K u_b - f`` (N, N·m)."""
        return self.K @ u_b - self.f

    def point_motion(self, u_b: Float[Array, " m"]) -> Float[Array, "n_points 6"]:
        """Control-point motion ``R u_b + r0`` as (n_points, 6): m and rad."""
        return (self.R @ u_b + self.r0).reshape(-1, 6)

    def node_displacements(self, u_b: Float[Array, " m"]) -> Float[Array, "n 6"]:
        """Node DOF (n_nodes, 6) for interface DOF ``u_b``: m and rad."""
        return self.node_modes @ u_b + self.node_u0


def _topology(mesh: TableMesh, patches: Sequence[RigidPatch], points: Sequence):
    """Static (NumPy) maps: slave patch of each node (-1: interior), node blocks, point quads."""
    if len(patches) == 0:
        raise ValueError("patches must hold at least one RigidPatch (the table would be free)")
    xs, ys = mesh.xs, mesh.ys
    tol = 1e-9
    owner = np.full(mesh.n_nodes, -1)
    for k, p in enumerate(patches):
        x0, x1, y0, y1 = p.box
        if x0 < xs[0] - tol or x1 > xs[-1] + tol or y0 < ys[0] - tol or y1 > ys[-1] + tol:
            raise ValueError(
                f"patch {k} ({p.name or 'unnamed'}) footprint [{x0}, {x1}] × [{y0}, {y1}] m is "
                f"outside the table [{xs[0]}, {xs[-1]}] × [{ys[0]}, {ys[-1]}] m"
            )
        ids = mesh.nodes_in_box(x0, x1, y0, y1)
        if len(ids) == 0:
            raise ValueError(
                f"patch {k} ({p.name or 'unnamed'}) footprint contains no node; add grid lines "
                "at its edges (see patch_lines)"
            )
        if np.any(owner[ids] >= 0):
            raise ValueError(f"patch {k} ({p.name or 'unnamed'}) overlaps another patch")
        owner[ids] = k
    interior = np.flatnonzero(owner < 0)
    n_free = len(interior)
    block = np.empty(mesh.n_nodes, dtype=np.int64)
    block[interior] = np.arange(n_free)
    block[owner >= 0] = n_free + owner[owner >= 0]
    quads = np.array([mesh.locate(float(x), float(y)) for x, y in points], dtype=np.int64)
    return owner, block, n_free, quads


def _spd_solve(A, B, xp=jnp):
    """``A⁻¹ B`` for SPD ``A`` by Cholesky, differentiated as a linear solve: a tangent costs
    one more pair of triangular solves, ``dX = A⁻¹ (dB − dA X)``, not the derivative of the
    factorisation (which costs O(n³) per tangent). NumPy: the Cholesky factor ``L``, then
    ``L⁻ᵀ (L⁻¹ B)`` (:func:`~diffguide.fe.banded._lower_inverse`: ``numpy.linalg`` has no
    triangular solver, and its LU pivots rows of a lower-triangular matrix but not of an upper
    one)."""
    if xp is np:
        L = np.linalg.cholesky(A)
        return np.linalg.solve(L.T, banded._lower_inverse(L) @ B)
    c, lower = jax.scipy.linalg.cho_factor(jax.lax.stop_gradient(A))
    return jax.lax.custom_linear_solve(
        lambda x: A @ x,
        B,
        solve=lambda _, b: jax.scipy.linalg.cho_solve((c, lower), b),
        symmetric=True,
    )


def condense(
    mesh: TableMesh,
    plate: PlateSection,
    patches: Sequence[RigidPatch],
    points: Sequence[tuple[float, float]] = (),
    *,
    nodes: Float[Array, "n 3"] | None = None,
    ref_xy: Float[Array, "p 2"] | None = None,
    gravity: ScalarLike = 9.81,
    surface_load: Float[Array, "3"] | None = None,
    method: str = "banded",
    backend: str = "auto",
) -> CondensedTable:
    """Condense the table onto rigid patches and recover control points.

    Args:
        mesh: table mesh; footprints and points must lie on the table.
        plate: plate section (thickness, material).
        patches: the rigid interfaces, in the order of ``u_b``.
        points: control points (x, y) in m on the top surface (z = +t/2).
        nodes: node coordinates (m) replacing ``mesh.nodes`` (e.g. traced); the footprint
            membership and point elements are decided on ``mesh.nodes``.
        ref_xy: reference points (x, y) (m) replacing the patches' static ``x``, ``y`` (e.g.
            traced, to move the patches together with ``nodes``); shape (n_patches, 2). The
            heights still follow ``RigidPatch.z`` / the plate underside.
        gravity: g (m/s²) along -Z; 0 for no self-weight.
        surface_load: uniform load on the plate (Pa, global components).
        method: ``"banded"`` (default): element matrices scattered straight into the
            block-tridiagonal interior block (one block per grid line across the shorter side),
            block Cholesky by ``lax.scan`` (:mod:`diffguide.fe.banded`); ``O(n_b s³)`` time and
            ``O(n_b s²)`` memory for ``n_b`` blocks of ``s`` DOF. ``"dense"``: the reduced
            matrix assembled dense and a dense Cholesky, ``O(n³)`` (a reference).
        backend: ``"auto"`` (default): ``"numpy"`` when no input is traced, else ``"jax"``.
            ``"numpy"``: the same formulas evaluated eagerly with NumPy (element matrices of
            all elements in one batched call, the block solve in a Python loop over the
            blocks): no tracing and no compilation, ~0.05 s for the 20 × 10 table where the
            first compiled call costs seconds; not differentiable. ``"jax"``: the compiled,
            differentiable program (a traced input needs it).

    Returns:
        :class:`CondensedTable`. Differentiable w.r.t. thickness, material, rib sizes, ``nodes``,
        ``ref_xy``.
    """
    require_x64("diffguide.fe.condense")
    if backend not in ("auto", "numpy", "jax"):
        raise ValueError(f"backend must be 'auto', 'numpy' or 'jax', got {backend!r}")
    traced = any(
        isinstance(leaf, jax.core.Tracer)
        for leaf in jax.tree_util.tree_leaves((mesh, plate, nodes, ref_xy, gravity, surface_load))
    )
    if backend == "numpy" and traced:
        raise ValueError("backend='numpy' needs concrete inputs (an input is traced)")
    eager = backend == "numpy" or (backend == "auto" and not traced)
    owner, block, n_free, quads = _topology(mesh, patches, points)
    key = None
    caches = active_caches()
    if caches is not None and caches.tables is not None:  # a disk cache of tables (.cache)
        key = table_cache.table_key(
            "condense",
            mesh,
            plate,
            tuple(patches),
            np.asarray(points, dtype=float),
            nodes,
            ref_xy,
            gravity,
            surface_load,
            method,
        )
        cached = table_cache.load(caches, key)
        if cached is not None:
            return CondensedTable(**cached)
    if eager:  # concrete inputs: NumPy arrays throughout
        xp = np
        mesh, plate, nodes, ref_xy, gravity = jax.tree_util.tree_map(
            lambda x: (
                np.asarray(x, dtype=float)
                if isinstance(x, (int, float, jax.Array)) and not isinstance(x, bool)
                else x
            ),
            (mesh, plate, nodes, ref_xy, gravity),
        )
    else:
        xp = jnp
        mesh, plate, gravity = as_arrays((mesh, plate, gravity))
    sl = xp.zeros(3) if surface_load is None else xp.asarray(surface_load, dtype=float)
    table = _condense_layout(mesh, plate, owner, block, n_free, quads, patches, points, nodes,
                             ref_xy, gravity, sl, method, xp)
    if eager:
        table = _finish_numpy(table)
    table_cache.store(caches, key, table)
    return table


def _finish_numpy(table: "CondensedTable") -> "CondensedTable":
    """The NumPy result as JAX arrays (what the compiled path returns)."""
    return jax.tree_util.tree_map(jnp.asarray, table)


def _condense_layout(
    mesh,
    plate,
    owner,
    block,
    n_free,
    quads,
    patches,
    points,
    nodes,
    ref_xy,
    gravity,
    sl,
    method,
    xp,
):
    pxyz = np.array([[p.x, p.y, np.nan if p.z is None else p.z] for p in patches])
    if ref_xy is not None and np.shape(ref_xy) != (len(patches), 2):
        raise ValueError(
            f"ref_xy must have shape (n_patches, 2) = ({len(patches)}, 2), got {np.shape(ref_xy)}"
        )
    pts = np.array(points, dtype=float).reshape(-1, 2)
    nat = _grid_natural_coords(mesh, quads, pts) if nodes is None else None
    if method == "dense":
        layout = None
    elif method == "banded":
        layout = banded.block_layout(len(mesh.xs), len(mesh.ys), owner, len(patches))
        for conn in (mesh.quads, mesh.beams):
            layout.check(conn)
    else:
        raise ValueError(f"method must be 'banded' or 'dense', got {method!r}")
    args = (
        mesh,
        plate,
        nodes,
        ref_xy,
        gravity,
        sl,
        owner,
        block,
        n_free,
        quads,
        pxyz,
        pts,
        nat,
        layout,
    )
    return _condense_impl(np, *args) if xp is np else _condense(*args)


def _grid_natural_coords(mesh: TableMesh, quads: np.ndarray, pts: np.ndarray):
    """Natural coordinates (ξ, η) (n_pts, 2) of the points in their quads, in closed form on the
    mesh's own flat, axis-aligned grid (``ξ = 2 (x - x_i) / (x_{i+1} - x_i) - 1``; the same as
    :func:`~diffguide.fe.shell.shell_natural_coords`, without a Newton solve to compile), or
    ``None`` when ``mesh.nodes`` is not that grid."""
    xs, ys = np.asarray(mesh.xs), np.asarray(mesh.ys)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    grid = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    if np.shape(mesh.nodes) != grid.shape or not np.array_equal(np.asarray(mesh.nodes), grid):
        return None
    i, j = np.divmod(quads, len(ys) - 1)
    return np.stack(
        [
            2.0 * (pts[:, 0] - xs[i]) / (xs[i + 1] - xs[i]) - 1.0,
            2.0 * (pts[:, 1] - ys[j]) / (ys[j + 1] - ys[j]) - 1.0,
        ],
        axis=1,
    )


#: XLA options of the condensation when it is compiled on its own (not inside another traced
#: function): a one-time computation per table, whose compilation at the default optimisation
#: level costs about twice the compile time for the little it gains at run time (a few
#: hundredths of a second per condensation).
CONDENSE_COMPILER_OPTIONS = {"xla_backend_optimization_level": 0}


def _condense(*args):
    # a ``jit`` with compiler options must be the outermost one
    impl = _condense_top if outside_traces() else _condense_nested
    return impl(*args)


def _condense_impl(
    xp,
    mesh,
    plate,
    nodes,
    ref_xy,
    gravity,
    sl,
    owner,
    block,
    n_free,
    quads,
    pxyz,
    pts,
    nat,
    layout=None,
):
    xyz = xp.asarray(mesh.nodes if nodes is None else nodes, dtype=float)
    t = xp.asarray(plate.thickness, dtype=float)
    n_patch = pxyz.shape[0]
    m = 6 * n_patch
    n_i = 6 * n_free
    n_r = n_i + m
    ref = xp.where(xp.isnan(pxyz), -0.5 * t, pxyz)
    if ref_xy is not None:
        ref = xp.concatenate([xp.asarray(ref_xy, dtype=float), ref[:, 2:]], axis=1)
    slave = owner >= 0
    d = xyz - ref[xp.where(slave, owner, 0)]
    A = xp.where(slave[:, None, None], rigid_transfer(d, xp), xp.eye(6))  # node DOF = A @ block DOF

    parts = []
    for ea in element_arrays_xp(mesh, plate, nodes, gravity, sl, xp):
        k = ea.conn.shape[1]
        Ae = A[ea.conn]  # (n_el, k, 6, 6)
        if xp is np:  # only the elements touching a patch (A = I elsewhere)
            tied_el = np.flatnonzero(slave[ea.conn].any(axis=1))
            Ke = ea.K.copy()
            Ke[tied_el] = congruence(ea.K[tied_el], Ae[tied_el], np)
        else:
            Ke = congruence(ea.K, Ae, xp)
        fe = xp.einsum("eiac,eia->eic", Ae, ea.f.reshape(-1, k, 6)).reshape(-1, 6 * k)
        parts.append((ea.conn, Ke, fe))

    if layout is None:  # dense: interior nodes in node order, then the interface DOF
        idx, vals, fidx, fvals = [], [], [], []
        for conn, Ke, fe in parts:
            dofs = (6 * block[conn][:, :, None] + xp.arange(6)).reshape(conn.shape[0], -1)
            idx.append(xp.ravel(dofs[:, :, None] * n_r + dofs[:, None, :]))
            vals.append(xp.ravel(Ke))
            fidx.append(xp.ravel(dofs))
            fvals.append(xp.ravel(fe))
        K = banded.scatter_add(n_r * n_r, xp.concatenate(idx), xp.concatenate(vals), xp)
        K = K.reshape(n_r, n_r)
        f = banded.scatter_add(n_r, xp.concatenate(fidx), xp.concatenate(fvals), xp)
        Kii, Kib, Kbb = K[:n_i, :n_i], K[:n_i, n_i:], K[n_i:, n_i:]
        X = _spd_solve(Kii, xp.concatenate([Kib, f[:n_i, None]], axis=1), xp)
        Kc = Kbb - Kib.T @ X[:, :m]
        fc = f[n_i:] - Kib.T @ X[:, m]
        Xn = X.reshape(-1, 6, m + 1)[xp.minimum(block, n_free - 1)]  # slave rows: unused
    else:  # block-tridiagonal interior (all nodes, slave DOF decoupled), see .banded
        D, C, Kib, Kbb, fi, fb = banded.assemble_blocks(layout, parts, xp)
        X = banded.spd_solve(D, C, xp.concatenate([Kib, fi[:, :, None]], axis=2), xp)
        Kc = Kbb - xp.einsum("nim,nik->mk", Kib, X[:, :, :m])
        fc = fb - xp.einsum("nim,ni->m", Kib, X[:, :, m])
        Xn = X.reshape(-1, 6, m + 1)[layout.node_index()]
    Kc = 0.5 * (Kc + Kc.T)

    # node DOF per interface DOF: interior nodes -X, slave nodes the rigid map of their patch
    onehot = xp.asarray(owner[:, None] == np.arange(n_patch), dtype=A.dtype)  # (n, p)
    tied = xp.einsum("np,nab->napb", onehot, A).reshape(-1, 6, m)
    node_modes = xp.where(slave[:, None, None], tied, -Xn[:, :, :m])
    node_u0 = xp.where(slave[:, None], 0.0, Xn[:, :, m])

    # control points: bilinear interpolation in the containing quad + offset to the top surface
    qn = xp.asarray(mesh.quads)[quads]  # (n_pts, 4)
    if pts.shape[0] > 0:
        exyz = xyz[qn]  # (n_pts, 4, 3)
        s = shell_natural_coords(exyz, xp.asarray(pts), xp) if nat is None else xp.asarray(nat)
        N = shell_shape(s[:, 0], s[:, 1], xp)  # (n_pts, 4)
        R, _ = shell_frame(exyz, xp)
        W = N[:, :, None, None] * rigid_transfer(0.5 * t * R[:, 2], xp)[:, None]  # (n_pts, 4, 6, 6)
        Rm = xp.einsum("pkab,pkbm->pam", W, node_modes[qn]).reshape(-1, m)
        r0 = xp.einsum("pkab,pkb->pa", W, node_u0[qn]).reshape(-1)
    else:
        Rm, r0 = xp.zeros((0, m)), xp.zeros(0)
    return CondensedTable(
        K=Kc, f=fc, R=Rm, r0=r0, node_modes=node_modes, node_u0=node_u0, ref_points=ref, nodes=xyz
    )


def _condense_jax(*args):
    return _condense_impl(jnp, *args)


_condense_top = eqx.filter_jit(_condense_jax, compiler_options=CONDENSE_COMPILER_OPTIONS)
_condense_nested = eqx.filter_jit(_condense_jax)
