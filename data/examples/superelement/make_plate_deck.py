"""Write the CalculiX deck that reduces the ``majda2012`` table (a solid plate) to the retained
nodes diffguide needs, and the node file of those nodes.

    python make_plate_deck.py [--variant plate|thin|ribbed] [--nx-el 25] [--layers 1]
        # writes plate.inp (the deck), plate_nodes.inp (the retained nodes), plate_held_loads.inp
        # (the self-weight at the held nodes) and plate.toml (the description diffguide reads)
    ccx plate   # writes plate.dat (the reactions; 3 min on one core for the 25 mm grid)

The plate (``thin``: 20 mm thick; ``ribbed``: 30 mm on two transverse ribs 20 x 40 mm at
x = -/+300 mm): 1000 x 500 x 50 mm, cast iron (E 110 GPa, nu 0.26, 7200 kg/m3), C3D20R bricks on a
grid with lines every ``--nx-el`` mm plus the footprint edges and the control points, ``--layers``
elements through the thickness (one by default, as CalculiX's model of the whole machine in
``reference/calculix``; ribs: two through their depth). Units: SI (m, N, Pa, kg/m3). Origin:
the table centre, the plate mid-surface at z = 0 (top face z = +25 mm, underside -25 mm).

Retained nodes (named for diffguide in the description file, ``plate.toml``):

- carriages C11, C12, C21, C22 (rail at y = -170 / +170 mm, carriage at x = -160 / +160 mm), then
  the nut at (0, 0): ``*RIGID BODY`` over every node of the footprint (60 x 48 mm; the nut's
  50 x 50 mm), through the whole thickness; REF NODE 900001 + k at the centre of the footprint on
  the underside, ROT NODE 900101 + k (its DOF 1-3 are the rotations);
- control points P1 (450, 200), P2 (-450, 200), P3 (-450, -200), P4 (450, -200) mm: the top-face
  node at the point, its four neighbours one grid line away along X and Y, and the underside
  nodes under all five (translations: roll and pitch from the fibre through the point, yaw from
  the mid-surface, as a shell's rotations); P5 (0, 0) lies in the nut's rigid footprint: its
  top-face node moves with the nut (nothing retained).

The steps: one ``*STATIC`` step per retained DOF, that DOF moved by 1 (m or rad) with every other
retained DOF held (the columns of the reduced stiffness are the reactions RF), then one step with
every retained DOF held under gravity (the reduced self-weight loads are -RF plus the loads at
the held nodes themselves, which CalculiX's RF leaves out: ``plate_held_loads.inp``). This is what
``*SUBSTRUCTURE GENERATE`` is documented to do; the CalculiX 2.20 of Debian 12 writes the
uncondensed K_bb there instead (checked: no rigid-body null space), hence the explicit steps.
"""

import argparse
from pathlib import Path

import numpy as np

LENGTH, WIDTH, THICK = 1.0, 0.5, 0.05
E, NU, RHO, G = 110e9, 0.26, 7200.0, 9.81
RAIL_Y, CARR_X, FOOT = (-0.170, 0.170), (-0.160, 0.160), (0.060, 0.048)
NUT_XY, NUT_FOOT = (0.0, 0.0), (0.05, 0.05)
POINTS = {"P1": (0.450, 0.200), "P2": (-0.450, 0.200), "P3": (-0.450, -0.200),
          "P4": (0.450, -0.200), "P5": (0.0, 0.0)}
REF0, ROT0 = 900001, 900101
#: ``{variant: (plate thickness m, ribs)}``; a rib ``(x, width, depth)`` (m) runs along Y under
#: the plate, clear of the carriage and nut footprints.
VARIANTS = {"plate": (THICK, ()),
            "thin": (0.02, ()),
            "ribbed": (0.03, ((-0.30, 0.02, 0.04), (0.30, 0.02, 0.04)))}
#: Lattice offsets of the C3D20R nodes 1-20 (corners, bottom / top edge midpoints, vertical ones).
CORNER = [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0), (0, 0, 2), (2, 0, 2), (2, 2, 2), (0, 2, 2),
          (1, 0, 0), (2, 1, 0), (1, 2, 0), (0, 1, 0), (1, 0, 2), (2, 1, 2), (1, 2, 2), (0, 1, 2),
          (0, 0, 1), (2, 0, 1), (2, 2, 1), (0, 2, 1)]


