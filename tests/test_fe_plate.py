"""MITC4 flat shell against plate theory (Timoshenko & Woinowsky-Krieger, Navier series,
scikit-fem Morley elements) and patch tests.

Square plates of side a, ν = 0.3, centre deflection in units of q a⁴ / D or P a² / D. The
convergence meshes are quarter models (symmetry: on x = a/2, ry = 0; on y = a/2, rx = 0) with
N × N elements, i.e. a full 2N × 2N mesh. Kirchhoff references use a/h = 1000 (the Mindlin
correction there is ~6e-6, far below the discretisation error). "Simply supported" is the hard
support w = 0 and tangential rotation = 0 (the Navier solution's).
"""

import jax.numpy as jnp
import numpy as np
import pytest

from diffguide.fe.assemble import PlateSection, assemble, solve_fixed
from diffguide.fe.materials import Material
from diffguide.fe.mesh import TableMesh, table_mesh
from diffguide.fe.shell import shell_stiffness

E, NU = 1e9, 0.3
KAPPA = 5.0 / 6.0


def navier_ss(load: str, a_over_h: float = np.inf, terms: int = 2001) -> float:
    """Centre deflection of a simply supported square plate (Navier double sine series).

    Uniform load: ``w = 16 q a⁴ / (π⁶ D) Σ s_m s_n / (m n (m² + n²)²)``; central point load:
    ``w = 4 P a² / (π⁴ D) Σ 1 / (m² + n²)²`` (m, n odd). Mindlin (κ = 5/6): each term times
    ``1 + π² (m² + n²) (h/a)² / (6 κ (1 - ν))`` (shear deflection ``M / κ G h``).
    """
    k = np.arange(1, terms + 1, 2, dtype=float)
    m, n = np.meshgrid(k, k, indexing="ij")
    r2 = m**2 + n**2
    shear = 1.0 + np.pi**2 * r2 / a_over_h**2 / (6 * KAPPA * (1 - NU))
    if load == "q":
        s = (-1.0) ** ((m - 1) / 2 + (n - 1) / 2)
        return float(16 / np.pi**6 * np.sum(s * shear / (m * n * r2**2)))
    return float(4 / np.pi**4 * np.sum(1.0 / r2**2))


# Clamped square plate, Kirchhoff: Taylor & Govindjee, Commun. Numer. Meth. Engng 20 (2004)
# 757-765 (Timoshenko & Woinowsky-Krieger give 0.00126 and 0.00560); cross-checked below with
# scikit-fem's Morley element.
CLAMPED = {"q": 0.00126532, "p": 0.0056120}
TABLE = {("ss", "q"): 0.00406, ("ss", "p"): 0.01160, ("cl", "q"): 0.00126, ("cl", "p"): 0.00560}


def plate_centre(n: int, a_over_h: float, bc: str, load: str, quarter: bool = True) -> float:
    """Centre deflection coefficient of the MITC4 model (unit side, E = 1 GPa)."""
    a = 1.0
    h = a / a_over_h
    D = E * h**3 / (12 * (1 - NU**2))
    side = a / 2 if quarter else a
    mesh = table_mesh(side, side, n, n, origin=(0.0, 0.0))
    plate = PlateSection(h, Material(E, NU, 0.0))
    K, f = assemble(mesh, plate, surface_load=jnp.array([0, 0, -1.0]))
    x, y = mesh.nodes[:, 0], mesh.nodes[:, 1]
    fix = np.zeros((mesh.n_nodes, 6), bool)
    fix[:, [0, 1, 5]] = True  # pure bending problem: no membrane, no drilling
    ex = np.isclose(x, 0) | (np.isclose(x, a) & (not quarter))
    ey = np.isclose(y, 0) | (np.isclose(y, a) & (not quarter))
    if bc == "ss":
        fix[ex, 2] = fix[ex, 3] = True
        fix[ey, 2] = fix[ey, 4] = True
    else:
        fix[ex | ey, 2:5] = True
    if quarter:
        fix[np.isclose(x, a / 2), 4] = True
        fix[np.isclose(y, a / 2), 3] = True
    c = mesh.node_at(a / 2, a / 2)
    if load == "p":
        f = jnp.zeros(mesh.n_dof).at[6 * c + 2].set(-(0.25 if quarter else 1.0))
    u = solve_fixed(K, f, fix.ravel())
    return float(-u[6 * c + 2] * D / a ** (4 if load == "q" else 2))


