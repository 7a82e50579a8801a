"""The eager NumPy evaluation of the table (``condense(backend="numpy")``, the default for
concrete inputs) against the compiled JAX program, and the shell stiffness's thickness split
``K(t) = t K₁ + t³ K₃`` against a direct quadrature of ``Bᵀ D(t) B`` with ``B`` from
``jax.jacfwd`` of the strain map."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide.fe import Rib, RigidPatch, condense, table_mesh
from diffguide.fe.assemble import PlateSection
from diffguide.fe.beam import beam_load, beam_stiffness
from diffguide.fe.shell import (
    _GAUSS,
    _plane_stress,
    _strains,
    shell_frame,
    shell_load,
    shell_natural_coords,
    shell_stiffness,
)
from diffguide.machine.majda2012 import majda2012_table

FIELDS = ("K", "f", "R", "r0", "node_modes", "node_u0", "ref_points", "nodes")


def _rel(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def _quad():
    """A warped, skewed quad in a rotated frame (not axis-aligned, not flat)."""
    rot = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0]
    xyz = np.array([[0, 0, 0], [0.1, 0.01, 0.002], [0.12, 0.09, -0.001], [-0.01, 0.08, 0.0]])
    return xyz @ rot


def _direct_shell(xyz, t, E, nu, kappa=5.0 / 6.0, drill=1e-3):
    """Σ det J Bᵀ D(t) B with B = jacfwd of the strain map and D(t) built at the thickness."""
    R, xy = shell_frame(jnp.asarray(xyz))
    G = E / (2 * (1 + nu))
    C = np.asarray(_plane_stress(nu)) * E / (1 - nu**2)
    D = np.zeros((9, 9))
    D[0:3, 0:3] = C * t
    D[3:6, 3:6] = C * t**3 / 12
    D[6:8, 6:8] = np.eye(2) * kappa * G * t
    D[8, 8] = drill * G * t
    K = np.zeros((24, 24))
    d0 = jnp.zeros((4, 6))
    for xi, eta in _GAUSS:
        B = np.asarray(jax.jacfwd(lambda d: _strains(d, xy, xi, eta)[0])(d0)).reshape(9, 24)
        detJ = float(_strains(d0, xy, xi, eta)[1])
        K += detJ * B.T @ D @ B
    T = np.kron(np.eye(8), np.asarray(R))
    return T.T @ K @ T


@pytest.mark.parametrize("t", [0.005, 0.05, 0.3])
def test_shell_thickness_split_equals_direct_quadrature(t):
    xyz = _quad()
    ref = _direct_shell(xyz, t, 110e9, 0.26)
    assert _rel(shell_stiffness(xyz, t, 110e9, 0.26, xp=np), ref) < 1e-12
    assert _rel(shell_stiffness(jnp.asarray(xyz), t, 110e9, 0.26), ref) < 1e-12


def test_element_functions_numpy_equal_jax_batched():
    xyz = np.stack([_quad(), 1.7 * _quad() + 0.3, _quad()[[1, 2, 3, 0]]])
    t = np.array([0.02, 0.05, 0.1])
    Kn = shell_stiffness(xyz, t, 110e9, 0.26, xp=np)
    for i in range(3):
        Kj = shell_stiffness(jnp.asarray(xyz[i]), t[i], 110e9, 0.26)
        assert _rel(Kn[i], Kj) < 1e-13
    tr = np.array([1.0, -2.0, -3.0])
    assert _rel(shell_load(xyz, tr, xp=np), jax.vmap(lambda x: shell_load(x, tr))(xyz)) < 1e-14
    p = xyz.mean(axis=1)[:, :2] + 0.01
    s_np = shell_natural_coords(xyz, p, xp=np)
    s_jx = jax.vmap(shell_natural_coords)(jnp.asarray(xyz), jnp.asarray(p))
    assert _rel(s_np, s_jx) < 1e-12
    bx = np.array([[[0, 0, 0], [0.2, 0.05, 0.01]], [[0.1, 0, 0], [0.1, 0, 0.3]]])
    off = np.array([[0, 0, -0.04], [0.01, 0.02, 0.0]])
    sec = (2e11, 8e10, 1e-3, 2e-7, 3e-7, 1e-7, 5 / 6)
    Kb = beam_stiffness(bx, *sec, off, xp=np)
    fb = beam_load(bx, np.array([1.0, 2.0, 3.0]), off, xp=np)
    for i in range(2):
        assert _rel(Kb[i], beam_stiffness(jnp.asarray(bx[i]), *sec, jnp.asarray(off[i]))) < 1e-13
        assert _rel(fb[i], beam_load(jnp.asarray(bx[i]), jnp.array([1.0, 2, 3]), off[i])) < 1e-14


@pytest.mark.parametrize("method", ["banded", "dense"])
def test_numpy_condensation_equals_jax(method):
    """Ribbed table, points between nodes: the two backends agree to 1e-10 (every field)."""
    ribs = [Rib("x", 0.0, 0.03, 0.05, start=-0.3, stop=0.3), Rib("y", 0.1, 0.02, 0.04)]
    tm = majda2012_table(10, 5, ribs=ribs)
    mesh, plate = tm.mesh, tm.plate
    pts = [(0.013, 0.021), (-0.27, 0.18)]
    a = condense(mesh, plate, tm.patches, pts, method=method, backend="numpy")
    b = condense(mesh, plate, tm.patches, pts, method=method, backend="jax")
    for name in FIELDS:
        assert _rel(getattr(a, name), getattr(b, name)) < 1e-10, name
    assert isinstance(a.K, jax.Array)


def test_numpy_condensation_with_moved_nodes_and_reference_points():
    """``nodes`` / ``ref_xy`` overrides (point coordinates by Newton, not the grid formula)."""
    mesh = table_mesh(0.8, 0.4, 8, 4, lines_x=[-0.25, -0.15, 0.15, 0.25])
    plate = PlateSection(0.04)
    patches = [RigidPatch(x, 0.0, 0.05, 0.1) for x in (-0.2, 0.2)]
    nodes = np.asarray(mesh.nodes) * np.array([1.01, 0.99, 1.0]) + np.array([0, 0, 1e-4])
    ref_xy = np.array([[-0.21, 0.001], [0.205, -0.002]])
    kw = dict(nodes=nodes, ref_xy=ref_xy, surface_load=np.array([0.0, 0.0, -1e3]))
    a = condense(mesh, plate, patches, [(0.05, 0.03)], backend="numpy", **kw)
    b = condense(mesh, plate, patches, [(0.05, 0.03)], backend="jax", **kw)
    for name in FIELDS:
        assert _rel(getattr(a, name), getattr(b, name)) < 1e-10, name


def test_auto_backend_keeps_gradients_and_numpy_refuses_tracers():
    tm = majda2012_table(6, 3)

    def stiff(t, backend="auto"):
        pl = eqx.tree_at(lambda p: p.thickness, tm.plate, t)
        return condense(tm.mesh, pl, tm.patches, tm.points, backend=backend).K[2, 2]

    g = jax.grad(stiff)(0.05)
    h = 1e-6
    fd = (stiff(0.05 + h) - stiff(0.05 - h)) / (2 * h)
    assert float(g) == pytest.approx(float(fd), rel=1e-6)
    with pytest.raises(ValueError, match="concrete"):
        jax.grad(lambda t: stiff(t, "numpy"))(0.05)
    with pytest.raises(ValueError, match="backend"):
        condense(tm.mesh, tm.plate, tm.patches, backend="scipy")
