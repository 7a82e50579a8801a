"""Readers of reduced (superelement) matrices against hand-written files that follow each
format's documented syntax, with closed-form contents (a two-node spring), and the exact
condensation against a closed form (a clamped-clamped Euler-Bernoulli beam)."""

import numpy as np
import pytest

from diffguide.fe.superelement import (
    ReducedMatrix,
    RetainedPoint,
    check_rigid_modes,
    table_from_reduced,
    weight_at_interfaces,
    with_rotation_nodes,
)
from diffguide.io.superelement import (
    SuperelementFileError,
    read_ccx_reactions,
    read_cload,
    read_dmig,
    read_inp_nodes,
    read_user_element_matrix,
    reduced_from_reactions,
)

K_SPRING = 2.5e8  # N/m


def spring_3d(n):
    """A two-node axial spring along unit vector n: K = k [[nnᵀ, -nnᵀ], [-nnᵀ, nnᵀ]]."""
    P = K_SPRING * np.outer(n, n)
    return np.block([[P, -P], [-P, P]])


def test_ccx_user_element_one_dof_per_position(tmp_path):
    # CalculiX's layout: each position one DOF; a spring along X between nodes 7 and 9
    text = """**
** GENERATION OF SUBSTRUCTURE
*USER ELEMENT,NODES=         2,LINEAR
** ELEMENT NODES
**         7,         9,
         1
         2,         1
*MATRIX,TYPE=STIFFNESS
 0.2500000000000E+09,
-0.2500000000000E+09, 0.2500000000000E+09,
"""
    p = tmp_path / "s.mtx"
    p.write_text(text)
    rm = read_user_element_matrix(p)
    assert rm.dofs == ((7, 1), (9, 1))
    np.testing.assert_array_equal(rm.K, K_SPRING * np.array([[1, -1], [-1, 1]]))


def test_abaqus_user_element_nodes_with_dof_lists(tmp_path):
    # Abaqus's layout: each node once with its DOF list; values wrapped 4 to a line
    n = np.array([1.0, 2.0, 2.0]) / 3.0
    K = spring_3d(n)
    vals = K[np.tril_indices(6)]
    lines = [", ".join(f"{v:.16e}" for v in vals[i:i + 4]) + "," for i in range(0, len(vals), 4)]
    text = ("*USER ELEMENT, NODES=2, LINEAR\n** ELEMENT NODES\n** 3, 4\n1, 2, 3\n"
            "*MATRIX, TYPE=STIFFNESS\n" + "\n".join(lines) + "\n")
    p = tmp_path / "s.mtx"
    p.write_text(text)
    rm = read_user_element_matrix(p)
    assert rm.dofs == ((3, 1), (3, 2), (3, 3), (4, 1), (4, 2), (4, 3))
    np.testing.assert_allclose(rm.K, K, rtol=1e-15)
    # in mm: N/mm -> N/m is x 1000
    np.testing.assert_allclose(read_user_element_matrix(p, length_unit=1e-3).K, 1e3 * K)


def test_user_element_wrong_count_names_line(tmp_path):
    p = tmp_path / "bad.mtx"
    p.write_text("*USER ELEMENT,NODES=2,LINEAR\n** ELEMENT NODES\n** 1, 2\n1\n"
                 "*MATRIX,TYPE=STIFFNESS\n1.0,\n-1.0,\n")
    with pytest.raises(SuperelementFileError, match=r"bad.mtx:5: .*3 values, found 2"):
        read_user_element_matrix(p)
    p.write_text("*USER ELEMENT,NODES=2,LINEAR\n** ELEMENT NODES\n** 1, 2\n1\n"
                 "*MATRIX,TYPE=STIFFNESS\n1.0,\n-1.0, 1.x0\n")
    with pytest.raises(SuperelementFileError, match=r"bad.mtx:7: field matrix value: '1.x0'"):
        read_user_element_matrix(p)


def _small(*fields):
    return "".join(f"{f:<8}" for f in fields)


