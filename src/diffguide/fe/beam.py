"""2-node 3-D Timoshenko beam with an optional rigid offset of its axis from its nodes.

Pure functions of one element's node coordinates and section; ``jax.vmap`` them over elements.
Node DOF (global frame): ``(ux, uy, uz, rx, ry, rz)``.

Local frame: e1 along the beam (node 1 → node 2), e2 = normalize(Z × e1) (global Y for a beam
along X), e3 = e1 × e2 (global Z for a horizontal beam); for a vertical beam X replaces Z.
``Iy`` is the second moment about e2 (bending in the e1–e3 plane, the vertical plane of a rib),
``Iz`` about e3.

The stiffness is the exact one of a prismatic Timoshenko beam (Przemieniecki 1968): for bending
in one plane, with ``Φ = 12 E I / (κ G A L²)``,
``K = E I / ((1 + Φ) L³) [[12, 6L, -12, 6L], [6L, (4+Φ)L², -6L, (2-Φ)L²], ...]``, so a cantilever
under a tip load deflects exactly ``P L³ / 3 E I + P L / κ G A``.

Offset (eccentric beam, e.g. a rib under a plate): the beam's axis runs at ``node + e`` (global
vector ``e``, m, the same at both ends) and is tied rigidly to the node:
``u_axis = u_node + θ_node × e``, ``θ_axis = θ_node``.
"""

import jax.numpy as jnp

from .._core.types import Array, Float, ScalarLike


def beam_frame(xyz: Float[Array, "2 3"]) -> tuple[Float[Array, "3 3"], Float[Array, ""]]:
    """Rows e1, e2, e3 of the local frame and the length L (m) of a beam element."""
    xyz = jnp.asarray(xyz)
    d = xyz[1] - xyz[0]
    L = jnp.linalg.norm(d)
    e1 = d / L
    ez = jnp.array([0.0, 0.0, 1.0], dtype=d.dtype)
    ex = jnp.array([1.0, 0.0, 0.0], dtype=d.dtype)
    ref = jnp.where(jnp.abs(e1[2]) > 0.99, ex, ez)
    e2 = jnp.cross(ref, e1)
    e2 = e2 / jnp.linalg.norm(e2)
    e3 = jnp.cross(e1, e2)
    return jnp.stack([e1, e2, e3]), L


def rect_section(width: ScalarLike, depth: ScalarLike) -> dict[str, Array]:
    """Section constants of a solid rectangle, ``width`` along e2 and ``depth`` along e3 (m).

    Returns ``A`` (m²), ``Iy = w h³/12`` (about e2), ``Iz = h w³/12`` (about e3) and the torsion
    constant ``J = a b³ (1/3 - 0.21 (b/a)(1 - b⁴/(12 a⁴)))`` with a ≥ b the long and short sides
    (Roark, Table 10.7, within ~4 %).
    """
    w, h = jnp.asarray(width), jnp.asarray(depth)
    a, b = jnp.maximum(w, h), jnp.minimum(w, h)
    J = a * b**3 * (1.0 / 3.0 - 0.21 * (b / a) * (1.0 - b**4 / (12.0 * a**4)))
    return {"A": w * h, "Iy": w * h**3 / 12.0, "Iz": h * w**3 / 12.0, "J": J}


def _bending(EI, phi, L, sign):
    """4×4 Timoshenko bending block for (deflection 1, rotation 1, deflection 2, rotation 2)."""
    c = EI / ((1.0 + phi) * L**3)
    s = sign
    return c * jnp.array(
        [
            [12.0, s * 6 * L, -12.0, s * 6 * L],
            [s * 6 * L, (4 + phi) * L**2, -s * 6 * L, (2 - phi) * L**2],
            [-12.0, -s * 6 * L, 12.0, -s * 6 * L],
            [s * 6 * L, (2 - phi) * L**2, -s * 6 * L, (4 + phi) * L**2],
        ]
    )


def _offset_matrix(offset):
    """12×12 map from node DOF to beam-axis DOF: u_axis = u_node + θ × e (for both nodes)."""
    e = jnp.asarray(offset)
    ex = jnp.array([[0.0, -e[2], e[1]], [e[2], 0.0, -e[0]], [-e[1], e[0], 0.0]])  # e × (.)
    A = jnp.eye(6, dtype=ex.dtype).at[:3, 3:].set(-ex)
    return jnp.kron(jnp.eye(2, dtype=ex.dtype), A)


def beam_stiffness(
    xyz: Float[Array, "2 3"],
    E: ScalarLike,
    G: ScalarLike,
    A: ScalarLike,
    Iy: ScalarLike,
    Iz: ScalarLike,
    J: ScalarLike,
    kappa: float = 5.0 / 6.0,
    offset: Float[Array, "3"] | None = None,
) -> Float[Array, "12 12"]:
    """Stiffness (global frame) of a 2-node Timoshenko beam.

    Args:
        xyz: node coordinates (m).
        E, G: Young's and shear moduli (Pa).
        A: area (m²); Iy, Iz: second moments about e2, e3 (m⁴); J: torsion constant (m⁴).
        kappa: shear correction factor (5/6 for a rectangle), the same in both planes.
        offset: global vector (m) from the nodes to the beam axis; None for no offset.

    Returns:
        K (12, 12) for ``(ux, uy, uz, rx, ry, rz)`` of node 1 then node 2.
    """
    R, L = beam_frame(xyz)
    E, G = jnp.asarray(E), jnp.asarray(G)
    Ks = kappa * G * A
    K = jnp.zeros((12, 12), dtype=R.dtype)
    ax = E * A / L * jnp.array([[1.0, -1.0], [-1.0, 1.0]])
    tor = G * J / L * jnp.array([[1.0, -1.0], [-1.0, 1.0]])
    iu, it = jnp.array([0, 6]), jnp.array([3, 9])
    K = K.at[jnp.ix_(iu, iu)].set(ax)
    K = K.at[jnp.ix_(it, it)].set(tor)
    iv = jnp.array([1, 5, 7, 11])  # v, θz: w' = θz  -> sign +
    K = K.at[jnp.ix_(iv, iv)].set(_bending(E * Iz, 12 * E * Iz / (Ks * L**2), L, 1.0))
    iw = jnp.array([2, 4, 8, 10])  # w, θy: w' = -θy -> sign -
    K = K.at[jnp.ix_(iw, iw)].set(_bending(E * Iy, 12 * E * Iy / (Ks * L**2), L, -1.0))
    T = jnp.kron(jnp.eye(4, dtype=R.dtype), R)
    if offset is not None:
        T = T @ _offset_matrix(offset)
    return T.T @ K @ T


def beam_load(
    xyz: Float[Array, "2 3"], q: Float[Array, "3"], offset: Float[Array, "3"] | None = None
) -> Float[Array, "12"]:
    """Equivalent nodal loads (N, N·m) of a uniform line load ``q`` (N/m, global) on the axis.

    Forces ``q L / 2`` at each node and the fixed-end moments ``± (L² / 12) e1 × q`` (exact for
    the Timoshenko beam), carried to the nodes through the offset.
    """
    R, L = beam_frame(xyz)
    q = jnp.asarray(q, dtype=R.dtype)
    m = L**2 / 12.0 * jnp.cross(R[0], q)
    f = jnp.concatenate([0.5 * L * q, m, 0.5 * L * q, -m])
    if offset is not None:
        f = _offset_matrix(offset).T @ f
    return f