def interfaces():
    """(name, x, y, half_x, half_y) of the carriages (rail by rail) then the nut."""
    out = [(f"C{i + 1}{j + 1}", cx, ry, FOOT[0] / 2, FOOT[1] / 2)
           for i, ry in enumerate(RAIL_Y) for j, cx in enumerate(CARR_X)]
    return out + [("nut", NUT_XY[0], NUT_XY[1], NUT_FOOT[0] / 2, NUT_FOOT[1] / 2)]


def grid_lines(half, step, extra):
    lines = np.concatenate([np.linspace(-half, half, int(round(2 * half / step)) + 1), extra])
    lines = np.unique(np.round(lines, 9))
    return lines[np.concatenate([[True], np.diff(lines) > 1e-6])]


def build(step=0.025, layers=1, variant="plate"):
    """Nodes, elements, rigid footprints and retained points of ``variant`` (:data:`VARIANTS`)."""
    thick, ribs = VARIANTS[variant]
    ifs = interfaces()
    ex = [v for _, x, _, hx, _ in ifs for v in (x - hx, x, x + hx)]
    ey = [v for _, _, y, _, hy in ifs for v in (y - hy, y, y + hy)]
    ex += [p[0] for p in POINTS.values()] + [v for x, w, _ in ribs for v in (x - w / 2, x + w / 2)]
    ey += [p[1] for p in POINTS.values()]
    xs, ys = grid_lines(LENGTH / 2, step, ex), grid_lines(WIDTH / 2, step, ey)
    zs = np.linspace(-thick / 2, thick / 2, layers + 1)
    if ribs:  # two brick layers through the ribs' depth, under the plate
        depth = ribs[0][2]
        zs = np.concatenate([np.linspace(-thick / 2 - depth, -thick / 2, 3)[:-1], zs])
    n_below = 2 if ribs else 0

    def fine(v):  # corner and mid-edge coordinates
        mid = 0.5 * (v[:-1] + v[1:])
        return np.insert(v, np.arange(1, len(v)), mid)

    X, Y, Z = fine(xs), fine(ys), fine(zs)
    NI, NJ = len(X), len(Y)

    def nid(i, j, k):
        return 1 + i + NI * (j + NJ * k)

    def in_rib(x0, x1):
        return any(x - w / 2 - 1e-9 <= x0 and x1 <= x + w / 2 + 1e-9 for x, w, _ in ribs)

    elements = []
    for k in range(0, len(Z) - 1, 2):
        for j in range(0, NJ - 1, 2):
            for i in range(0, NI - 1, 2):
                if k // 2 < n_below and not in_rib(X[i], X[i + 2]):
                    continue
                elements.append([nid(i + a, j + b, k + c) for a, b, c in CORNER])
    nodes = {}
    for k in range(len(Z)):
        for j in range(NJ):
            for i in range(NI):
                if (i % 2) + (j % 2) + (k % 2) <= 1:
                    nodes[nid(i, j, k)] = (X[i], Y[j], Z[k])
    used = {n for e in elements for n in e}
    nodes = {n: v for n, v in nodes.items() if n in used}
    ids = np.array(list(nodes))
    xyz = np.array([nodes[n] for n in ids])

    def at(x, y, z):
        d = np.abs(xyz - [x, y, z]).sum(axis=1)
        if d.min() > 1e-9:
            raise ValueError(f"no node at ({x}, {y}, {z})")
        return int(ids[np.argmin(d)])

    def line_after(v, lines, sign):
        k = int(np.flatnonzero(np.isclose(lines, v))[0]) + sign
        return float(lines[k])

    rigid = []
    for name, x, y, hx, hy in ifs:
        inside = ((np.abs(xyz[:, 0] - x) <= hx + 1e-9) & (np.abs(xyz[:, 1] - y) <= hy + 1e-9))
        rigid.append((name, ids[inside], (x, y, -thick / 2)))
    points, extra_nodes = {}, {}
    zt = thick / 2
    for name, (x, y) in POINTS.items():
        node = at(x, y, zt)
        if name == "P5":  # in the nut's rigid footprint
            points[name] = (node, ())
            continue
        nb = tuple(at(*p, zt) for p in [(line_after(x, xs, -1), y), (line_after(x, xs, 1), y),
                                         (x, line_after(y, ys, -1)), (x, line_after(y, ys, 1))])
        # the nodes under the point and under each neighbour, on the underside
        points[name] = (node, nb + tuple(at(*coord[:2], -zt) for coord in
                                         [(x, y)] + [nodes[q] for q in nb]))
    return nodes, elements, rigid, points, extra_nodes