def _dmig_small_cards(name, K, dofs, lower=True):
    """Small-field DMIG text (header + one column entry per column), documented layout."""
    out = [_small("DMIG", name, "0", "6", "2", "", "", "", "")]
    n = len(dofs)
    for j in range(n):
        rows = [i for i in range(n) if (i >= j if lower else i <= j) and K[i, j] != 0]
        if not rows:
            continue
        g, c = dofs[j]
        entries = [(dofs[i][0], dofs[i][1], f"{K[i, j]:.2E}".replace("E", "")) for i in rows]
        first = entries[0]
        out.append(_small("DMIG", name, g, c, "", first[0], first[1], first[2], ""))
        rest = entries[1:]
        for k in range(0, len(rest), 2):
            chunk = rest[k:k + 2]
            fields = [""]
            for e in chunk:
                fields += [e[0], e[1], e[2], ""]
            out.append(_small(*fields))
    return "\n".join(out) + "\n"


@pytest.mark.parametrize("lower", [True, False])
def test_dmig_small_field_spring(tmp_path, lower):
    n = np.array([0.0, 0.6, 0.8])
    K = spring_3d(n)
    dofs = [(11, 1), (11, 2), (11, 3), (12, 1), (12, 2), (12, 3)]
    p = tmp_path / "k.pch"
    p.write_text("$ a punch file\n" + _dmig_small_cards("KAAX", K, dofs, lower))
    rm = read_dmig(p)
    assert rm.dofs == tuple(d for d, row in zip(dofs, K) if np.any(row))  # ux rows are zero
    keep = [i for i in range(6) if np.any(K[i])]
    np.testing.assert_allclose(rm.K, K[np.ix_(keep, keep)], rtol=1e-12)  # exact in 3 digits


def test_dmig_large_and_free_field(tmp_path):
    k = K_SPRING
    large = (
        "DMIG*   KAAX                           0               6               2\n"
        "*                      0\n"
        "DMIG*   KAAX                         101               3\n"
        f"*                    101               3{k:16.9E}\n"
        "*                    102               3" + f"{-k:16.9E}".replace("E", "D") + "\n"
        "DMIG*   KAAX                         102               3\n"
        f"*                    102               3{k:16.9E}\n"
    )
    p = tmp_path / "large.pch"
    p.write_text(large)
    rm = read_dmig(p, "kaax")
    assert rm.dofs == ((101, 3), (102, 3))
    np.testing.assert_allclose(rm.K, k * np.array([[1, -1], [-1, 1]]), rtol=1e-9)
    free = (f"DMIG,KAAX,0,6,1,,,,\nDMIG,KAAX,101,3,,101,3,{k},\n,102,3,{-k},\n"
            f"DMIG,KAAX,102,3,,102,3,{k}\n")
    p = tmp_path / "free.bdf"
    p.write_text(free)
    np.testing.assert_allclose(read_dmig(p).K, rm.K, rtol=1e-9)


def test_dmig_errors_name_line_and_field(tmp_path):
    p = tmp_path / "c.pch"
    p.write_text(_small("DMIG", "K", "0", "6", "3") + "\n")
    with pytest.raises(SuperelementFileError, match=r"c.pch:1: field TIN \(5\): type 3"):
        read_dmig(p)
    p.write_text(_small("DMIG", "K", "0", "6", "2") + "\n"
                 + _small("DMIG", "K", "1", "7", "", "1", "1", "1.0") + "\n")
    with pytest.raises(SuperelementFileError, match=r"c.pch:2: field CJ \(4\): 7 .*0..6"):
        read_dmig(p)
    p.write_text(_small("DMIG", "K", "0", "6", "2") + "\n"
                 + _small("DMIG", "K", "1", "1", "", "2", "1", "1.0") + "\n"
                 + _small("DMIG", "K", "2", "1", "", "1", "1", "2.0") + "\n")
    with pytest.raises(SuperelementFileError, match=r"c.pch:3: symmetric matrix K"):
        read_dmig(p)
    with pytest.raises(SuperelementFileError, match="no DMIG header for matrix 'M'"):
        read_dmig(p, "M")


