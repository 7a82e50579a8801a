"""Timoshenko beam element and ribbed plate strip against closed-form beam theory."""

import jax.numpy as jnp
import numpy as np
import pytest

from diffguide.fe.assemble import PlateSection, assemble, element_arrays_xp, solve_fixed
from diffguide.fe.beam import beam_stiffness, rect_section
from diffguide.fe.materials import STEEL, Material
from diffguide.fe.mesh import Rib, table_mesh

E, NU = 210e9, 0.3
G = E / (2 * (1 + NU))
KAPPA = 5.0 / 6.0


def _cantilever(direction, n_el, offset=None, width=0.03, depth=0.05, length=1.3):
    """Global K of a straight cantilever of n_el elements along ``direction`` (unit)."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    xyz = np.outer(np.linspace(0, length, n_el + 1), d) + np.array([0.1, -0.2, 0.3])
    s = rect_section(width, depth)
    K = np.zeros((6 * (n_el + 1),) * 2)
    for e in range(n_el):
        Ke = beam_stiffness(
            jnp.asarray(xyz[e : e + 2]), E, G, s["A"], s["Iy"], s["Iz"], s["J"], KAPPA,
            None if offset is None else jnp.asarray(offset),
        )
        K[6 * e : 6 * e + 12, 6 * e : 6 * e + 12] += np.asarray(Ke)
    return K, {k: float(v) for k, v in s.items()}


def _tip(K, load):
    n = K.shape[0]
    f = np.zeros(n)
    f[-6:] = load
    u = np.zeros(n)
    u[6:] = np.linalg.solve(K[6:, 6:], f[6:])
    return u[-6:]


@pytest.mark.parametrize("n_el", [1, 4])
def test_cantilever_tip_deflection_timoshenko(n_el):
    L, P = 1.3, 1234.0
    K, s = _cantilever([1, 0, 0], n_el, length=L)
    # vertical (about e2 = Y, I = w h³/12) and lateral (about e3 = Z, I = h w³/12)
    uz = _tip(K, [0, 0, P, 0, 0, 0])[2]
    uy = _tip(K, [0, P, 0, 0, 0, 0])[1]
    ref_z = P * L**3 / (3 * E * s["Iy"]) + P * L / (KAPPA * G * s["A"])
    ref_y = P * L**3 / (3 * E * s["Iz"]) + P * L / (KAPPA * G * s["A"])
    assert uz == pytest.approx(ref_z, rel=1e-8)
    assert uy == pytest.approx(ref_y, rel=1e-8)
    # axial P L / E A and torsion T L / G J
    assert _tip(K, [P, 0, 0, 0, 0, 0])[0] == pytest.approx(P * L / (E * s["A"]), rel=1e-8)
    assert _tip(K, [0, 0, 0, P, 0, 0])[3] == pytest.approx(P * L / (G * s["J"]), rel=1e-8)
    # slope at the tip of a cantilever under a tip moment: M L / E I
    assert _tip(K, [0, 0, 0, 0, P, 0])[4] == pytest.approx(P * L / (E * s["Iy"]), rel=1e-8)


def test_cantilever_rotated_in_space():
    """A beam along an arbitrary direction: deflection along its local e3 as for a beam on X."""
    d = np.array([0.3, -0.5, 0.81])
    d /= np.linalg.norm(d)
    L, P = 1.3, 500.0
    K, s = _cantilever(d, 3, length=L)
    e2 = np.cross([0, 0, 1], d)
    e2 /= np.linalg.norm(e2)
    e3 = np.cross(d, e2)
    u = _tip(K, np.concatenate([P * e3, np.zeros(3)]))
    ref = P * L**3 / (3 * E * s["Iy"]) + P * L / (KAPPA * G * s["A"])
    assert u[:3] @ e3 == pytest.approx(ref, rel=1e-8)
    assert np.linalg.norm(u[:3] - (u[:3] @ e3) * e3) < 1e-10 * ref


def test_offset_beam_axial_load_bends():
    """Axial tip force P at the nodes, beam axis a distance e below them (eccentric beam).

    On the axis the force comes with the moment M_y = (node - axis) × F = e P: tip rotation
    M L / E I, tip deflection -M L² / 2 E I, and the node (e above the axis) moves axially by
    P L / E A + e · M L / E I.
    """
    L, P, e = 1.3, 1000.0, 0.04
    K, s = _cantilever([1, 0, 0], 4, offset=[0, 0, -e], length=L)
    u = _tip(K, [P, 0, 0, 0, 0, 0])
    EI = E * s["Iy"]
    # the force P at the node acts on the axis with the moment (node - axis) × F = (0,0,e)×(P,0,0)
    My = e * P
    assert u[4] == pytest.approx(My * L / EI, rel=1e-8)
    assert u[2] == pytest.approx(-My * L**2 / (2 * EI), rel=1e-8)
    assert u[0] == pytest.approx(P * L / (E * s["A"]) + e * My * L / EI, rel=1e-8)


def test_beam_rigid_body_modes_with_offset():
    xyz = jnp.array([[0.1, 0.2, 0.0], [0.5, 0.4, 0.1]])
    s = rect_section(0.02, 0.07)
    K = np.asarray(beam_stiffness(xyz, E, G, s["A"], s["Iy"], s["Iz"], s["J"], KAPPA,
                                  jnp.array([0.01, -0.02, -0.05])))
    ev = np.linalg.eigvalsh(K)
    assert np.sum(np.abs(ev) < 1e-9 * ev.max()) == 6
    assert ev.min() > -1e-9 * ev.max()


def test_plate_strip_with_offset_rib_matches_t_section():
    """Cantilevered plate strip (b × t) with a rib (w × h) under it vs the T-section beam.

    δ = P L³ / 3 E I_T + P L / κ G A_web, I_T about the composite section's neutral axis.
    """
    L, b, t, w, h, P = 2.0, 0.2, 0.02, 0.04, 0.12, 1000.0
    mat = Material(E=E, nu=NU, rho=0.0)
    mesh = table_mesh(L, b, 40, 4, origin=(0.0, -b / 2), ribs=[Rib("x", 0.0, w, h)])
    K, f = assemble(mesh, PlateSection(t, mat))
    tip = mesh.node_at(L, 0.0)
    f = np.zeros(mesh.n_dof)
    f[6 * tip + 2] = -P
    root = np.flatnonzero(np.isclose(mesh.nodes[:, 0], 0.0))
    fixed = (6 * root[:, None] + np.arange(6)).ravel()
    u = np.asarray(solve_fixed(K, jnp.asarray(f), fixed)).reshape(-1, 6)
    A1, A2, z2 = b * t, w * h, -(t + h) / 2
    zc = A2 * z2 / (A1 + A2)
    I = b * t**3 / 12 + A1 * zc**2 + w * h**3 / 12 + A2 * (z2 - zc) ** 2
    ref = P * L**3 / (3 * E * I) + P * L / (KAPPA * G * A2)
    assert -u[tip, 2] == pytest.approx(ref, rel=0.02)


def test_steel_registry():
    assert STEEL.E == 210e9 and STEEL.nu == 0.3 and STEEL.rho == 7850.0


def _prandtl_torsion(mask, h):
    """Saint-Venant torsion constant of the cells ``mask`` (square cells of side ``h``): Prandtl's
    ``∇²φ = -2``, ``φ = 0`` outside, five-point differences, ``J = 2 Σ φ h²``."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spl

    idx = -np.ones(mask.shape, int)
    idx[mask] = np.arange(mask.sum())
    i, k = np.nonzero(mask)
    n = len(i)
    rows, cols, vals = [np.arange(n)], [np.arange(n)], [np.full(n, 4.0)]
    for di, dk in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        i2, k2 = i + di, k + dk
        ok = (i2 >= 0) & (i2 < mask.shape[0]) & (k2 >= 0) & (k2 < mask.shape[1])
        ok[ok] = mask[i2[ok], k2[ok]]
        rows.append(np.flatnonzero(ok))
        cols.append(idx[i2[ok], k2[ok]])
        vals.append(-np.ones(ok.sum()))
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), (n, n))
    return 2.0 * h * h * spl.spsolve(A.tocsc(), np.full(n, 2.0 * h * h)).sum()