def gravity_loads(nodes, elements):
    """Consistent nodal self-weight loads ``{node: Fz}`` (N) of the C3D20R mesh: ``-rho g`` times
    the integral of each shape function (3-point Gauss per direction, exact on these boxes).
    CalculiX's RF of a held node leaves out the load applied at that node; these are added to
    the retained nodes' loads (written as *CLOAD lines, :func:`write`)."""
    nat = np.array(CORNER, dtype=float) - 1.0  # natural coordinates of the 20 nodes
    gp, gw = np.polynomial.legendre.leggauss(3)
    out = {}
    for conn in elements:
        xyz = np.array([nodes[n] for n in conn])
        half = 0.5 * (xyz.max(axis=0) - xyz.min(axis=0))
        detJ = half.prod()
        acc = np.zeros(20)
        for a, wa in zip(gp, gw):
            for b, wb in zip(gp, gw):
                for c, wc in zip(gp, gw):
                    acc += wa * wb * wc * _shape20(nat, np.array([a, b, c]))
        for n, v in zip(conn, -RHO * G * detJ * acc):
            out[n] = out.get(n, 0.0) + v
    return out


def _shape20(nat, s):
    """The 20 serendipity shape functions at natural point ``s``."""
    N = np.empty(20)
    for k, ni in enumerate(nat):
        t = 1.0 + s * ni
        if np.all(ni != 0):
            N[k] = 0.125 * t.prod() * (np.dot(s, ni) - 2.0)
        else:
            z = int(np.flatnonzero(ni == 0)[0])
            N[k] = 0.25 * (1.0 - s[z] ** 2) * np.prod(np.delete(t, z))
    return N


def retained_dofs(rigid, points):
    """The retained (node, dof) in the order of the unit-displacement steps."""
    dofs = []
    for k in range(len(rigid)):
        dofs += [(REF0 + k, d) for d in (1, 2, 3)] + [(ROT0 + k, d) for d in (1, 2, 3)]
    for node, nb in points.values():
        if nb:
            dofs += [(n, d) for n in (node,) + nb for d in (1, 2, 3)]
    return dofs