def test_ccx_reactions_assemble_columns(tmp_path):
    # two unit-displacement steps of the spring (nodes 1, 2 along X) + a gravity step
    k = K_SPRING
    dat = ""
    for t, (r1, r2) in enumerate([(k, -k), (-k, k), (5.0, 7.0)], start=1):
        dat += (f"\n forces (fx,fy,fz) for set RETAINED and time  {t:.7E}\n\n"
                f"         1  {r1:.6E}  0.000000E+00  0.000000E+00\n"
                f"         2  {r2:.6E}  0.000000E+00  0.000000E+00\n")
    p = tmp_path / "r.dat"
    p.write_text(dat)
    assert len(read_ccx_reactions(p)) == 3
    loads = tmp_path / "held.inp"
    loads.write_text("** held\n*CLOAD\n2, 1, -1.5\n")
    rm = reduced_from_reactions(p, [(1, 1), (2, 1)], held_loads=read_cload(loads))
    np.testing.assert_allclose(rm.K, k * np.array([[1, -1], [-1, 1]]), rtol=1e-6)
    np.testing.assert_allclose(rm.f, [-5.0, -8.5])
    with pytest.raises(SuperelementFileError, match="3 RF steps, expected 4"):
        reduced_from_reactions(p, [(1, 1), (2, 1), (3, 1)])


def test_inp_nodes(tmp_path):
    p = tmp_path / "n.inp"
    p.write_text("** nodes\n*NODE, NSET=A\n1, 0., 1., 2.\n2, 3.5, -1, 0\n*ELEMENT, TYPE=C3D8\n"
                 "1, 1, 2, 3, 4, 5, 6, 7, 8\n")
    nodes = read_inp_nodes(p, length_unit=1e-3)
    np.testing.assert_allclose(nodes[2], [3.5e-3, -1e-3, 0.0])
    assert set(nodes) == {1, 2}


# ---------------------------------------------------------------- condensation, closed form

E, I, A, G, J, L = 200e9, 2e-6, 3e-3, 80e9, 4e-6, 1.0  # a beam along X, SI


def beam_element(le):
    """12 x 12 Euler-Bernoulli 3D beam along X (closed form; Iy = Iz = I)."""
    K = np.zeros((12, 12))
    a, t = E * A / le, G * J / le
    for i, j, v in [(0, 0, a), (0, 6, -a), (6, 6, a), (3, 3, t), (3, 9, -t), (9, 9, t)]:
        K[i, j] = K[j, i] = v
    b = E * I / le**3
    # bending in XZ (uz = 2, ry = 4) and in XY (uy = 1, rz = 5): sign of the rotation differs
    for w, r, s in [(2, 4, -1.0), (1, 5, 1.0)]:
        idx = [w, r, w + 6, r + 6]
        k = b * np.array([[12, 6 * le, -12, 6 * le], [6 * le, 4 * le**2, -6 * le, 2 * le**2],
                          [-12, -6 * le, 12, -6 * le], [6 * le, 2 * le**2, -6 * le, 4 * le**2]])
        S = np.diag([1.0, s, 1.0, s])
        K[np.ix_(idx, idx)] += S @ k @ S
    return K


def two_element_beam(q):
    """Nodes 1 (x=0), 2 (x=L/2), 3 (x=L); uniform load q (N/m) along -Z, consistent loads."""
    le = L / 2
    K = np.zeros((18, 18))
    f = np.zeros(18)
    fe = np.zeros(12)
    fe[[2, 8]] = -q * le / 2
    fe[4], fe[10] = q * le**2 / 12, -q * le**2 / 12  # ry = -dw/dx: moments of the load
    for e in range(2):
        K[6 * e:6 * e + 12, 6 * e:6 * e + 12] += beam_element(le)
        f[6 * e:6 * e + 12] += fe
    dofs = tuple((n, d) for n in (1, 2, 3) for d in range(1, 7))
    coords = {1: (0.0, 0.0, 0.0), 2: (L / 2, 0.0, 0.0), 3: (L, 0.0, 0.0)}
    return ReducedMatrix(K=K, dofs=dofs, f=f, source="beam"), coords