def _rib_share(w, d, t, cells):
    """J(plate + rib) - J(plate) of a plate 8 t wider than the rib, Richardson-extrapolated
    from grids of w / cells and w / (2 cells) (the error is O(h))."""
    out = []
    for m in (cells, 2 * cells):
        h = w / m
        b = w + 8 * t
        z = (np.arange(round((t + d) / h)) + 0.5) * h  # up from the rib's bottom
        x = (np.arange(round(b / h)) + 0.5) * h - b / 2
        Z, X = np.meshgrid(z, x, indexing="ij")
        plate = Z >= d
        out.append(_prandtl_torsion(plate | (np.abs(X) < w / 2), h) - _prandtl_torsion(plate, h))
    return 2 * out[1] - out[0]


@pytest.mark.parametrize("w, d, t, rel", [
    (0.02, 0.04, 0.03, 0.005),  # the superelement example's rib
    (0.02, 0.06, 0.035, 0.005),  # t/w = 1.75, d = 3 w: between the fit's points
    (0.02, 0.02, 0.03, 0.025),  # a square rib: 2 % documented
    (0.02, 0.01, 0.02, 0.05),  # flatter than square, d = w / 2, t = w: 3 % documented
])
def test_bonded_rib_torsion_matches_prandtl(w, d, t, rel):
    """The torsion constant a rib adds to its plate (closed form with a fitted junction term)
    against a finite-difference solution of Prandtl's equation for the T-section; and bonded, the
    rib is stiffer than the free rectangle."""
    from diffguide.fe.beam import bonded_rib_torsion

    ref = _rib_share(w, d, t, 20)
    got = float(bonded_rib_torsion(w, d, t))
    assert got == pytest.approx(ref, rel=rel)
    assert got > 1.5 * float(rect_section(w, d)["J"])