@pytest.mark.parametrize(
    "bc, load, min_rate",
    [("ss", "q", 1.8), ("ss", "p", 1.4), ("cl", "q", 1.8), ("cl", "p", 1.6)],
)
def test_kirchhoff_plates_converge(bc, load, min_rate):
    ref = navier_ss(load) if bc == "ss" else CLAMPED[load]
    ns = np.array([4, 8, 16])
    w = np.array([plate_centre(n, 1000.0, bc, load) for n in ns])
    err = np.abs(w / ref - 1)
    rate = np.polyfit(np.log(1.0 / ns), np.log(err), 1)[0]
    assert rate > min_rate, (w, err, rate)
    assert err[-1] < 0.01
    assert w[-1] == pytest.approx(TABLE[(bc, load)], rel=0.01)


def test_references_are_consistent():
    """Navier sums reproduce the tabulated coefficients (Timoshenko & Woinowsky-Krieger); Mindlin
    sums the tabulated a/h = 5, 10 values."""
    assert navier_ss("q") == pytest.approx(0.00406, abs=5e-6)
    assert navier_ss("p") == pytest.approx(0.01160, abs=5e-6)
    assert navier_ss("q", 5.0) == pytest.approx(0.0049043, rel=1e-4)
    assert navier_ss("q", 10.0) == pytest.approx(0.0042728, rel=1e-4)


def test_clamped_references_against_scikit_fem_morley():
    skfem = pytest.importorskip("skfem")
    from skfem.helpers import dd, ddot, eye, trace

    mesh = skfem.MeshTri.init_tensor(np.linspace(0, 1, 97), np.linspace(0, 1, 97))
    basis = skfem.Basis(mesh, skfem.ElementTriMorley())

    @skfem.BilinearForm
    def bending(u, v, _):  # D = 1
        k = dd(u)
        return ddot((1 - NU) * k + NU * eye(trace(k), 2), dd(v))

    @skfem.LinearForm
    def unit(v, _):
        return v

    K = skfem.asm(bending, basis)
    c = int(np.argmin(np.hypot(mesh.p[0] - 0.5, mesh.p[1] - 0.5)))
    fixed = basis.get_dofs().all(["u", "u_n"])
    fq = skfem.asm(unit, basis)
    fp = np.zeros(K.shape[0])
    fp[basis.nodal_dofs[0, c]] = 1.0
    for load, f in (("q", fq), ("p", fp)):
        w = skfem.solve(*skfem.condense(K, f, D=fixed))[basis.nodal_dofs[0, c]]
        assert w == pytest.approx(CLAMPED[load], rel=0.01)  # Morley error at h = 1/96: < 0.6 %


@pytest.mark.parametrize("a_over_h, ref", [(5.0, 0.0049043), (10.0, 0.0042728)])
def test_mindlin_thick_plates(a_over_h, ref):
    assert plate_centre(8, a_over_h, "ss", "q") == pytest.approx(ref, rel=0.01)


def test_no_shear_locking_thin_plate_full_mesh():
    """a/h = 1000 on a full 16 × 16 mesh (no symmetry): within 2 % of Kirchhoff."""
    w = plate_centre(16, 1000.0, "ss", "q", quarter=False)
    assert w == pytest.approx(navier_ss("q"), rel=0.02)


# --- patch tests -------------------------------------------------------------------------------

_PATCH_XY = np.array(
    [[0, 0], [0.24, 0], [0.24, 0.12], [0, 0.12],
     [0.04, 0.02], [0.18, 0.03], [0.16, 0.08], [0.08, 0.08]]
)
_PATCH_QUADS = np.array([[0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7], [4, 5, 6, 7]])


def _rotation(angles):
    ax, ay, az = angles
    rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
    return rz @ ry @ rx


def _patch_mesh(Q):
    nodes = np.c_[_PATCH_XY, np.zeros(8)] @ Q.T + np.array([0.3, -0.1, 0.2])
    empty = np.zeros((0, 2), np.int64)
    return TableMesh(
        xs=np.array([0.0]), ys=np.array([0.0]), nodes=nodes, quads=_PATCH_QUADS, beams=empty,
        beam_rib=np.zeros(0, np.int64),
    )