def test_condensed_beam_is_one_element_and_midspan_sag():
    q = 1e3
    rm, coords = two_element_beam(q)
    assert check_rigid_modes(rm, coords) < 1e-12
    table = table_from_reduced(rm, coords, [1, 3], [RetainedPoint(name="mid", node=2)])
    np.testing.assert_allclose(table.K, beam_element(L), rtol=1e-10, atol=1e-6)
    # both ends held: the mid-span sag of a clamped-clamped beam, q L^4 / (384 E I)
    np.testing.assert_allclose(table.r0[2], -q * L**4 / (384 * E * I), rtol=1e-10)
    # the ends' reactions: f = -(qL/2) at each end, moments -+ qL^2/12
    np.testing.assert_allclose(np.asarray(table.f)[[2, 8]], -q * L / 2, rtol=1e-10)
    np.testing.assert_allclose(np.asarray(table.f)[[4, 10]], [q * L**2 / 12, -q * L**2 / 12],
                               rtol=1e-10)
    # the mid node under a unit end rotation ry: Hermite cubic, w(L/2) = -L/8, slope 1/4
    R = np.asarray(table.R)
    np.testing.assert_allclose(R[2, 4], -L / 8, rtol=1e-10)
    np.testing.assert_allclose(R[4, 4], -0.25, rtol=1e-10, atol=1e-14)
    assert table.nodes.shape == (0, 3)


def test_rotation_from_neighbours_is_exact_for_rigid_motion():
    # a point and 4 neighbours on a plane, retained translations only; a spring web keeps K
    # regular: the fitted rotation of a rigid motion is that rotation
    pts = {1: (0, 0, 0.1), 2: (-0.1, 0, 0.1), 3: (0.1, 0, 0.1), 4: (0, -0.1, 0.1),
           5: (0, 0.1, 0.1)}
    dofs = tuple((n, d) for n in pts for d in (1, 2, 3))
    rm = ReducedMatrix(K=np.eye(15), dofs=dofs, f=np.zeros(15))
    from diffguide.fe.superelement import _point_rows

    S = _point_rows(rm, pts, RetainedPoint(name="P", node=1, neighbours=(2, 3, 4, 5)), [])
    theta, t0 = np.array([1e-4, -2e-4, 3e-4]), np.array([1e-6, 2e-6, -1e-6])
    u = np.concatenate([t0 + np.cross(theta, np.subtract(pts[n], pts[1])) for n in pts])
    np.testing.assert_allclose(S @ u, np.concatenate([t0, theta]), rtol=1e-12, atol=1e-18)


def test_rotation_nodes_and_missing_point():
    rm, coords = two_element_beam(0.0)
    # rename node 3's rotations as a CalculiX ROT NODE 30, then back
    dofs = tuple((30, d - 3) if (n == 3 and d > 3) else (n, d) for n, d in rm.dofs)
    rm2 = with_rotation_nodes(ReducedMatrix(K=rm.K, dofs=dofs, f=rm.f), {30: 3})
    assert rm2.dofs == rm.dofs
    with pytest.raises(KeyError, match="control point 'P9' needs node 7 DOF 1"):
        table_from_reduced(rm, coords, [1, 3], [RetainedPoint(name="P9", node=7)])
    # a matrix with a support (not free-floating) is refused
    K = rm.K.copy()
    K[2, 2] += 1e9
    with pytest.raises(ValueError, match="rigid motions"):
        check_rigid_modes(ReducedMatrix(K=K, dofs=rm.dofs, f=rm.f), coords)


def test_weight_at_interfaces_statics():
    ref = np.array([[-0.2, -0.1, 0], [0.2, -0.1, 0], [-0.2, 0.1, 0], [0.2, 0.1, 0]])
    f = weight_at_interfaces(ref, 100.0, (0.05, 0.02, 0.0), 10.0).reshape(4, 6)
    np.testing.assert_allclose(f[:, 2].sum(), -1000.0)
    np.testing.assert_allclose((f[:, 2] * ref[:, 0]).sum(), -1000.0 * 0.05)
    np.testing.assert_allclose((f[:, 2] * ref[:, 1]).sum(), -1000.0 * 0.02)


