"""4-node flat shell: bilinear membrane + MITC4 Reissner–Mindlin bending + drilling penalty.

Pure functions of one element's node coordinates and section; ``jax.vmap`` them over elements.

Node DOF (global frame): ``(ux, uy, uz, rx, ry, rz)``, rotations in rad about the global axes
(right-hand rule). In the element's local frame (e1, e2 in the mean plane, e3 = normal) a point at
distance ``z`` from the mid-surface moves by ``u + θ × z e3``, i.e. ``βx = θy``, ``βy = -θx``.

Strains (local frame, shape functions ``N_k`` of the bilinear quad, 2×2 Gauss):

- membrane ``ε = [u,x, v,y, u,y + v,x]``,
  ``N = (E t / (1 - ν²)) [[1, ν, 0], [ν, 1, 0], [0, 0, (1-ν)/2]] ε``;
- bending ``κ = [βx,x, βy,y, βx,y + βy,x]``, ``D = E t³ / (12 (1 - ν²))`` times the same matrix;
- transverse shear ``γ = [w,x + βx, w,y + βy]`` with the MITC4 assumed covariant strains of
  Bathe & Dvorkin (1985): ``γ_ξ`` tied at the edge midpoints (0, ±1), ``γ_η`` at (±1, 0),
  interpolated linearly and mapped back by ``γ = J⁻¹ [γ_ξ, γ_η]``; shear stiffness ``κ_s G t``
  (``κ_s = 5/6``). This removes shear locking: the element is accurate for thin plates.
- drilling: the penalty ``½ ∫ α G t (θz - ω)² dA`` with ``ω = (v,x - u,y) / 2`` the in-plane
  rotation (Hughes & Brezzi 1989), ``α`` = ``drill`` (default 1e-3): it gives ``rz`` stiffness
  (so that the assembled matrix is regular) and leaves rigid-body rotation and any linear
  membrane field (patch test) free of energy.

Reference: K.-J. Bathe, E. N. Dvorkin, "A four-node plate bending element based on
Mindlin/Reissner plate theory and a mixed interpolation", IJNME 21 (1985) 367-383.
"""

import math

import jax
import jax.numpy as jnp

from .._core.types import Array, Float, ScalarLike

_G = 1.0 / math.sqrt(3.0)
_GAUSS = ((-_G, -_G), (_G, -_G), (_G, _G), (-_G, _G))
_XI = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))


def _shape(xi, eta):
    """Bilinear shape functions (4,) and their derivatives d/dξ, d/dη (2, 4)."""
    xk = jnp.array([p[0] for p in _XI])
    ek = jnp.array([p[1] for p in _XI])
    n = 0.25 * (1 + xi * xk) * (1 + eta * ek)
    dn = jnp.stack([0.25 * xk * (1 + eta * ek), 0.25 * ek * (1 + xi * xk)])
    return n, dn


def shell_frame(xyz: Float[Array, "4 3"]) -> tuple[Float[Array, "3 3"], Float[Array, "4 2"]]:
    """Local frame of a (nearly flat) quad and its nodes' in-plane coordinates.

    Returns ``(R, xy)``: rows of ``R`` are e1 (mean ξ direction), e2, e3 (unit normal,
    ``(x3 - x1) × (x4 - x2)``); ``xy`` are the nodes projected on the mean plane (m).
    """
    xyz = jnp.asarray(xyz)
    n = jnp.cross(xyz[2] - xyz[0], xyz[3] - xyz[1])
    n = n / jnp.linalg.norm(n)
    a = (xyz[1] + xyz[2]) - (xyz[0] + xyz[3])
    a = a - jnp.dot(a, n) * n
    e1 = a / jnp.linalg.norm(a)
    e2 = jnp.cross(n, e1)
    R = jnp.stack([e1, e2, n])
    xy = (xyz - jnp.mean(xyz, axis=0)) @ R[:2].T
    return R, xy


def _strains(d, xy, xi, eta):
    """Generalized strains [ε (3), κ (3), γ (2), θz - ω (1)] at (ξ, η) for local DOF d (4, 6)."""
    n, dn = _shape(xi, eta)
    J = dn @ xy  # [[x_ξ, y_ξ], [x_η, y_η]]
    dx = jnp.linalg.solve(J, dn)  # (2, 4): dN/dx, dN/dy
    u, v, w, tx, ty, tz = (d[:, k] for k in range(6))
    bx, by = ty, -tx
    eps = jnp.array([dx[0] @ u, dx[1] @ v, dx[1] @ u + dx[0] @ v])
    kap = jnp.array([dx[0] @ bx, dx[1] @ by, dx[1] @ bx + dx[0] @ by])

    def covariant(xt, et):  # displacement-based covariant shear strains (γ_ξ, γ_η)
        nt, dnt = _shape(xt, et)
        Jt = dnt @ xy
        beta = jnp.array([nt @ bx, nt @ by])
        return dnt @ w + Jt @ beta

    g_xi = 0.5 * (1 - eta) * covariant(0.0, -1.0)[0] + 0.5 * (1 + eta) * covariant(0.0, 1.0)[0]
    g_eta = 0.5 * (1 - xi) * covariant(-1.0, 0.0)[1] + 0.5 * (1 + xi) * covariant(1.0, 0.0)[1]
    gam = jnp.linalg.solve(J, jnp.array([g_xi, g_eta]))
    drill = n @ tz - 0.5 * (dx[0] @ v - dx[1] @ u)
    return jnp.concatenate([eps, kap, gam, drill[None]]), jnp.linalg.det(J)


