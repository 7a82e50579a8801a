"""4-node flat shell: bilinear membrane + MITC4 Reissner–Mindlin bending + drilling penalty.

Pure functions of the node coordinates and section of one element, or of a batch of elements
(leading axes). Each is written once for an array module ``xp``: :mod:`jax.numpy` (the default;
traceable and differentiable) or :mod:`numpy` (eager, for concrete inputs: no tracing, no
compilation; used by :func:`diffguide.fe.condense` when nothing is traced).

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

Thickness. The strain–displacement matrix ``B`` does not depend on ``t``, and the section matrix
is ``t D₁ + t³ D₃`` (``D₁``: membrane, shear, drilling; ``D₃``: bending), so the stiffness is
exactly ``K(t) = t K₁ + t³ K₃`` (:func:`shell_matrices`).

Reference: K.-J. Bathe, E. N. Dvorkin, "A four-node plate bending element based on
Mindlin/Reissner plate theory and a mixed interpolation", IJNME 21 (1985) 367-383.
"""

import math

import jax.numpy as jnp
import numpy as np

from .._core.types import Array, Float, ScalarLike
from ._xp import congruence

_G = 1.0 / math.sqrt(3.0)
_GAUSS = ((-_G, -_G), (_G, -_G), (_G, _G), (-_G, _G))
_XI = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))
_XK = np.array([p[0] for p in _XI])
_EK = np.array([p[1] for p in _XI])
#: Unit displacement states of the 24 element DOF, (24, 4, 6): the strains of these are the
#: columns of ``B`` (the strains are linear in the DOF).
_UNIT = np.eye(24).reshape(24, 4, 6)


def _shape(xi, eta, xp=jnp):
    """Bilinear shape functions (..., 4) and their derivatives d/dξ, d/dη (..., 2, 4) at
    natural coordinates ``xi``, ``eta`` (scalars or arrays of any shape)."""
    xi, eta = xp.asarray(xi)[..., None], xp.asarray(eta)[..., None]
    n = 0.25 * (1 + xi * _XK) * (1 + eta * _EK)
    dn = xp.stack([0.25 * _XK * (1 + eta * _EK), 0.25 * _EK * (1 + xi * _XK)], axis=-2)
    return n, dn


def _inv2(J, xp):
    """Inverse and determinant of (..., 2, 2) matrices (closed form)."""
    a, b, c, d = J[..., 0, 0], J[..., 0, 1], J[..., 1, 0], J[..., 1, 1]
    det = a * d - b * c
    inv = xp.stack([xp.stack([d, -b], axis=-1), xp.stack([-c, a], axis=-1)], axis=-2)
    return inv / det[..., None, None], det


def _cross(a, b, xp):
    return xp.cross(a, b, axis=-1)


def _normalize(v, xp):
    return v / xp.sqrt(xp.sum(v * v, axis=-1, keepdims=True))


def shell_frame(
    xyz: Float[Array, "... 4 3"], xp=jnp
) -> tuple[Float[Array, "... 3 3"], Float[Array, "... 4 2"]]:
    """Local frame of a (nearly flat) quad and its nodes' in-plane coordinates.

    Returns ``(R, xy)``: rows of ``R`` are e1 (mean ξ direction), e2, e3 (unit normal,
    ``(x3 - x1) × (x4 - x2)``); ``xy`` are the nodes projected on the mean plane (m).
    Leading axes of ``xyz`` are a batch of elements.
    """
    xyz = xp.asarray(xyz)
    n = _normalize(_cross(xyz[..., 2, :] - xyz[..., 0, :], xyz[..., 3, :] - xyz[..., 1, :], xp), xp)
    a = (xyz[..., 1, :] + xyz[..., 2, :]) - (xyz[..., 0, :] + xyz[..., 3, :])
    a = a - xp.sum(a * n, axis=-1, keepdims=True) * n
    e1 = _normalize(a, xp)
    e2 = _cross(n, e1, xp)
    R = xp.stack([e1, e2, n], axis=-2)
    xy = (xyz - xp.mean(xyz, axis=-2, keepdims=True)) @ xp.swapaxes(R[..., :2, :], -1, -2)
    return R, xy