def test_real_ccx_substructure_file_is_read_and_its_uncondensed_matrix_refused():
    """A ``.mtx`` that CalculiX 2.20 wrote (deck alongside): the reader takes its layout; its
    matrix is the retained nodes' own element stiffness, not condensed (that version's
    ``*SUBSTRUCTURE GENERATE``), so a free-floating part shows no rigid-body null space and the
    check refuses it."""
    from pathlib import Path

    data = Path(__file__).parent / "data" / "superelement"
    rm = read_user_element_matrix(data / "ccx220_substructure.mtx")
    assert len(rm.dofs) == 24 and rm.dofs[:4] == ((1, 1), (1, 2), (1, 3), (2, 1))
    coords = read_inp_nodes(data / "ccx220_substructure.inp")
    with pytest.raises(ValueError, match="does not leave the table's rigid motions free"):
        check_rigid_modes(rm, coords)


def test_scaled_table_is_the_table_of_the_scaled_matrix():
    from diffguide.fe.superelement import scaled_table

    rm, coords = two_element_beam(1e3)
    pts = [RetainedPoint(name="mid", node=2)]
    base = table_from_reduced(rm, coords, [1, 3], pts)
    stiff = table_from_reduced(ReducedMatrix(K=1.5 * rm.K, dofs=rm.dofs, f=rm.f), coords, [1, 3],
                               pts)
    got = scaled_table(base, 1.5)
    for name in ("K", "f", "R", "r0"):
        np.testing.assert_allclose(getattr(got, name), getattr(stiff, name), rtol=1e-12,
                                   atol=1e-12 * float(np.abs(getattr(stiff, name)).max()))


def test_description_file_in_mm_with_rotation_nodes(tmp_path):
    """The beam written in mm and N (K in N/mm, N, N·mm), node 3's rotations on a CalculiX
    rotation node 30, as a .mtx + description file: read back in SI it is the beam."""
    from diffguide.io.superelement_file import load_imported_table

    rm, coords = two_element_beam(0.0)
    rot = np.array([d > 3 for _, d in rm.dofs])
    s = np.where(rot, 1.0, 1e3)  # u_mm = 1000 u_m; rotations unchanged
    # F_file = m F (forces in N, moments in N·mm: m = 1000), u_file = s u: K_file = m K s⁻¹
    K_mm = np.diag(np.where(rot, 1e3, 1.0)) @ rm.K @ np.diag(1 / s)
    dofs = [(30, d - 3) if (n == 3 and d > 3) else (n, d) for n, d in rm.dofs]
    nodes = [n for n, _ in dofs]
    lines = ["*USER ELEMENT, NODES=18, LINEAR", "** ELEMENT NODES",
             "** " + ", ".join(map(str, nodes)), str(dofs[0][1])]
    lines += [f"{k + 1}, {d}" for k, (_, d) in enumerate(dofs) if k > 0]
    lines.append("*MATRIX, TYPE=STIFFNESS")
    lines += [", ".join(f"{v:.17e}" for v in K_mm[i, :i + 1]) + "," for i in range(18)]
    (tmp_path / "beam.mtx").write_text("\n".join(lines) + "\n")
    (tmp_path / "beam_nodes.inp").write_text(
        "*NODE\n" + "".join(f"{n}, {1e3 * x}, {1e3 * y}, {1e3 * z}\n"
                            for n, (x, y, z) in coords.items()))
    (tmp_path / "beam.toml").write_text(
        'format = "ccx-mtx"\nmatrix = "beam.mtx"\nnodes = "beam_nodes.inp"\n'
        'length_unit = 0.001\n[rotation_nodes]\n"30" = 3\n[interfaces]\na = 1\nb = 3\n'
        '[points.mid]\nnode = 2\n')
    data = load_imported_table(tmp_path / "beam.toml")
    order = [data.matrix.dofs.index(d) for d in rm.dofs]
    np.testing.assert_allclose(data.matrix.K[np.ix_(order, order)], rm.K, rtol=1e-12,
                               atol=1e-9 * np.abs(rm.K).max())
    np.testing.assert_allclose(data.coords[3], coords[3])