@pytest.mark.parametrize("angles", [(0, 0, 0), (0.4, -0.7, 1.1)])
def test_membrane_patch_test(angles):
    """Linear in-plane field (with rigid rotation) on the MacNeal–Harder patch: exact.

    u = 1e-3 (2x + 0.5y), v = 1e-3 (-x + 1.5y) in the plate plane, prescribed on the 4 outer
    nodes; the interior nodes must reproduce it and rz the rotation ω = (v,x - u,y)/2.
    """
    Q = _rotation(angles)
    mesh = _patch_mesh(Q)
    K, _ = assemble(mesh, PlateSection(0.01, Material(210e9, 0.3, 0.0)))
    x, y = _PATCH_XY.T
    ul = 1e-3 * np.c_[2 * x + 0.5 * y, -x + 1.5 * y, np.zeros(8)]
    omega = 0.5 * 1e-3 * (-1.0 - 0.5)
    exact = np.c_[ul @ Q.T, np.tile(Q @ [0, 0, omega], (8, 1))]
    # prescribe: outer-node translations; every node's out-of-plane DOF (w, in-plane rotations)
    local_fixed = []
    for k in range(8):
        if k < 4:
            local_fixed += [(k, "t", d) for d in range(3)]
        else:
            local_fixed += [(k, "t", 2)]
        local_fixed += [(k, "r", 0), (k, "r", 1)]
    # work in a frame where the plane is (e1, e2): transform K to local node triads
    T = np.kron(np.eye(16), Q.T)  # global -> local
    Kl = T @ np.asarray(K) @ T.T
    exact_l = (exact.reshape(-1, 3) @ Q).reshape(8, 6)
    fixed = [6 * k + (0 if kind == "t" else 3) + d for k, kind, d in local_fixed]
    ul_sol = np.asarray(solve_fixed(jnp.asarray(Kl), jnp.zeros(48), np.array(fixed),
                                    jnp.asarray(exact_l.ravel()[fixed])))
    # 1e-11: rounding only (the weak drilling penalty amplifies it; the rotated patch gave
    # 0.9e-12 and 2.2e-12 with element matrices that agree to 5e-16)
    assert np.max(np.abs(ul_sol - exact_l.ravel())) < 1e-11 * np.max(np.abs(exact_l))


def test_bending_patch_test():
    """Constant curvatures w = (κx x² + κy y² + κxy xy)/2 with θ = (w,y, -w,x): exact (MITC4)."""
    mesh = _patch_mesh(np.eye(3))
    K, _ = assemble(mesh, PlateSection(0.01, Material(210e9, 0.3, 0.0)))
    x, y = mesh.nodes[:, 0], mesh.nodes[:, 1]
    kx, ky, kxy = 2e-3, -1e-3, 1.5e-3
    w = 0.5 * (kx * x**2 + ky * y**2 + kxy * x * y)
    wx, wy = kx * x + 0.5 * kxy * y, ky * y + 0.5 * kxy * x
    exact = np.c_[np.zeros((8, 2)), w, wy, -wx, np.zeros(8)]
    fixed = [6 * k + d for k in range(8) for d in ((2, 3, 4) if k < 4 else ())]
    fixed += [6 * k + d for k in range(8) for d in (0, 1, 5)]
    u = solve_fixed(K, jnp.zeros(48), np.array(fixed), jnp.asarray(exact.ravel()[fixed]))
    u = np.asarray(u)
    assert np.max(np.abs(u - exact.ravel())) < 1e-12 * np.max(np.abs(exact))


def test_shell_rigid_body_modes():
    xyz = jnp.asarray(np.c_[_PATCH_XY[[0, 1, 5, 4]], np.zeros(4)] @ _rotation((0.3, 0.2, -0.5)).T)
    ev = np.linalg.eigvalsh(np.asarray(shell_stiffness(xyz, 0.02, 110e9, 0.26)))
    assert np.sum(np.abs(ev) < 1e-10 * ev.max()) == 6
    assert ev.min() > -1e-10 * ev.max()


def test_drilling_penalty_does_not_change_results():
    """In-plane cantilever (a deep beam along x, shear load at the tip) and a sagging plate:
    10× the drilling penalty changes the deflections by < 0.1 %."""
    out = []
    for drill in (1e-3, 1e-2):
        mesh = table_mesh(1.0, 0.25, 16, 4, origin=(0.0, 0.0))
        K, f = assemble(mesh, PlateSection(0.02, Material(110e9, 0.26, 7200.0), drill=drill),
                        gravity=9.81)
        root = np.flatnonzero(np.isclose(mesh.nodes[:, 0], 0.0))
        fixed = (6 * root[:, None] + np.arange(6)).ravel()
        tip = mesh.node_at(1.0, 0.125)
        fy = jnp.zeros(mesh.n_dof).at[6 * tip + 1].set(1000.0)
        out.append([solve_fixed(K, fy, fixed)[6 * tip + 1], solve_fixed(K, f, fixed)[6 * tip + 2]])
    out = np.array(out)
    assert np.all(np.abs(out[1] / out[0] - 1) < 1e-3), out
