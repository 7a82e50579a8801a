"""Element matrices of a table mesh (batched), scattering into global arrays, loads, supports.

"Assembly" here is the FE sense: element matrices scattered (``.at[].add``) into a dense global
matrix. Global DOF order: node by node, ``6 * node + k`` with ``k`` in ``(ux, uy, uz, rx, ry, rz)``
(m, rad); forces in N and moments in N·m in the same order. Nothing here is a Python loop over
elements: the element routines take all elements of a kind in one batched call, and the whole
assembly is ``jax.jit``-ed (:func:`element_arrays_xp` also evaluates them eagerly in NumPy).
Differentiable w.r.t. thickness, E, ν, ρ, rib sizes and node coordinates.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.types import Array, Float, ScalarLike
from ._xp import memo
from .beam import beam_load, beam_stiffness, bonded_rib_torsion, rect_section
from .materials import CAST_IRON, Material
from .mesh import TableMesh
from .shell import shell_load, shell_matrices, shell_stiffness

#: DOF names in node order.
DOF_NAMES = ("ux", "uy", "uz", "rx", "ry", "rz")


class PlateSection(eqx.Module):
    """Section of the table plate.

    Args:
        thickness: plate thickness t in m, > 0 (mid-surface at z = 0, top at +t/2).
        material: plate material (and ribs' unless a rib sets its own); cast iron by default.
        kappa: transverse shear correction factor (5/6).
        drill: drilling penalty factor α (penalty stiffness α G t per unit area), small.
    """

    thickness: ScalarLike
    material: Material = CAST_IRON
    kappa: float = eqx.field(static=True, default=5.0 / 6.0)
    drill: float = eqx.field(static=True, default=1e-3)

    def __check_init__(self):
        t = self.thickness
        if isinstance(t, (int, float)) and not t > 0:
            raise ValueError(f"thickness must be > 0 m, got {t}")
        if not 0 < self.kappa <= 1:
            raise ValueError(f"kappa must be in (0, 1], got {self.kappa}")
        if not 0 < self.drill <= 1:
            raise ValueError(f"drill must be in (0, 1], got {self.drill}")


class ElementArrays(eqx.Module):
    """Element matrices and load vectors of one element family, with their connectivity."""

    conn: Array  # (n_el, n_nodes_per_el) node indices
    K: Array  # (n_el, 6 n, 6 n)
    f: Array  # (n_el, 6 n)


def _rib_arrays(mesh: TableMesh, plate: PlateSection, xp=jnp):
    """Per-rib E, G, rho, width, depth (stacked)."""
    mats = [r.material if r.material is not None else plate.material for r in mesh.ribs]
    E = xp.stack([xp.asarray(m.E, dtype=float) for m in mats])
    nu = xp.stack([xp.asarray(m.nu, dtype=float) for m in mats])
    rho = xp.stack([xp.asarray(m.rho, dtype=float) for m in mats])
    w = xp.stack([xp.asarray(r.width, dtype=float) for r in mesh.ribs])
    d = xp.stack([xp.asarray(r.depth, dtype=float) for r in mesh.ribs])
    return E, E / (2 * (1 + nu)), rho, w, d


def as_arrays(tree):
    """Turn the Python-number leaves of a pytree into float arrays (so that ``filter_jit``
    traces them instead of recompiling for each new value)."""

    def conv(x):
        if isinstance(x, (int, float)) and not isinstance(x, bool):
            return jnp.asarray(x, dtype=float)
        return x

    return jax.tree_util.tree_map(conv, tree)


def element_arrays(
    mesh: TableMesh,
    plate: PlateSection,
    nodes: Float[Array, "n 3"] | None = None,
    gravity: ScalarLike = 0.0,
    surface_load: Float[Array, "3"] | None = None,
) -> tuple["ElementArrays", ...]:
    """Element stiffness matrices and load vectors of all shells and rib beams (global frame).

    Args:
        mesh: the table mesh (topology).
        plate: plate section.
        nodes: node coordinates (m) replacing ``mesh.nodes`` (e.g. traced, to differentiate).
        gravity: g in m/s², acting along -Z on the plate (ρ t g per m²) and the ribs (ρ A g per m).
        surface_load: uniform load on the plate in Pa, global (X, Y, Z) components; e.g.
            ``(0, 0, -q)`` for a downward pressure q.

    Returns:
        A tuple of :class:`ElementArrays`: shells, then beams (if the mesh has ribs).
    """
    mesh, plate, gravity = as_arrays((mesh, plate, gravity))
    sl = jnp.zeros(3) if surface_load is None else jnp.asarray(surface_load, dtype=float)
    return _element_arrays(mesh, plate, nodes, gravity, sl)


def element_arrays_xp(mesh, plate, nodes, gravity, surface_load, xp=jnp):
    """:func:`element_arrays` for the array module ``xp`` (:mod:`jax.numpy`: traceable;
    :mod:`numpy`: eager, for concrete inputs), all elements of a kind in one batched call."""
    xyz = xp.asarray(mesh.nodes if nodes is None else nodes, dtype=float)
    t = xp.asarray(plate.thickness, dtype=float)
    mat = plate.material
    quads = xp.asarray(mesh.quads)
    exyz = xyz[quads]
    if xp is np:  # K(t) = t K₁ + t³ K₃: K₁, K₃ shared by the thicknesses of a family
        args = (exyz, mat.E, mat.nu, plate.kappa, plate.drill)
        K1, K3 = memo("shell", args, lambda: shell_matrices(*args, xp=np), size=1)
        Ks = t * K1 + t**3 * K3
    else:
        Ks = shell_stiffness(exyz, t, mat.E, mat.nu, plate.kappa, plate.drill, xp=xp)
    zero = xp.zeros((), dtype=float)
    traction = xp.stack([zero, zero, -gravity * mat.rho * t]) + surface_load
    fs = shell_load(exyz, traction, xp=xp)
    out = [ElementArrays(conn=quads, K=Ks, f=fs)]
    if mesh.beams.shape[0] > 0:
        E, G, rho, w, d = _rib_arrays(mesh, plate, xp)
        k = xp.asarray(mesh.beam_rib)
        E, G, rho, w, d = E[k], G[k], rho[k], w[k], d[k]
        sec = rect_section(w, d, xp=xp)
        J = bonded_rib_torsion(w, d, t, xp=xp)  # the rib's share of the T-section's torsion
        zeros = xp.zeros_like(d)
        off = xp.stack([zeros, zeros, -(0.5 * t + 0.5 * d)], axis=1)
        beams = xp.asarray(mesh.beams)
        bxyz = xyz[beams]
        Kb = beam_stiffness(
            bxyz, E, G, sec["A"], sec["Iy"], sec["Iz"], J, 5.0 / 6.0, off, xp=xp
        )
        q = xp.stack([zeros, zeros, -gravity * rho * sec["A"]], axis=1)
        fb = beam_load(bxyz, q, off, xp=xp)
        out.append(ElementArrays(conn=beams, K=Kb, f=fb))
    return tuple(out)


@eqx.filter_jit
def _element_arrays(mesh, plate, nodes, gravity, surface_load):
    return element_arrays_xp(mesh, plate, nodes, gravity, surface_load, jnp)


def element_dofs(conn: Array) -> Array:
    """Global DOF indices (n_el, 6 n) of elements with node connectivity ``conn`` (n_el, n)."""
    conn = jnp.asarray(conn)
    return (6 * conn[:, :, None] + jnp.arange(6)[None, None, :]).reshape(conn.shape[0], -1)


def scatter_matrix(n_dof: int, dofs: Array, Ke: Array, out: Array | None = None) -> Array:
    """Add element matrices ``Ke`` (n_el, k, k) at ``dofs`` (n_el, k) into a dense matrix."""
    out = jnp.zeros((n_dof, n_dof), dtype=Ke.dtype) if out is None else out
    return out.at[dofs[:, :, None], dofs[:, None, :]].add(Ke)


def scatter_vector(n_dof: int, dofs: Array, fe: Array, out: Array | None = None) -> Array:
    """Add element vectors ``fe`` (n_el, k) at ``dofs`` (n_el, k) into a vector."""
    out = jnp.zeros(n_dof, dtype=fe.dtype) if out is None else out
    return out.at[dofs].add(fe)


def assemble(
    mesh: TableMesh,
    plate: PlateSection,
    nodes: Float[Array, "n 3"] | None = None,
    gravity: ScalarLike = 0.0,
    surface_load: Float[Array, "3"] | None = None,
) -> tuple[Float[Array, "n_dof n_dof"], Float[Array, " n_dof"]]:
    """Global stiffness K (dense, 6 n_nodes square) and load vector f of the free table.

    Arguments as :func:`element_arrays`. DOF ``6 * node + k``, k in (ux, uy, uz, rx, ry, rz).
    """
    mesh, plate, gravity = as_arrays((mesh, plate, gravity))
    sl = jnp.zeros(3) if surface_load is None else jnp.asarray(surface_load, dtype=float)
    return _assemble(mesh, plate, nodes, gravity, sl)


@eqx.filter_jit
def _assemble(mesh, plate, nodes, gravity, surface_load):
    n = mesh.n_dof
    K = f = None
    for ea in _element_arrays(mesh, plate, nodes, gravity, surface_load):
        dofs = element_dofs(ea.conn)
        K = scatter_matrix(n, dofs, ea.K, K)
        f = scatter_vector(n, dofs, ea.f, f)
    return K, f


def point_load(
    mesh: TableMesh,
    x: float,
    y: float,
    force: tuple[float, float, float] = (0.0, 0.0, 0.0),
    moment: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> np.ndarray:
    """Global load vector (N, N·m) of a force and moment applied at the node at (x, y) (m)."""
    f = np.zeros(mesh.n_dof)
    k = mesh.node_at(x, y)
    f[6 * k : 6 * k + 6] = np.concatenate([force, moment])
    return f


def solve_fixed(
    K: Float[Array, "n n"],
    f: Float[Array, " n"],
    fixed: np.ndarray,
    values: Float[Array, " n_fixed"] | None = None,
) -> Float[Array, " n"]:
    """Solve ``K u = f`` with the DOF ``fixed`` (NumPy indices or boolean mask) prescribed.

    ``u[fixed] = values`` (default 0; in the order of ``fixed``); the others from
    ``K_ff u_f = f_f - K_fp u_p`` (dense
    Cholesky). Returns the full displacement vector.
    """
    fixed = np.asarray(fixed)
    n = K.shape[0]
    pi = np.flatnonzero(fixed) if fixed.dtype == bool else fixed.astype(np.int64).ravel()
    mask = np.zeros(n, bool)
    mask[pi] = True
    if mask.sum() != len(pi):
        raise ValueError("fixed must not repeat a DOF")
    fi = np.flatnonzero(~mask)
    up = jnp.zeros(len(pi), dtype=K.dtype) if values is None else jnp.asarray(values, K.dtype)
    rhs = f[fi] - K[np.ix_(fi, pi)] @ up
    cf = jax.scipy.linalg.cho_factor(K[np.ix_(fi, fi)])
    uf = jax.scipy.linalg.cho_solve(cf, rhs)
    return jnp.zeros(n, dtype=K.dtype).at[fi].set(uf).at[pi].set(up)