def test_point_rotation_from_the_fibre_below_and_from_the_top_face():
    """A point's rotation from its neighbours on the top face is the face's slope; with a node
    below it, roll and pitch are the fibre's. The field ``u_x = γ z − ω y``, ``u_y = ω x``,
    ``u_z = a x + b y``: the fibres tilt by γ about Y, the faces by the slope ``(a, b)``, both
    turn by ω about Z (the difference is the transverse shear strain ``(a − γ, b)``). The top
    face gives ``θ = (b, -a, ω)``, the fibre ``(0, γ, ω)``."""
    from diffguide.fe.superelement import _point_rows

    t, h = 0.05, 0.025
    coords = {1: (0.1, 0.2, t / 2), 2: (0.1 - h, 0.2, t / 2), 3: (0.1 + h, 0.2, t / 2),
              4: (0.1, 0.2 - h, t / 2), 5: (0.1, 0.2 + h, t / 2), 6: (0.1, 0.2, -t / 2)}
    dofs = tuple((n, d) for n in coords for d in (1, 2, 3))
    rm = ReducedMatrix(np.eye(len(dofs)), dofs, np.zeros(len(dofs)), "test")
    a, b, g, w = 2e-6, -3e-6, 5e-6, 7e-6

    def u(x, y, z):
        return np.array([g * z - w * y, w * x, a * x + b * y])

    vec = np.concatenate([u(*coords[n]) for n in coords])
    face = _point_rows(rm, coords, RetainedPoint("P", 1, (2, 3, 4, 5)), []) @ vec
    fibre = _point_rows(rm, coords, RetainedPoint("P", 1, (2, 3, 4, 5), below=6), []) @ vec
    np.testing.assert_allclose(face[3:], [b, -a, w], rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(fibre[3:], [0.0, g, w], rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(face[:3], fibre[:3])
    coords[6] = (0.1 + 1e-3, 0.2, -t / 2)
    with pytest.raises(ValueError, match="not straight under"):
        _point_rows(rm, coords, RetainedPoint("P", 1, (2, 3, 4, 5), below=6), [])
    with pytest.raises(ValueError, match="needs neighbours too"):
        _point_rows(rm, coords, RetainedPoint("P", 1, (), below=6), [])


def test_point_yaw_from_the_mid_surface():
    """``u_x = −ω y + c z y``, ``u_y = ω x − c z x``: the in-plane rotation ``½(∂u_y/∂x −
    ∂u_x/∂y) = ω − c z`` varies through the thickness. From the top-face neighbours the yaw is
    ``ω − c t/2``; with the nodes under them (``neighbours_below``), the mid-surface's ``ω``."""
    from diffguide.fe.superelement import _point_rows

    t, h, x0, y0 = 0.05, 0.025, 0.1, 0.2
    xy = [(x0, y0), (x0 - h, y0), (x0 + h, y0), (x0, y0 - h), (x0, y0 + h)]
    coords = {k + 1: (x, y, t / 2) for k, (x, y) in enumerate(xy)}
    coords.update({k + 11: (x, y, -t / 2) for k, (x, y) in enumerate(xy)})
    dofs = tuple((n, d) for n in coords for d in (1, 2, 3))
    rm = ReducedMatrix(np.eye(len(dofs)), dofs, np.zeros(len(dofs)), "test")
    w, c = 7e-6, 4e-5

    def u(x, y, z):
        return np.array([-w * y + c * z * y, w * x - c * z * x, 0.0])

    vec = np.concatenate([u(*coords[n]) for n in coords])
    top = RetainedPoint("P", 1, (2, 3, 4, 5), below=11)
    mid = RetainedPoint("P", 1, (2, 3, 4, 5), below=11, neighbours_below=(12, 13, 14, 15))
    assert (_point_rows(rm, coords, top, []) @ vec)[5] == pytest.approx(w - c * t / 2, rel=1e-12)
    assert (_point_rows(rm, coords, mid, []) @ vec)[5] == pytest.approx(w, rel=1e-12)
    with pytest.raises(ValueError, match="one node per neighbour"):
        _point_rows(rm, coords, RetainedPoint("P", 1, (2, 3, 4, 5), below=11,
                                              neighbours_below=(12, 13)), [])