def _strains(d, xy, xi, eta, xp=jnp):
    """Generalized strains [ε (3), κ (3), γ (2), θz - ω (1)] (..., 9) at (ξ, η) for local DOF
    ``d`` (..., 4, 6) of elements with in-plane node coordinates ``xy`` (..., 4, 2) (leading
    axes broadcast), and ``det J`` (...)."""
    n, dn = _shape(xi, eta, xp)
    J = dn @ xy  # [[x_ξ, y_ξ], [x_η, y_η]]
    Jinv, detJ = _inv2(J, xp)
    dx = Jinv @ dn  # (..., 2, 4): dN/dx, dN/dy
    u, v, w, tx, ty, tz = (d[..., k] for k in range(6))
    bx, by = ty, -tx

    def dot(a, b):
        return xp.sum(a * b, axis=-1)

    nx_, ny_ = dx[..., 0, :], dx[..., 1, :]
    eps = [dot(nx_, u), dot(ny_, v), dot(ny_, u) + dot(nx_, v)]
    kap = [dot(nx_, bx), dot(ny_, by), dot(ny_, bx) + dot(nx_, by)]

    def covariant(xt, et):  # displacement-based covariant shear strains (γ_ξ, γ_η)
        nt, dnt = _shape(xt, et, xp)
        Jt = dnt @ xy
        beta = (dot(nt, bx), dot(nt, by))
        return [dot(dnt[r], w) + Jt[..., r, 0] * beta[0] + Jt[..., r, 1] * beta[1] for r in (0, 1)]

    g_xi = 0.5 * (1 - eta) * covariant(0.0, -1.0)[0] + 0.5 * (1 + eta) * covariant(0.0, 1.0)[0]
    g_eta = 0.5 * (1 - xi) * covariant(-1.0, 0.0)[1] + 0.5 * (1 + xi) * covariant(1.0, 0.0)[1]
    gam = [Jinv[..., r, 0] * g_xi + Jinv[..., r, 1] * g_eta for r in (0, 1)]
    drill = dot(n, tz) - 0.5 * (dot(nx_, v) - dot(ny_, u))
    return xp.stack(eps + kap + gam + [drill], axis=-1), detJ


def _plane_stress(nu, xp=jnp):
    nu = xp.asarray(nu)
    one, zero = xp.ones_like(nu), xp.zeros_like(nu)
    rows = [[one, nu, zero], [nu, one, zero], [zero, zero, 0.5 * (1.0 - nu)]]
    return xp.stack([xp.stack(r, axis=-1) for r in rows], axis=-2)


def _to_global(K, R, xp):
    """``Tᵀ K T`` with ``T = I₈ ⊗ R``: (..., 24, 24) local → global frame."""
    return congruence(K, xp.broadcast_to(R[..., None, :, :], R.shape[:-2] + (8, 3, 3)), xp)


def shell_matrices(
    xyz: Float[Array, "... 4 3"],
    E: ScalarLike,
    nu: ScalarLike,
    kappa: float = 5.0 / 6.0,
    drill: float = 1e-3,
    xp=jnp,
) -> tuple[Float[Array, "... 24 24"], Float[Array, "... 24 24"]]:
    """The thickness-free parts ``(K₁, K₃)`` of the stiffness ``K(t) = t K₁ + t³ K₃`` (global
    frame; N/m³ and N/m⁵ per unit displacement, likewise for rotations) of a batch of elements
    ``xyz`` (..., 4, 3) (arguments as :func:`shell_stiffness`; ``E``, ``nu`` scalars or
    broadcasting with the batch)."""
    R, xy = shell_frame(xyz, xp)
    E, nu = xp.asarray(E), xp.asarray(nu)
    G = xp.asarray(E / (2.0 * (1.0 + nu)))
    C = _plane_stress(nu, xp) * xp.asarray(E / (1.0 - nu**2))[..., None, None]
    K1 = K3 = 0.0
    for xi, eta in _GAUSS:
        # B (..., 9, 24): strains of the 24 unit DOF states (exactly the Jacobian: linear map)
        S, detJ = _strains(_UNIT, xy[..., None, :, :], xi, eta, xp)
        B = xp.swapaxes(S, -1, -2)
        Bm, Bb, Bs, Bd = B[..., 0:3, :], B[..., 3:6, :], B[..., 6:8, :], B[..., 8, :]
        w = detJ[..., 0, None, None]
        K1 = K1 + w * (
            xp.swapaxes(Bm, -1, -2) @ C @ Bm
            + kappa * G[..., None, None] * (xp.swapaxes(Bs, -1, -2) @ Bs)
            + drill * G[..., None, None] * (Bd[..., :, None] * Bd[..., None, :])
        )
        K3 = K3 + w * (xp.swapaxes(Bb, -1, -2) @ (C / 12.0) @ Bb)
    return _to_global(K1, R, xp), _to_global(K3, R, xp)


