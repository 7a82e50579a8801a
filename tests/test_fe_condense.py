"""Condensation onto rigid patches against an independent full solve; the block-tridiagonal
(default) path against the dense one; gradients of the default path vs finite differences."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide.fe import (
    PlateSection,
    Rib,
    RigidPatch,
    assemble,
    banded,
    condense,
    solve_fixed,
    table_mesh,
)
from diffguide.fe.banded import block_layout
from diffguide.fe.materials import Material
from diffguide.machine.majda2012 import majda2012_table


@pytest.fixture(scope="module")
def small():
    """majda2012 table on a coarse 10 × 5 grid (+ footprint lines), with the nut and a rib."""
    tm = majda2012_table(10, 5, ribs=[Rib("x", 0.0, 0.03, 0.05, start=-0.3, stop=0.3)])
    return tm, tm.condense()


def _full_solution(tm, u_b):
    """Independent full solve: all node DOF, slave DOF prescribed to the rigid motion of u_b.

    Returns node DOF (n, 6) and the wrench on the table at each reference point, summed from
    the reactions at its slave nodes: F = Σ r_k, M = Σ (d_k × r_k + m_k).
    """
    mesh, t = tm.mesh, float(tm.plate.thickness)
    K, f = assemble(mesh, tm.plate, gravity=tm.gravity)
    K, f = np.asarray(K), np.asarray(f)
    fixed, values, owners = [], [], []
    for p, patch in enumerate(tm.patches):
        ref = np.array([patch.x, patch.y, -t / 2])
        ub = u_b[6 * p : 6 * p + 6]
        for k in mesh.nodes_in_box(*patch.box):
            d = mesh.nodes[k] - ref
            fixed += list(range(6 * k, 6 * k + 6))
            values += list(ub[:3] + np.cross(ub[3:], d)) + list(ub[3:])
            owners.append((p, k, d))
    u = solve_fixed(jnp.asarray(K), jnp.asarray(f), np.array(fixed), jnp.asarray(values))
    u = np.asarray(u)
    r = (K @ u - f).reshape(-1, 6)
    F = np.zeros((len(tm.patches), 6))
    for p, k, d in owners:
        F[p, :3] += r[k, :3]
        F[p, 3:] += np.cross(d, r[k, :3]) + r[k, 3:]
    return u.reshape(-1, 6), F.ravel()


def _rel(a, b):
    return np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(np.asarray(b)))


def test_condensed_equals_full_solve(small):
    tm, c = small
    rng = np.random.default_rng(0)
    m = 6 * len(tm.patches)
    u_b = np.concatenate([rng.normal(scale=s, size=3) for _ in tm.patches for s in (1e-5, 1e-5)])
    u_b = u_b.reshape(-1, 6)
    u_b[:, 3:] *= 1e-1  # rotations ~1e-6 rad, translations ~1e-5 m
    u_b = u_b.ravel()
    assert u_b.shape == (m,)
    u_full, F_full = _full_solution(tm, u_b)
    assert _rel(c.node_displacements(jnp.asarray(u_b)), u_full) < 1e-10
    assert _rel(c.interface_loads(jnp.asarray(u_b)), F_full) < 1e-10
    # control points: they are nodes (grid lines there); top-surface point = node + θ × (0,0,t/2)
    t = float(tm.plate.thickness)
    expect = []
    for x, y in tm.points:
        uk = u_full[tm.mesh.node_at(x, y)]
        expect.append(np.r_[uk[:3] + np.cross(uk[3:], [0, 0, t / 2]), uk[3:]])
    assert _rel(c.point_motion(jnp.asarray(u_b)), np.array(expect)) < 1e-10
    # gravity part alone
    u0, _ = _full_solution(tm, np.zeros(m))
    assert _rel(c.node_u0, u0) < 1e-10


def test_point_between_nodes_is_bilinear_interpolation():
    tm = majda2012_table(10, 5, nut=False)
    p = (0.3137, 0.0712)
    c = condense(tm.mesh, tm.plate, tm.patches, [p])
    xs, ys = tm.mesh.xs, tm.mesh.ys
    i, j = np.searchsorted(xs, p[0]) - 1, np.searchsorted(ys, p[1]) - 1
    sx = (p[0] - xs[i]) / (xs[i + 1] - xs[i])
    sy = (p[1] - ys[j]) / (ys[j + 1] - ys[j])
    u = np.asarray(c.node_u0)
    t = float(tm.plate.thickness)
    acc = np.zeros(6)
    for (di, dj), w in {
        (0, 0): (1 - sx) * (1 - sy),
        (1, 0): sx * (1 - sy),
        (1, 1): sx * sy,
        (0, 1): (1 - sx) * sy,
    }.items():
        uk = u[tm.mesh.node_at(xs[i + di], ys[j + dj])]
        acc += w * np.r_[uk[:3] + np.cross(uk[3:], [0, 0, t / 2]), uk[3:]]
    assert np.allclose(np.asarray(c.r0), acc, rtol=1e-12, atol=1e-12 * np.abs(acc).max())


def test_rigid_body_modes_and_load_resultant(small):
    tm, c = small
    K = np.asarray(c.K)
    assert np.allclose(K, K.T, rtol=0, atol=1e-12 * np.abs(K).max())
    refs = np.asarray(c.ref_points)
    rng = np.random.default_rng(1)
    for _ in range(3):
        a, w = rng.normal(size=3), rng.normal(size=3)
        u_b = np.concatenate([np.r_[a + np.cross(w, r), w] for r in refs])
        assert np.abs(K @ u_b).max() < 1e-9 * np.abs(K).max() * np.abs(u_b).max()
    ev = np.linalg.eigvalsh(K)
    assert np.sum(ev < 1e-9 * ev.max()) == 6
    # condensed loads = the table weight and its moment about the origin
    mesh = tm.mesh
    plate_w = tm.plate.material.rho * 9.81 * float(tm.plate.thickness) * 1.0 * 0.5
    rib_w = tm.plate.material.rho * 9.81 * 0.03 * 0.05 * 0.6
    f = np.asarray(c.f).reshape(-1, 6)
    assert f[:, 2].sum() == pytest.approx(-(plate_w + rib_w), rel=1e-12)
    moment = (np.cross(refs, f[:, :3]) + f[:, 3:]).sum(0)
    assert np.allclose(moment, 0.0, atol=1e-9 * plate_w)  # table and rib symmetric about 0
    assert mesh.beams.shape[0] > 0


def _uz_p1(tm, thickness=None, E=None, depth=None, nodes=None):
    plate = tm.plate
    if thickness is not None:
        plate = eqx.tree_at(lambda p: p.thickness, plate, thickness)
    if E is not None:
        plate = eqx.tree_at(lambda p: p.material.E, plate, E)
    mesh = tm.mesh
    if depth is not None:
        mesh = eqx.tree_at(lambda m: m.ribs[0].depth, mesh, depth)
    c = condense(mesh, plate, tm.patches, tm.points, nodes=nodes, gravity=9.81, method="banded")
    # a deflection with both parts: gravity sag plus the response to a carriage lift
    u_b = jnp.zeros(c.K.shape[0]).at[2].set(1e-6)
    return c.point_motion(u_b)[0, 2]


def test_gradients_match_finite_differences(small):
    """d(uz at P1)/d(thickness, E, rib depth) by reverse mode vs central differences."""
    tm, _ = small
    x0 = {"thickness": float(tm.plate.thickness), "E": 110e9, "depth": 0.05}
    g = jax.grad(lambda kw: _uz_p1(tm, **kw))({k: jnp.asarray(v) for k, v in x0.items()})
    for name, v in x0.items():
        h = 1e-4 * v
        fd = (_uz_p1(tm, **{**x0, name: v + h}) - _uz_p1(tm, **{**x0, name: v - h})) / (2 * h)
        assert float(g[name]) == pytest.approx(float(fd), rel=1e-6), name
    # independent check: with ν fixed, K ∝ E: R (a stiffness ratio) does not depend on E and
    # the gravity part r0 ∝ 1/E, so d(uz)/dE = -r0_z / E
    assert float(g["E"]) == pytest.approx(-float(small[1].r0[2]) / 110e9, rel=1e-9)


def test_gradient_wrt_node_coordinates(small):
    tm, _ = small
    x0 = jnp.asarray(tm.mesh.nodes)
    rng = np.random.default_rng(2)
    v = jnp.asarray(rng.normal(size=x0.shape) * np.array([1e-3, 1e-3, 1e-4]))
    _, jv = jax.jvp(lambda n: _uz_p1(tm, nodes=n), (x0,), (v,))
    h = 1e-3
    fd = (_uz_p1(tm, nodes=x0 + h * v) - _uz_p1(tm, nodes=x0 - h * v)) / (2 * h)
    assert float(jv) == pytest.approx(float(fd), rel=1e-6)


_FIELDS = ("K", "f", "R", "r0", "node_modes", "node_u0")


@pytest.mark.parametrize("ribbed", [False, True])
def test_banded_equals_dense(ribbed):
    """Block-tridiagonal condensation = dense Cholesky of the assembled reduced matrix."""
    ribs = [Rib("x", 0.0, 0.03, 0.05, start=-0.3, stop=0.3), Rib("y", 0.1, 0.02, 0.04)]
    tm = majda2012_table(10, 5, ribs=ribs) if ribbed else majda2012_table()
    a, b = tm.condense(method="banded"), tm.condense(method="dense")
    for name in _FIELDS:
        assert _rel(getattr(a, name), getattr(b, name)) < 1e-10, name


def test_banded_blocks_across_the_shorter_side():
    """A mesh wider than long is blocked along Y (blocks = grid lines y = const)."""
    mesh = table_mesh(0.4, 0.9, 4, 9, lines_y=[-0.07, -0.03, 0.03, 0.07])
    plate = PlateSection(0.04)
    patches = [RigidPatch(0.0, y, 0.1, 0.03) for y in (-0.25, 0.25)]
    lay = block_layout(len(mesh.xs), len(mesh.ys), np.full(mesh.n_nodes, -1), 2)
    assert (lay.n_blocks, lay.block_size) == (len(mesh.ys), 6 * len(mesh.xs))
    pts = [(0.1, 0.05), (-0.13, -0.31)]
    a = condense(mesh, plate, patches, pts, method="banded")
    b = condense(mesh, plate, patches, pts, method="dense")
    for name in _FIELDS:
        assert _rel(getattr(a, name), getattr(b, name)) < 1e-10, name


def test_block_tridiagonal_solve_against_numpy():
    """banded.cholesky / cho_solve / matvec on a random SPD block-tridiagonal matrix."""
    rng = np.random.default_rng(3)
    nb, s, k = 5, 4, 3
    M = rng.normal(size=(nb * s, nb * s))
    band = np.abs(np.subtract.outer(np.arange(nb * s) // s, np.arange(nb * s) // s)) <= 1
    K = M @ M.T * band + nb * s * np.eye(nb * s)  # SPD (diagonally dominant), block band
    D = np.stack([K[i * s : (i + 1) * s, i * s : (i + 1) * s] for i in range(nb)])
    C = np.stack([K[(i + 1) * s : (i + 2) * s, i * s : (i + 1) * s] for i in range(nb - 1)])
    B = rng.normal(size=(nb, s, k))
    X = banded.cho_solve(banded.cholesky(jnp.asarray(D), jnp.asarray(C)), jnp.asarray(B))
    X_ref = np.linalg.solve(K, B.reshape(-1, k)).reshape(nb, s, k)
    assert _rel(X, X_ref) < 1e-12
    assert _rel(banded.matvec(jnp.asarray(D), jnp.asarray(C), X), B) < 1e-12
    assert _rel(banded.spd_solve(jnp.asarray(D), jnp.asarray(C), jnp.asarray(B)), X_ref) < 1e-12


def test_invalid_input():
    with pytest.raises(ValueError, match="thickness"):
        PlateSection(thickness=-0.01)
    with pytest.raises(ValueError, match="nx"):
        table_mesh(1.0, 0.5, 0, 4)
    with pytest.raises(ValueError, match="E"):
        Material(E=0.0, nu=0.3, rho=1.0)
    with pytest.raises(ValueError, match="nu"):
        Material(E=1.0, nu=0.5, rho=1.0)
    mesh = table_mesh(1.0, 0.5, 10, 5)
    plate = PlateSection(0.05)
    with pytest.raises(ValueError, match="outside the table"):
        condense(mesh, plate, [RigidPatch(0.49, 0.0, 0.03, 0.03)])
    with pytest.raises(ValueError, match="no node"):
        condense(mesh, plate, [RigidPatch(0.02, 0.02, 0.01, 0.01)])
    with pytest.raises(ValueError, match="overlaps"):
        condense(mesh, plate, [RigidPatch(0.0, 0.0, 0.1, 0.1), RigidPatch(0.1, 0.0, 0.1, 0.1)])
    with pytest.raises(ValueError, match="outside the table"):
        condense(mesh, plate, [RigidPatch(0.0, 0.0, 0.1, 0.1)], [(0.7, 0.0)])
    with pytest.raises(ValueError, match="method"):
        condense(mesh, plate, [RigidPatch(0.0, 0.0, 0.1, 0.1)], method="sparse")
    with pytest.raises(ValueError, match="half_x"):
        RigidPatch(0.0, 0.0, 0.0, 0.1)