def test_bonded_rib_torsion_is_smooth_and_vanishes_with_the_rib():
    """ΔJ and its derivative by the depth are continuous where the flat-rib branch meets the
    formula (d = w, central differences on each side), ΔJ grows with d and is 0 at d = 0."""
    import jax

    from diffguide.fe.beam import bonded_rib_torsion

    w, t, h = 0.02, 0.03, 1e-7
    dJ = jax.grad(lambda d: bonded_rib_torsion(w, d, t))
    for d in (w - 2 * h, w + 2 * h):
        fd = (bonded_rib_torsion(w, d + h, t) - bonded_rib_torsion(w, d - h, t)) / (2 * h)
        assert float(dJ(d)) == pytest.approx(float(fd), rel=1e-5)
    assert float(dJ(w - 1e-9)) == pytest.approx(float(dJ(w + 1e-9)), rel=1e-6)
    d = np.linspace(0.0, 0.08, 81)
    J = np.asarray(bonded_rib_torsion(w, d, t))
    assert J[0] == pytest.approx(0.0, abs=1e-12 * J.max()) and np.all(np.diff(J) > 0)


def test_prandtl_solver_gives_the_rectangle():
    """The finite-difference check itself (to 0.3 %) on a 2:1 rectangle against the series of
    Timoshenko & Goodier (Theory of Elasticity, §109):
    ``J = a b³/3 (1 - 192 b / (π⁵ a) Σ tanh(nπa/2b) / n⁵)``, n odd."""
    a, b = 0.04, 0.02
    res = []
    for m in (20, 40):
        h = b / m
        res.append(_prandtl_torsion(np.ones((round(a / h), m), bool), h))
    n = np.arange(1, 40, 2)
    series = np.sum(np.tanh(n * np.pi * a / (2 * b)) / n**5)
    ref = a * b**3 / 3 * (1 - 192 * b / (np.pi**5 * a) * series)
    assert 2 * res[1] - res[0] == pytest.approx(ref, rel=3e-3)  # measured 0.24 % low


def test_twisted_ribbed_strip_matches_t_section():
    """A plate strip (b × t) cantilevered and twisted by a torque T at its tip, with and without a
    rib (w × d) under its centre line: the twist rate k over its middle gives G J = T / k, and the
    rib adds to J what Saint-Venant torsion of the T-section adds to the plate's (the
    finite-difference Prandtl solution, :func:`_rib_share`), 1.9 × the free rectangle's J."""
    L, b, t, w, d, T = 2.0, 0.2, 0.02, 0.02, 0.04, 100.0
    mat = Material(E=E, nu=NU, rho=0.0)

    def torsion_constant(ribs):
        mesh = table_mesh(L, b, 40, 8, origin=(0.0, -b / 2), ribs=ribs)
        K = np.zeros((mesh.n_dof, mesh.n_dof))  # NumPy element arrays: no compilation
        for ea in element_arrays_xp(mesh, PlateSection(t, mat), None, 0.0, np.zeros(3), np):
            dofs = (6 * ea.conn[:, :, None] + np.arange(6)).reshape(len(ea.conn), -1)
            np.add.at(K, (dofs[:, :, None], dofs[:, None, :]), ea.K)
        tip = np.flatnonzero(np.isclose(mesh.nodes[:, 0], L))
        f = np.zeros(mesh.n_dof)
        f[6 * tip + 3] = T / len(tip)
        root = np.flatnonzero(np.isclose(mesh.nodes[:, 0], 0.0))
        free = np.setdiff1d(np.arange(mesh.n_dof), (6 * root[:, None] + np.arange(6)).ravel())
        u = np.zeros(mesh.n_dof)
        u[free] = np.linalg.solve(K[np.ix_(free, free)], f[free])
        u = u.reshape(-1, 6)
        # the section's rotation from the edges' deflection, at 0.4 L and 0.8 L
        rot = [(u[mesh.node_at(x, b / 2), 2] - u[mesh.node_at(x, -b / 2), 2]) / b
               for x in (0.4 * L, 0.8 * L)]
        return T / (G * (rot[1] - rot[0]) / (0.4 * L))

    added = torsion_constant([Rib("x", 0.0, w, d)]) - torsion_constant([])
    assert added == pytest.approx(_rib_share(w, d, t, 20), rel=0.01)
    assert added > 1.8 * float(rect_section(w, d)["J"])