def shell_stiffness(
    xyz: Float[Array, "... 4 3"],
    thickness: ScalarLike,
    E: ScalarLike,
    nu: ScalarLike,
    kappa: float = 5.0 / 6.0,
    drill: float = 1e-3,
    xp=jnp,
) -> Float[Array, "... 24 24"]:
    """Stiffness matrix (N/m, N, N·m per rad) of one flat MITC4 shell in the global frame.

    Args:
        xyz: node coordinates (m), counter-clockwise about the normal; (..., 4, 3) for a batch.
        thickness: plate thickness t (m).
        E: Young's modulus (Pa). nu: Poisson's ratio.
        kappa: transverse shear correction (5/6).
        drill: drilling penalty factor α (the penalty stiffness is α G t per unit area).
        xp: array module (:mod:`jax.numpy` or :mod:`numpy`).

    Returns:
        K (24, 24) for the DOF ``(ux, uy, uz, rx, ry, rz)`` of nodes 1..4 in turn:
        ``t K₁ + t³ K₃`` (:func:`shell_matrices`).
    """
    K1, K3 = shell_matrices(xyz, E, nu, kappa, drill, xp)
    t = xp.asarray(thickness)[..., None, None]
    return t * K1 + t**3 * K3


def shell_area_weights(xyz: Float[Array, "... 4 3"], xp=jnp) -> Float[Array, "... 4"]:
    """``∫ N_k dA`` (m²) for each node: the consistent nodal share of a uniform surface load."""
    _, xy = shell_frame(xyz, xp)
    w = 0.0
    for xi, eta in _GAUSS:
        n, dn = _shape(xi, eta, xp)
        _, det = _inv2(dn @ xy, xp)
        w = w + n * det[..., None]
    return w


def shell_load(
    xyz: Float[Array, "... 4 3"], traction: Float[Array, "... 3"], xp=jnp
) -> Float[Array, "... 24"]:
    """Consistent nodal forces (N) of a uniform surface load ``traction`` (Pa, global X, Y, Z)."""
    w = shell_area_weights(xyz, xp)
    tr = xp.asarray(traction)[..., None, :]
    f = xp.concatenate([w[..., :, None] * tr, xp.zeros_like(w[..., :, None] * tr)], axis=-1)
    return xp.reshape(f, f.shape[:-2] + (24,))


def shell_shape(xi: ScalarLike, eta: ScalarLike, xp=jnp) -> Float[Array, "... 4"]:
    """Bilinear shape functions at natural coordinates (ξ, η) in [-1, 1]²."""
    return _shape(xi, eta, xp)[0]


def shell_natural_coords(
    xyz: Float[Array, "... 4 3"], p: Float[Array, "... 2"], xp=jnp
) -> Float[Array, "... 2"]:
    """Natural coordinates (ξ, η) of the in-plane point ``p`` (global x, y in m) in a quad.

    Newton on the bilinear map (exact after one step for parallelograms; 4 steps).
    """
    xyz, p = xp.asarray(xyz), xp.asarray(p)
    R, xy = shell_frame(xyz, xp)
    c = xp.mean(xyz, axis=-2)
    p3 = xp.stack([p[..., 0], p[..., 1], c[..., 2]], axis=-1)
    target = ((p3 - c)[..., None, :] @ xp.swapaxes(R[..., :2, :], -1, -2))[..., 0, :]
    s = xp.zeros_like(target)
    for _ in range(4):
        n, dn = _shape(s[..., 0], s[..., 1], xp)
        r = (n[..., None, :] @ xy)[..., 0, :] - target
        Jinv, _ = _inv2(dn @ xy, xp)  # rows: d(x, y)/dξ, d(x, y)/dη
        s = s - (r[..., None, :] @ Jinv)[..., 0, :]  # J⁻ᵀ r
    return s