def _plane_stress(nu):
    return jnp.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, 0.5 * (1.0 - nu)]])


def shell_stiffness(
    xyz: Float[Array, "4 3"],
    thickness: ScalarLike,
    E: ScalarLike,
    nu: ScalarLike,
    kappa: float = 5.0 / 6.0,
    drill: float = 1e-3,
) -> Float[Array, "24 24"]:
    """Stiffness matrix (N/m, N, N·m per rad) of one flat MITC4 shell in the global frame.

    Args:
        xyz: node coordinates (m), counter-clockwise about the normal.
        thickness: plate thickness t (m).
        E: Young's modulus (Pa). nu: Poisson's ratio.
        kappa: transverse shear correction (5/6).
        drill: drilling penalty factor α (the penalty stiffness is α G t per unit area).

    Returns:
        K (24, 24) for the DOF ``(ux, uy, uz, rx, ry, rz)`` of nodes 1..4 in turn.
    """
    R, xy = shell_frame(xyz)
    t = jnp.asarray(thickness)
    E = jnp.asarray(E)
    nu = jnp.asarray(nu)
    G = E / (2.0 * (1.0 + nu))
    C = _plane_stress(nu) * (E / (1.0 - nu**2))
    D = jnp.zeros((9, 9))
    D = D.at[0:3, 0:3].set(C * t)
    D = D.at[3:6, 3:6].set(C * t**3 / 12.0)
    D = D.at[6:8, 6:8].set(jnp.eye(2) * kappa * G * t)
    D = D.at[8, 8].set(drill * G * t)
    d0 = jnp.zeros((4, 6), dtype=xy.dtype)
    K = jnp.zeros((24, 24), dtype=xy.dtype)
    for xi, eta in _GAUSS:
        B = jax.jacfwd(lambda d: _strains(d, xy, xi, eta)[0])(d0).reshape(9, 24)
        detJ = _strains(d0, xy, xi, eta)[1]
        K = K + detJ * (B.T @ D @ B)
    T = jnp.kron(jnp.eye(8, dtype=R.dtype), R)
    return T.T @ K @ T


def shell_area_weights(xyz: Float[Array, "4 3"]) -> Float[Array, "4"]:
    """``∫ N_k dA`` (m²) for each node: the consistent nodal share of a uniform surface load."""
    _, xy = shell_frame(xyz)
    w = jnp.zeros(4, dtype=xy.dtype)
    for xi, eta in _GAUSS:
        n, dn = _shape(xi, eta)
        w = w + n * jnp.linalg.det(dn @ xy)
    return w


def shell_load(xyz: Float[Array, "4 3"], traction: Float[Array, "3"]) -> Float[Array, "24"]:
    """Consistent nodal forces (N) of a uniform surface load ``traction`` (Pa, global X, Y, Z)."""
    w = shell_area_weights(xyz)
    f = jnp.zeros((4, 6), dtype=w.dtype).at[:, :3].set(w[:, None] * jnp.asarray(traction))
    return f.reshape(24)


def shell_shape(xi: ScalarLike, eta: ScalarLike) -> Float[Array, "4"]:
    """Bilinear shape functions at natural coordinates (ξ, η) in [-1, 1]²."""
    return _shape(jnp.asarray(xi), jnp.asarray(eta))[0]


def shell_natural_coords(xyz: Float[Array, "4 3"], p: Float[Array, "2"]) -> Float[Array, "2"]:
    """Natural coordinates (ξ, η) of the in-plane point ``p`` (global x, y in m) in a quad.

    Newton on the bilinear map (exact after one step for parallelograms; 4 steps).
    """
    R, xy = shell_frame(xyz)
    c = jnp.mean(jnp.asarray(xyz), axis=0)
    p3 = jnp.array([p[0], p[1], c[2]])
    target = (p3 - c) @ R[:2].T
    s = jnp.zeros(2, dtype=xy.dtype)
    for _ in range(4):
        n, dn = _shape(s[0], s[1])
        r = n @ xy - target
        J = dn @ xy  # rows: d(x, y)/dξ, d(x, y)/dη
        s = s - jnp.linalg.solve(J.T, r)
    return s