def write(out_dir: Path, step=0.025, layers=1, variant="plate"):
    nodes, elements, rigid, points, _ = build(step, layers, variant)
    dofs = retained_dofs(rigid, points)
    retained_nodes = sorted({n for n, _ in dofs})
    L = ["** diffguide: the majda2012 table as a solid plate, reduced to its retained nodes.",
         "** Written by make_plate_deck.py (see its docstring). Units: m, N, Pa, kg/m3.",
         "*NODE, NSET=NALL"]
    L += [f"{n}, {x:.9g}, {y:.9g}, {z:.9g}" for n, (x, y, z) in nodes.items()]
    for k, (_, _, (x, y, z)) in enumerate(rigid):
        L += [f"{REF0 + k}, {x:.9g}, {y:.9g}, {z:.9g}", f"{ROT0 + k}, {x:.9g}, {y:.9g}, {z:.9g}"]
    L.append("*ELEMENT, TYPE=C3D20R, ELSET=EALL")
    L += [f"{e + 1}, " + ", ".join(map(str, c[:15])) + ",\n" + ", ".join(map(str, c[15:]))
          for e, c in enumerate(elements)]
    for k, (name, members, _) in enumerate(rigid):
        L.append(f"*NSET, NSET=F{name}")
        L += [", ".join(map(str, members[i:i + 12])) for i in range(0, len(members), 12)]
        L.append(f"*RIGID BODY, NSET=F{name}, REF NODE={REF0 + k}, ROT NODE={ROT0 + k}")
    L.append("*NSET, NSET=RETAINED")
    L += [", ".join(map(str, retained_nodes[i:i + 12])) for i in range(0, len(retained_nodes), 12)]
    L += ["*MATERIAL, NAME=CASTIRON", "*ELASTIC", f"{E:.6g}, {NU}", "*DENSITY", f"{RHO}",
          "*SOLID SECTION, ELSET=EALL, MATERIAL=CASTIRON"]
    for j, (node, d) in enumerate(dofs):
        L += [f"** unit displacement {j + 1}: node {node} DOF {d}", "*STEP", "*STATIC",
              "*BOUNDARY, OP=NEW", "RETAINED, 1, 3, 0.", f"{node}, {d}, {d}, 1.",
              "*NODE PRINT, NSET=RETAINED, TOTALS=NO", "RF", "*END STEP"]
    L += ["** self-weight with every retained DOF held", "*STEP", "*STATIC",
          "*BOUNDARY, OP=NEW", "RETAINED, 1, 3, 0.", "*DLOAD", f"EALL, GRAV, {G}, 0., 0., -1.",
          "*NODE PRINT, NSET=RETAINED, TOTALS=NO", "RF", "*END STEP"]
    (out_dir / f"{variant}.inp").write_text("\n".join(L) + "\n")
    N = ["** Retained nodes of plate.inp (and the top-face node of P5), m. Order of the",
         "** unit-displacement steps of plate.dat (node, DOF):"]
    N += ["** " + " ".join(f"{n}:{d}" for n, d in dofs[i:i + 8]) for i in range(0, len(dofs), 8)]
    N.append("*NODE")
    extra = [points["P5"][0]]
    for n in retained_nodes + extra:
        if n >= REF0:
            k = (n - REF0) % 100
            x, y, z = rigid[k][2]
        else:
            x, y, z = nodes[n]
        N.append(f"{n}, {x:.9g}, {y:.9g}, {z:.9g}")
    (out_dir / f"{variant}_nodes.inp").write_text("\n".join(N) + "\n")
    # the self-weight applied at the held nodes (left out of CalculiX's RF): on the retained
    # point nodes directly, on a footprint's nodes as the rigid wrench at its REF / ROT node
    loads = gravity_loads(nodes, elements)
    held = {}
    for k, (_, members, ref) in enumerate(rigid):
        fz = np.array([loads.get(int(n), 0.0) for n in members])
        d = np.array([nodes[int(n)] for n in members]) - ref
        held[(REF0 + k, 3)] = fz.sum()
        held[(ROT0 + k, 1)] = (d[:, 1] * fz).sum()  # M = d x (0, 0, Fz)
        held[(ROT0 + k, 2)] = -(d[:, 0] * fz).sum()
    for node, d in dofs:
        if node < REF0 and d == 3:
            held[(node, 3)] = loads.get(node, 0.0)
    C = ["** Self-weight at the held (retained and rigid-footprint) nodes of plate.inp (N, N m):",
         "** CalculiX's RF leaves these out; f = -RF + these. Total of all nodal loads: "
         f"{sum(loads.values()):.6g} N", "*CLOAD"]
    C += [f"{n}, {d}, {v:.12g}" for (n, d), v in held.items()]
    (out_dir / f"{variant}_held_loads.inp").write_text("\n".join(C) + "\n")
    names = [name for name, _, _ in rigid]
    T = [f"# The reduced {variant} table of make_plate_deck.py (docs/superelement.md).",
         'format = "ccx-reactions"', f'matrix = "{variant}.dat"', f'nodes = "{variant}_nodes.inp"',
         f'held_loads = "{variant}_held_loads.inp"', "length_unit = 1.0",
         "# the unit-displacement steps, in order: [node, dof]",
         "dofs = [" + ", ".join(f"[{n}, {d}]" for n, d in dofs) + "]",
         "", "[rotation_nodes]  # CalculiX ROT NODE = REF NODE"]
    T += [f'"{ROT0 + k}" = {REF0 + k}' for k in range(len(rigid))]
    T += ["", "[interfaces]"] + [f"{n} = {REF0 + k}" for k, n in enumerate(names)]
    for name, (node, nb) in points.items():
        T += ["", f"[points.{name}]", f"node = {node}"]
        T += [f"neighbours = {list(nb[:4])}", f"below = {nb[4]}",
              f"neighbours_below = {list(nb[5:])}"] if nb else ['rigid_to = "nut"']
    (out_dir / f"{variant}.toml").write_text("\n".join(T) + "\n")
    return dofs, points


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nx-el", type=float, default=25.0, help="grid step (mm)")
    ap.add_argument("--layers", type=int, default=1, help="elements through the thickness")
    ap.add_argument("--variant", choices=sorted(VARIANTS), default="plate")
    ap.add_argument("--out", default=str(Path(__file__).parent))
    a = ap.parse_args()
    dofs, points = write(Path(a.out), a.nx_el / 1000, a.layers, a.variant)
    print(f"{len(dofs)} retained DOF; points {points}")
