r"""An independent reference for the assembled diffguide machine, computed with CalculiX (ccx).

For each machine (a TOML configuration, read here with ``tomllib`` only), each rail case and
each table position ``x`` this script writes a CalculiX deck, runs ``ccx``, reads the 3-D
displacements from the ``.frd`` file and writes the joint kinematic errors at the control points
(ISO 230-1, relative to ``x_ref = 0``) to ``tests/data/calculix/``. Nothing here calls diffguide:
geometry, the Hertz law, the preload, the screw stiffness and the rail profiles are computed from
the TOML values and the formulas below, so the stored numbers check diffguide, not repeat it.

The deck (one static, geometrically nonlinear step per position):

* table: 4-node (``S4``, default) or 8-node (``S8R``) shells on a structured grid with lines at
  every footprint edge and centre and at the control points; ccx expands them to C3D8I / C3D20R
  bricks through the thickness. Mid-surface at z = 0, top at +t/2.
* ribs (``[[ribs]]`` of the TOML, as diffguide reads them: axis, position, width, depth below
  the plate, the whole table long): bricks of the same material under the plate, on the plate's
  underside nodes (grid lines at the rib edges), ``rib_layers`` through the depth; a rib under a
  carriage or nut footprint is refused.
* carriages: rigid bodies (``*RIGID BODY``) whose reference node is the centre of the carriage's
  top face (x_c, y_rail, -t/2), tied to every table node in the footprint and to one node at each
  rolling element's contact point (x_c + ξ, y_rail ± y_r, -t/2 + z_r).
* rolling elements: one ``SPRINGA`` per element from its contact node A to a ground node
  B = A - L·n (n the element's load direction, L = 0.1 m), force–elongation table
  F(e) = -F_law(g0 - e): compression-only, the preload approach g0 at zero elongation, so the
  preloaded state is the undeformed state; F_law(a) = K·r_ε(a)^{3/2} (Hertz, two ball–groove
  contacts in series, elliptic integrals from scipy; r_ε the C¹ ramp of width ε = 0.02 g0, the
  same compression-only law as diffguide). The rail error enters as the prescribed displacement
  (0, e_y(s), e_z(s)) of B, s = x + x_c + ξ, so that the approach is
  a = g0 + n·(e(s) - u_A).
* screw: a ``SPRING1`` in X on the reference node of a rigid nut patch, k = E·πd²/4 / (L0 + x).
* gravity on the plate (``*DLOAD, GRAV``).
* ``*STEP, NLGEOM``: without it ccx makes one linear pass and the springs stay at their initial
  tangent.

Joint errors at a control point P (top surface): EXX, EYX, EZX are the displacement of the
expanded top-surface node at P; EAX = -(u_y,top - u_y,bottom)/t and EBX = (u_x,top -
u_x,bottom)/t are the rotation of the normal fibre through P (the shell director rotation that
diffguide reports); ECX = ½(∂u_y/∂x - ∂u_x/∂y) of the mid-surface (mean of top and bottom), by
central differences over the neighbouring grid nodes. Each minus its value at x = 0.

Run (needs ``ccx`` on the PATH and numpy/scipy; about a minute per machine on 2 cores)::

    python reference/calculix/make_reference.py            # all machines and cases
    python reference/calculix/make_reference.py --study    # + mesh and table-density studies
    python reference/calculix/make_reference.py --rib-study --workers 1   # the ribbed mesh study
"""

import argparse
import concurrent.futures
import datetime
import json
import math
import shutil
import subprocess
import tempfile
import tomllib
from pathlib import Path

import numpy as np
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
OUT = REPO / "tests" / "data" / "calculix"
SPRING_LENGTH = 0.1  # m, length of the element springs (only their direction matters)
QUANTITIES = ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX")

# ---------------------------------------------------------------------------------------------
# machine parameters (SI) from a diffguide TOML configuration
# ---------------------------------------------------------------------------------------------


def read_machine(path: Path) -> dict:
    """Every parameter the deck needs, in SI units, from a complete machine TOML file."""
    c = tomllib.loads(path.read_text())
    t, g, k, s = c["table"], c["guideway"], c["carriage"], c["screw"]
    if k["law"] != "hertz":
        raise ValueError("this reference implements the Hertz ball law only")
    mm = 1e-3
    return {
        "length": t["length_mm"] * mm,
        "width": t["width_mm"] * mm,
        "thickness": t["thickness_mm"] * mm,
        "E": t["E_GPa"] * 1e9,
        "nu": t["nu"],
        "rho": t["density_kg_m3"],
        "rail_y": [v * mm for v in g["rail_y_mm"]],
        "carriage_x": [v * mm for v in g["carriage_x_mm"]],
        "footprint": [v * mm for v in g["carriage_footprint_mm"]],
        "ball_d": k["ball_diameter_mm"] * mm,
        "groove_D": k["ball_diameter_mm"] * mm * k["groove_conformity"],
        "ball_E": k["E_GPa"] * 1e9,
        "ball_nu": k["nu"],
        "n_elements": k["elements_per_row"],
        "pitch": k["pitch_mm"] * mm,
        "contact_angle": math.radians(k["contact_angle_deg"]),
        "arrangement": k["arrangement"],
        "upper_yz": [v * mm for v in k["upper_row_yz_mm"]],
        "lower_yz": [v * mm for v in k["lower_row_yz_mm"]],
        "preload_force": k["capacity_N"] * k["preload_fraction"] / (4 * k["elements_per_row"]),
        "smoothing": k["smoothing_fraction"],
        "screw_EA": s["E_GPa"] * 1e9 * math.pi * (s["core_diameter_mm"] * mm) ** 2 / 4,
        "screw_L0": s["free_length_at_ref_mm"] * mm,
        "nut_xy": [v * mm for v in s["nut_xy_mm"]],
        "nut_footprint": [v * mm for v in s["nut_footprint_mm"]],
        "gravity": c["machine"]["gravity_m_s2"],
        "stroke": c["machine"]["stroke_mm"] * mm,
        "points": {name: (xy[0] * mm, xy[1] * mm) for name, xy in c["points"].items()},
        "ribs": [
            {
                "axis": r.get("axis", "x"),
                "position": r.get("position_mm", 0.0) * mm,
                "width": r.get("width_mm", 20.0) * mm,
                "depth": r.get("depth_mm", 60.0) * mm,
            }
            for r in c.get("ribs", [])
        ],
    }


# ---------------------------------------------------------------------------------------------
# the rolling-element law: Hertz (Johnson, Contact Mechanics, §4.2, eqs. 3.70-3.72)
# ---------------------------------------------------------------------------------------------


def hertz_contact_compliance(d: float, D: float, E: float, nu: float) -> float:
    """``c₁`` of one ball–groove contact, ``δ = c₁ F^(2/3)`` (m/N^(2/3)), elliptic integrals.

    Relative curvatures: ``2/d`` along the groove, ``2/d - 2/D`` across it. With
    ``A = ½(2/d - 2/D)`` (across, the major axis a) and ``B = ½(2/d)``, the eccentricity e solves
    ``B/A = (E(e)/(1-e²) - K(e)) / (K(e) - E(e))``; then ``a³ = 3F(K-E)/(2π e² A E*)`` and
    ``δ = 3F K(e)/(2π a E*)``, ``E* = E/(2(1-ν²))`` (ball and groove of the same steel).
    """
    A, B = 1 / d - 1 / D, 1 / d
    m_of = lambda e: e * e  # scipy's ellipk/ellipe take the parameter m = e²  # noqa: E731

    def ratio(e):
        m = m_of(e)
        K, Ee = ellipk(m), ellipe(m)
        return (Ee / (1 - m) - K) / (K - Ee) - B / A

    e = brentq(ratio, 1e-6, 1 - 1e-14, xtol=1e-15, rtol=1e-15)
    m = m_of(e)
    K, Ee = ellipk(m), ellipe(m)
    Estar = E / (2 * (1 - nu**2))
    F = 1.0
    a = (3 * F * (K - Ee) / (2 * math.pi * m * A * Estar)) ** (1 / 3)
    return 3 * F * K / (2 * math.pi * a * Estar)


def element_law(mach: dict) -> dict:
    """K (N/m^1.5), the preload approach g0 (m) and the smoothing length ε (m) of one element."""
    c1 = hertz_contact_compliance(mach["ball_d"], mach["groove_D"], mach["ball_E"], mach["ball_nu"])
    c = 2 * c1  # two contacts in series per ball
    g0 = c * mach["preload_force"] ** (2 / 3)
    return {"K": c**-1.5, "g0": g0, "eps": mach["smoothing"] * g0, "c_contact": c1}


def law_force(a, law: dict):
    """Smoothed compression-only force ``K r_ε(a)^1.5`` (N) at approach ``a`` (m)."""
    a = np.asarray(a, dtype=float)
    eps = law["eps"]
    r = np.where(a >= eps, a, np.where(a <= -eps, 0.0, (a + eps) ** 2 / (4 * eps)))
    return law["K"] * r**1.5


def spring_table(law: dict, ratio: float, a_max_g0: float = 6.0) -> np.ndarray:
    """(force N, elongation m) rows for ``*SPRING, NONLINEAR``: elongation e = g0 - a.

    Approach points: 9 across the smoothing zone [-ε, ε], then a geometric grid from ε to
    ``a_max_g0·g0`` with step ratio ``1 + ratio`` (linear interpolation of a^1.5 errs by about
    (3/32)·ratio² relative), one point continuing the last slope to 100 g0 (so the table never
    goes flat where an element is loaded), and one zero-force point well into tension.
    ccx holds at most 200 points.
    """
    g0, eps = law["g0"], law["eps"]
    a = list(np.linspace(-eps, eps, 9))
    while a[-1] < a_max_g0 * g0:
        a.append(a[-1] * (1 + ratio))
    a = np.array(a)
    F = law_force(a, law)
    slope = (F[-1] - F[-2]) / (a[-1] - a[-2])
    a = np.concatenate([[-g0 - 100 * eps], a, [100 * g0]])
    F = np.concatenate([[0.0], F, [F[-1] + slope * (100 * g0 - a[-2])]])
    if len(a) > 200:
        raise ValueError(f"spring table has {len(a)} points; ccx holds at most 200")
    rows = np.stack([-F, g0 - a], axis=1)
    return rows[np.argsort(rows[:, 1])]


# ---------------------------------------------------------------------------------------------
# rail profiles (the same definitions as diffguide's rail classes; JSON specs)
# ---------------------------------------------------------------------------------------------


def rail_profile(spec: dict, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(e_y, e_z) in m of one rail at rail coordinates ``s`` (m)."""
    s = np.asarray(s, dtype=float)
    kind = spec["kind"]
    if kind == "straight":
        v = np.zeros_like(s)
    elif kind == "paper":  # Majda (2012) eq. 4
        v = 0.5 * spec["delta"] * (s + s**2)
    elif kind == "sine":
        v = spec["amplitude"] * np.sin(2 * np.pi * s / spec["wavelength"] + spec["phase"])
    elif kind == "bump":
        v = spec["amplitude"] * np.exp(-(((s - spec["center"]) / spec["width"]) ** 2))
    else:
        raise ValueError(kind)
    zero = np.zeros_like(s)
    return (zero, v) if spec.get("plane", "vertical") == "vertical" else (v, zero)


def paper(plane):
    return {"kind": "paper", "delta": 0.05e-3, "plane": plane}


STRAIGHT = {"kind": "straight"}

#: rail cases: (rail 1, rail 2) specs.
CASES = {
    "variant1": (paper("vertical"), STRAIGHT),
    "variant2": (paper("horizontal"), STRAIGHT),
    "variant3": (paper("vertical"), paper("horizontal")),
    "both_bent": (
        {"kind": "sine", "amplitude": 4e-6, "wavelength": 0.5, "phase": 0.3, "plane": "vertical"},
        {"kind": "sine", "amplitude": 3e-6, "wavelength": 0.35, "phase": 1.2, "plane": "vertical"},
    ),
    # a 12 µm bump under rail 1 at s = 0.25 m: the lower rows of the carriage passing it lift off
    "liftoff": (
        {"kind": "bump", "amplitude": 12e-6, "center": 0.25, "width": 0.02, "plane": "vertical"},
        STRAIGHT,
    ),
}

#: machines: TOML file, rail cases, table positions (m).
MACHINES = {
    "majda2012": {
        "toml": "majda2012.toml",
        "cases": ["variant1", "variant2", "variant3", "both_bent", "liftoff"],
        "positions": {
            "default": list(np.linspace(-0.35, 0.35, 9)),
            "liftoff": [-0.35, -0.2, -0.1, 0.0, 0.05, 0.07, 0.09, 0.11, 0.13, 0.2, 0.35],
        },
    },
    "calculix_b": {
        "toml": "calculix_b.toml",
        "cases": ["variant1", "variant3", "both_bent"],
        "positions": {"default": list(np.linspace(-0.3, 0.3, 9))},
        # one brick layer is 3 % of a range off the two-layer model at P4 (EBX) in variant 3
        "mesh": {"variant3": {"nx": 40, "ny": 20, "element": "C3D20R", "layers": 2}},
    },
    # majda2012 on the superelement example's ribbed table (30 mm plate, two transverse ribs);
    # a second brick layer in the plate moves EAX/EBX/EZX by up to 1 % of a range, the rib's
    # 2 -> 4 layers by <= 0.06 % (README): two and two
    "ribbed": {
        "toml": "ribbed.toml",
        "cases": ["variant1", "variant2", "variant3"],
        "positions": {"default": list(np.linspace(-0.35, 0.35, 9))},
        "mesh": {
            c: {"nx": 40, "ny": 20, "element": "C3D20R", "layers": 2, "rib_layers": 2}
            for c in ("variant1", "variant2", "variant3")
        },
    },
}

# ---------------------------------------------------------------------------------------------
# mesh
# ---------------------------------------------------------------------------------------------


def grid_lines(lo: float, hi: float, n: int, extra, tol=1e-9) -> np.ndarray:
    lines = list(np.linspace(lo, hi, n + 1))
    for e in extra:
        if lo - tol <= e <= hi + tol and min(abs(e - v) for v in lines) > tol:
            lines.append(e)
    return np.array(sorted(lines))


def patches(mach: dict) -> list[dict]:
    """Rigid patches: the carriages (rail by rail), then the nut; centre, half-sizes, kind."""
    fx, fy = mach["footprint"]
    out = [
        {"x": cx, "y": ry, "hx": fx / 2, "hy": fy / 2, "rail": i}
        for i, ry in enumerate(mach["rail_y"])
        for cx in mach["carriage_x"]
    ]
    nx, ny = mach["nut_footprint"]
    out.append({"x": mach["nut_xy"][0], "y": mach["nut_xy"][1], "hx": nx / 2, "hy": ny / 2})
    return out


def rib_box(rib: dict, mach: dict) -> tuple[float, float, float, float]:
    """Plan-view extent (x0, x1, y0, y1) of a rib (m): the whole table along its axis."""
    half = rib["width"] / 2
    L, W = mach["length"] / 2, mach["width"] / 2
    if rib["axis"] == "x":
        return -L, L, rib["position"] - half, rib["position"] + half
    return rib["position"] - half, rib["position"] + half, -W, W


def check_ribs_clear(mach: dict) -> None:
    """Refuse a rib that runs under a carriage or nut footprint (they are bolted there)."""
    for rib in mach["ribs"]:
        x0, x1, y0, y1 = rib_box(rib, mach)
        for p in patches(mach):
            if x0 < p["x"] + p["hx"] - 1e-9 and p["x"] - p["hx"] + 1e-9 < x1:
                if y0 < p["y"] + p["hy"] - 1e-9 and p["y"] - p["hy"] + 1e-9 < y1:
                    raise ValueError(f"rib {rib} runs under the footprint at {p}")


def rib_z_lines(mach: dict, layers: int) -> np.ndarray:
    """z (m) of the brick layers below the plate's underside, down to the deepest rib."""
    bottom = -mach["thickness"] / 2
    zs = [np.linspace(bottom - r["depth"], bottom, layers + 1) for r in mach["ribs"]]
    return np.unique(np.round(np.concatenate(zs), 12))[:-1] if zs else np.zeros(0)


def in_rib(mach: dict, x0, x1, y0, y1, z0) -> bool:
    """Whether the cell [x0, x1] x [y0, y1] with bottom z0, below the plate, is rib material."""
    for rib in mach["ribs"]:
        bx0, bx1, by0, by1 = rib_box(rib, mach)
        inside = bx0 - 1e-9 <= x0 and x1 <= bx1 + 1e-9 and by0 - 1e-9 <= y0 and y1 <= by1 + 1e-9
        if inside and z0 >= -mach["thickness"] / 2 - rib["depth"] - 1e-9:
            return True
    return False


def make_mesh(
    mach: dict, nx: int, ny: int, element: str = "C3D20R", layers: int = 1, rib_layers: int = 2
) -> dict:
    """Structured brick mesh of the plate, grid lines at every footprint edge and centre and at
    the control points, ``layers`` elements through the thickness; ribs (``mach["ribs"]``) as
    ``rib_layers`` bricks through their depth under the plate, on the plate's underside nodes
    (grid lines at the rib edges).

    ``C3D20R``: 20-node bricks (what ccx makes of ``S8R`` shells: one layer of C3D20R), nodes at
    the corners and edge midpoints of a half-step grid. ``C3D8I``: 8-node incompatible-mode bricks
    (what ccx makes of ``S4`` shells).
    """
    check_ribs_clear(mach)
    lx, ly = [], []
    for p in patches(mach):
        lx += [p["x"] - p["hx"], p["x"], p["x"] + p["hx"]]
        ly += [p["y"] - p["hy"], p["y"], p["y"] + p["hy"]]
    for x, y in mach["points"].values():
        lx.append(x)
        ly.append(y)
    for rib in mach["ribs"]:
        x0, x1, y0, y1 = rib_box(rib, mach)
        lx += [x0, x1]
        ly += [y0, y1]
    L, W, t = mach["length"], mach["width"], mach["thickness"]
    xs = grid_lines(-L / 2, L / 2, nx, lx)
    ys = grid_lines(-W / 2, W / 2, ny, ly)
    zs = np.concatenate([rib_z_lines(mach, rib_layers), np.linspace(-t / 2, t / 2, layers + 1)])
    quad = element == "C3D20R"

    def refine(v):
        return np.sort(np.concatenate([v, 0.5 * (v[1:] + v[:-1])])) if quad else v

    X, Y, Z = refine(xs), refine(ys), refine(zs)
    s = 2 if quad else 1
    cells = []
    for i in range(0, len(X) - 1, s):
        for j in range(0, len(Y) - 1, s):
            for k in range(0, len(Z) - 1, s):
                if Z[k] < -t / 2 - 1e-12 and not in_rib(mach, X[i], X[i + s], Y[j], Y[j + s], Z[k]):
                    continue  # below the plate, outside every rib
                c = [(i, j), (i + s, j), (i + s, j + s), (i, j + s)]
                conn = [(a, b, k) for a, b in c] + [(a, b, k + s) for a, b in c]
                if quad:
                    m = [(i + 1, j), (i + 2, j + 1), (i + 1, j + 2), (i, j + 1)]
                    conn += [(a, b, k) for a, b in m] + [(a, b, k + 2) for a, b in m]
                    conn += [(a, b, k + 1) for a, b in c]
                cells.append(conn)
    used = sorted({n for conn in cells for n in conn}, key=lambda n: (n[0], n[1], n[2]))
    ids = {n: q + 1 for q, n in enumerate(used)}
    coords = np.array([(X[i], Y[j], Z[k]) for i, j, k in used])
    elems = [[ids[n] for n in conn] for conn in cells]
    return {"xs": xs, "ys": ys, "coords": coords, "elements": elems, "type": element}


# ---------------------------------------------------------------------------------------------
# deck sections
# ---------------------------------------------------------------------------------------------


def deck_table(mach: dict, mesh: dict) -> list[str]:
    """Table nodes, brick elements, material (E, ν, ρ) and section."""
    out = ["*NODE, NSET=NTABLE"]
    out += [f"{k + 1}, {x:.12g}, {y:.12g}, {z:.12g}" for k, (x, y, z) in enumerate(mesh["coords"])]
    out.append(f"*ELEMENT, TYPE={mesh['type']}, ELSET=ETABLE")
    for e, conn in enumerate(mesh["elements"]):
        text = ", ".join(map(str, [e + 1, *conn]))
        out += [text[i : i + 200] for i in range(0, len(text), 200)] if False else _wrap(text)
    out += [
        "*MATERIAL, NAME=TABLE",
        "*ELASTIC",
        f"{mach['E']:.12g}, {mach['nu']:.12g}",
        "*DENSITY",
        f"{mach['rho']:.12g}",
        "*SOLID SECTION, ELSET=ETABLE, MATERIAL=TABLE",
    ]
    return out


def _wrap(text: str, per_line: int = 16) -> list[str]:
    """An element record over several lines (ccx reads at most 16 entries per line)."""
    items = text.split(", ")
    lines = [", ".join(items[i : i + per_line]) for i in range(0, len(items), per_line)]
    return [ln + "," for ln in lines[:-1]] + [lines[-1]]


def carriage_geometry(mach: dict):
    """Contact points (rows, n, 3) in the carriage frame and load directions (rows, 3)."""
    s, c = math.sin(mach["contact_angle"]), math.cos(mach["contact_angle"])
    out = 1.0 if mach["arrangement"] == "O" else -1.0
    yz, nrm = [], []
    for (y, z), nz in ((mach["upper_yz"], c), (mach["lower_yz"], -c)):
        for side in (-1.0, 1.0):
            yz.append((side * y, z))
            nrm.append((0.0, out * side * s, nz))
    n = mach["n_elements"]
    xi = (np.arange(n) - (n - 1) / 2) * mach["pitch"]
    pts = np.array([[(x, y, z) for x in xi] for (y, z) in yz])
    return pts, np.array(nrm), xi


def rigid_tie(slave: int, d, ref: int, rot: int) -> list[str]:
    """Linear MPCs ``u_slave = u_ref + θ × d`` (θ: the translations of node ``rot``)."""
    dx, dy, dz = d
    rows = []
    for comp, terms in (
        (1, [(rot, 2, -dz), (rot, 3, dy)]),
        (2, [(rot, 3, -dx), (rot, 1, dz)]),
        (3, [(rot, 1, -dy), (rot, 2, dx)]),
    ):
        terms = [(slave, comp, 1.0), (ref, comp, -1.0)] + [t for t in terms if abs(t[2]) > 1e-15]
        rows += ["*EQUATION", str(len(terms))]
        flat = [f"{n}, {c}, {w:.12g}" for n, c, w in terms]
        rows += [", ".join(flat[i : i + 4]) for i in range(0, len(flat), 4)]
    return rows


def deck_carriages(mach: dict, mesh: dict, first_node: int, first_elem: int, table: np.ndarray):
    """Rigid carriages and nut (linear rigid ties to a reference and a rotation node), the
    element springs (SPRINGA) and their ground nodes.

    The ties are the small-rotation rigid-body constraints ``u = u_ref + θ × d`` written as
    ``*EQUATION``s; every table node in a footprint (all through the thickness) and every element
    contact node is tied. Returns (lines, info) with the node numbers later sections need.
    """
    t = mach["thickness"]
    pts, nrm, xi = carriage_geometry(mach)
    node, elem = first_node, first_elem
    lines, springs, refs = [], [], []
    coords = mesh["coords"]
    for p in patches(mach):
        ref, rot = node, node + 1
        node += 2
        origin = np.array([p["x"], p["y"], -t / 2])
        lines += [
            "*NODE, NSET=NREF",
            f"{ref}, {origin[0]:.12g}, {origin[1]:.12g}, {origin[2]:.12g}",
            "*NODE, NSET=NROT",
            f"{rot}, {origin[0]:.12g}, {origin[1]:.12g}, {origin[2]:.12g}",
        ]
        inside = np.flatnonzero(
            (abs(coords[:, 0] - p["x"]) <= p["hx"] + 1e-9)
            & (abs(coords[:, 1] - p["y"]) <= p["hy"] + 1e-9)
        )
        ties = [(int(i) + 1, coords[i] - origin) for i in inside]
        if "rail" in p:  # a carriage: one node per rolling element, a spring to the ground
            a_nodes, b_nodes = [], []
            for r in range(pts.shape[0]):
                for j in range(pts.shape[1]):
                    A = origin + pts[r, j]
                    B = A - SPRING_LENGTH * nrm[r]
                    a_nodes.append((node, A))
                    b_nodes.append((node + 1, B))
                    ties.append((node, pts[r, j]))
                    springs.append(
                        {
                            "elem": elem,
                            "A": node,
                            "B": node + 1,
                            "rail": p["rail"],
                            "s0": p["x"] + xi[j],
                            "n": nrm[r],
                            "row": r,
                        }
                    )
                    node += 2
                    elem += 1
            lines.append("*NODE, NSET=NCONTACT")
            lines += [f"{i}, {v[0]:.12g}, {v[1]:.12g}, {v[2]:.12g}" for i, v in a_nodes]
            lines.append("*NODE, NSET=NGROUND")
            lines += [f"{i}, {v[0]:.12g}, {v[1]:.12g}, {v[2]:.12g}" for i, v in b_nodes]
        for slave, d in ties:
            lines += rigid_tie(slave, d, ref, rot)
        refs.append((ref, rot))
    lines.append("*ELEMENT, TYPE=SPRINGA, ELSET=EBALLS")
    lines += [f"{s['elem']}, {s['A']}, {s['B']}" for s in springs]
    lines += ["*SPRING, ELSET=EBALLS, NONLINEAR", ""]
    lines += [f"{f:.12e}, {e:.12e}" for f, e in table]
    return lines, {"springs": springs, "refs": refs, "next_node": node, "next_elem": elem}


def deck_screw(mach: dict, nut_ref: int, elem: int, x: float) -> list[str]:
    """The screw: an axial spring to ground at the nut, k = EA / (L0 + x)."""
    k = mach["screw_EA"] / (mach["screw_L0"] + x)
    return [
        "*ELEMENT, TYPE=SPRING1, ELSET=ESCREW",
        f"{elem}, {nut_ref}",
        "*SPRING, ELSET=ESCREW",
        "1",
        f"{k:.12e}",
    ]


def deck_step(mach: dict, springs: list[dict], rails, x: float) -> list[str]:
    """The nonlinear static step: rail errors at the ground nodes, gravity, output requests."""
    bc = []
    for s in springs:
        ey, ez = rail_profile(rails[s["rail"]], np.array([x + s["s0"]]))
        bc += [
            f"{s['B']}, 1, 1, 0.",
            f"{s['B']}, 2, 2, {ey[0]:.12e}",
            f"{s['B']}, 3, 3, {ez[0]:.12e}",
        ]
    return [
        "*STEP, NLGEOM, INC=200",
        "*STATIC",
        "1.0, 1.0, 1e-4, 1.0",
        # tight equilibrium: residual and correction criteria 1e-6 instead of 5e-3 and 1e-2
        "*CONTROLS, PARAMETERS=FIELD",
        "1e-6, 1e-6, 0., 0., 0.02, 1e-5, 1e-3, 1e-8",
        "*CONTROLS, PARAMETERS=TIME INCREMENTATION",
        "12, 20, 9, 60, 10, 4, 5, 3",
        "*BOUNDARY",
        *bc,
        "*DLOAD",
        f"ETABLE, GRAV, {mach['gravity']:.12g}, 0., 0., -1.",
        "*NODE FILE",
        "U",
        "*NODE PRINT, NSET=NREF",
        "U",
        "*EL PRINT, ELSET=EBALLS",
        "S",
        "*END STEP",
    ]


def write_deck(mach, mesh, law, rails, x, table) -> tuple[str, dict]:
    """The whole deck for table position ``x`` (m): one function per section above."""
    lines = ["*HEADING", f"diffguide CalculiX reference, x = {x:.6f} m"]
    lines += deck_table(mach, mesh)
    n0 = len(mesh["coords"]) + 1
    e0 = len(mesh["elements"]) + 1
    body, info = deck_carriages(mach, mesh, n0, e0, table)
    lines += body
    lines += deck_screw(mach, info["refs"][-1][0], info["next_elem"], x)
    lines += deck_step(mach, info["springs"], rails, x)
    return "\n".join(lines) + "\n", info


# ---------------------------------------------------------------------------------------------
# running ccx and reading its results
# ---------------------------------------------------------------------------------------------


def ccx_version() -> str:
    out = subprocess.run(["ccx", "-v"], capture_output=True, text=True).stdout
    return " ".join(out.split())


def run_ccx(deck: str, workdir: Path, name: str = "job") -> Path:
    (workdir / f"{name}.inp").write_text(deck)
    proc = subprocess.run(
        ["ccx", "-i", name],
        cwd=workdir,
        capture_output=True,
        text=True,
        env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"},
    )
    log = proc.stdout + proc.stderr
    (workdir / f"{name}.log").write_text(log)
    if proc.returncode != 0 or "*ERROR" in log or "Job finished" not in log:
        raise RuntimeError(f"ccx failed in {workdir}: {log[-2000:]}")
    if "nan" in log.lower().split("job finished")[0][-5000:]:
        raise RuntimeError(f"ccx produced NaN in {workdir}")
    return workdir / f"{name}.frd"


def read_frd(path: Path) -> tuple[dict, dict]:
    """Node coordinates and the last displacement block of a .frd file: {node: xyz}."""
    coords, disp = {}, {}
    block = None
    with open(path) as f:
        for line in f:
            if line.startswith("    2C"):
                block = "coords"
                continue
            if line.startswith(" -4  DISP"):
                block = "disp"
                disp = {}
                continue
            if line.startswith(" -3"):
                block = None
                continue
            if block and line.startswith(" -1"):
                n = int(line[3:13])
                vals = [float(line[13 + 12 * i : 25 + 12 * i]) for i in range(3)]
                (coords if block == "coords" else disp)[n] = np.array(vals)
    return coords, disp


def element_approaches(springs: list[dict], disp: dict, law: dict) -> np.ndarray:
    """Approach of every element, ``a = g0 + n·(u_B - u_A)`` (m), from the solved displacements."""
    return np.array([law["g0"] + s["n"] @ (disp[s["B"]] - disp[s["A"]]) for s in springs])


def point_motion(mach: dict, mesh: dict, disp: dict) -> dict:
    """(ux, uy, uz, θx, θy, θz) of each control point (module docstring), m and rad.

    Nodes are found in the mesh the deck was written from (the .frd file rounds coordinates to
    five digits).
    """
    t = mach["thickness"]
    xyz = mesh["coords"]

    def at(x, y, z):
        d = np.abs(xyz[:, 0] - x) + np.abs(xyz[:, 1] - y) + np.abs(xyz[:, 2] - z)
        k = int(np.argmin(d))
        if d[k] > 1e-9:
            raise ValueError(f"no table node at ({x}, {y}, {z})")
        return disp[k + 1]

    def mid(x, y):
        return 0.5 * (at(x, y, t / 2) + at(x, y, -t / 2))

    xs, ys = mesh["xs"], mesh["ys"]
    out = {}
    for name, (x, y) in mach["points"].items():
        top, bot = at(x, y, t / 2), at(x, y, -t / 2)
        i = int(np.argmin(abs(xs - x)))
        j = int(np.argmin(abs(ys - y)))
        i0, i1 = max(i - 1, 0), min(i + 1, len(xs) - 1)
        j0, j1 = max(j - 1, 0), min(j + 1, len(ys) - 1)
        duy_dx = (mid(xs[i1], y)[1] - mid(xs[i0], y)[1]) / (xs[i1] - xs[i0])
        dux_dy = (mid(x, ys[j1])[0] - mid(x, ys[j0])[0]) / (ys[j1] - ys[j0])
        out[name] = np.array(
            [
                top[0],
                top[1],
                top[2],
                -(top[1] - bot[1]) / t,
                (top[0] - bot[0]) / t,
                0.5 * (duy_dx - dux_dy),
            ]
        )
    return out


def solve_position(mach, mesh, law, rails, x, table):
    """Run one position: ({point: motion}, element approaches (m))."""
    deck, info = write_deck(mach, mesh, law, rails, x, table)
    with tempfile.TemporaryDirectory(prefix="ccx_") as tmp:
        _, disp = read_frd(run_ccx(deck, Path(tmp)))
    return point_motion(mach, mesh, disp), element_approaches(info["springs"], disp, law)


def sweep(mach, mesh, law, rails, positions, table, workers=2):
    """Joint errors (n_pos, n_points, 6) relative to x = 0 over ``positions`` (m)."""
    xs = sorted(set([0.0, *[float(x) for x in positions]]))
    with concurrent.futures.ThreadPoolExecutor(max_workers=workers) as pool:
        results = dict(
            zip(xs, pool.map(lambda x: solve_position(mach, mesh, law, rails, x, table), xs))
        )
    names = list(mach["points"])
    ref = results[0.0][0]
    errors = np.array([[results[float(x)][0][n] - ref[n] for n in names] for x in positions])
    a = np.concatenate([results[x][1] for x in xs])
    stats = {
        "max_element_force_N": float(law_force(a.max(), law)),
        "min_approach_um": float(a.min() * 1e6),
        "max_approach_um": float(a.max() * 1e6),
        "lifted_off_elements": int(sum((results[x][1] <= -law["eps"]).sum() for x in xs)),
    }
    return errors, stats


# ---------------------------------------------------------------------------------------------
# output
# ---------------------------------------------------------------------------------------------


def write_csv(path: Path, names, positions, errors, points):
    lines = ["position_mm,point,x_mm,y_mm,EXX_um,EYX_um,EZX_um,EAX_urad,EBX_urad,ECX_urad"]
    for k, x in enumerate(positions):
        for p, name in enumerate(names):
            xy = points[name]
            vals = ",".join(f"{v * 1e6:.6f}" for v in errors[k, p])
            lines.append(f"{x * 1e3:.3f},{name},{xy[0] * 1e3:.3f},{xy[1] * 1e3:.3f},{vals}")
    path.write_text("\n".join(lines) + "\n")


DEFAULT_MESH = {"nx": 40, "ny": 20, "element": "C3D20R", "layers": 1}
TABLE_RATIO = 0.06
FINE_TABLE_RATIO = 0.035  # the finest that fits ccx's 200 table points

#: the mesh study: (label, mesh) on majda2012, variant 3, four positions.
STUDY_MESHES = [
    ("C3D20R 10x5", {"nx": 10, "ny": 5, "element": "C3D20R", "layers": 1}),
    ("C3D20R 20x10", {"nx": 20, "ny": 10, "element": "C3D20R", "layers": 1}),
    ("C3D20R 40x20", {"nx": 40, "ny": 20, "element": "C3D20R", "layers": 1}),
    ("C3D20R 40x20, 2 layers", {"nx": 40, "ny": 20, "element": "C3D20R", "layers": 2}),
    ("C3D8I 40x20 (S4-like)", {"nx": 40, "ny": 20, "element": "C3D8I", "layers": 1}),
]
STUDY_POSITIONS = [-0.35, -0.175, 0.175, 0.35]


def mesh_for(mach, spec):
    args = (spec["nx"], spec["ny"], spec["element"], spec["layers"], spec.get("rib_layers", 2))
    return make_mesh(mach, *args)


def relative_change(errors, best):
    """Largest |errors - best| per point and quantity, in % of ``best``'s range over x; the
    maximum over points and quantities whose range exceeds 1 % of the largest range of its kind
    (µm or µrad)."""
    rng = best.max(0) - best.min(0)
    dev = np.abs(errors - best).max(0)
    out = []
    for q in range(6):
        kind = slice(0, 3) if q < 3 else slice(3, 6)
        ok = rng[:, q] > 0.01 * rng[:, kind].max()
        out.append(float((100 * dev[ok, q] / rng[ok, q]).max()) if ok.any() else 0.0)
    return out


def study(workers: int, out: Path) -> None:
    """Mesh convergence (variant 3) and spring-table density (lift-off case) on majda2012."""
    mach = read_machine(HERE / "machines" / "majda2012.toml")
    law = element_law(mach)
    table = spring_table(law, TABLE_RATIO)
    cache = Path(tempfile.gettempdir()) / "diffguide_ccx_study.npz"
    results = dict(np.load(cache)) if cache.exists() else {}
    lines = []
    for label, spec in STUDY_MESHES:
        if label in results:
            continue
        mesh = mesh_for(mach, spec)
        t0 = datetime.datetime.now()
        errors, _ = sweep(mach, mesh, law, CASES["variant3"], STUDY_POSITIONS, table, workers)
        dt = (datetime.datetime.now() - t0).total_seconds()
        results[label] = errors
        np.savez(cache, **results)
        print(f"{label}: {len(mesh['coords'])} nodes, {dt:.0f} s", flush=True)
    best = results["C3D20R 40x20, 2 layers"]
    lines.append("| mesh | " + " | ".join(QUANTITIES) + " |")
    lines.append("|---" * 7 + "|")
    for label, errors in results.items():
        ch = relative_change(errors, best)
        lines.append(f"| {label} | " + " | ".join(f"{v:.2f} %" for v in ch) + " |")
    mesh = mesh_for(mach, DEFAULT_MESH)
    pos = MACHINES["majda2012"]["positions"]["liftoff"]
    coarse, stats = sweep(mach, mesh, law, CASES["liftoff"], pos, table, workers)
    fine_table = spring_table(law, FINE_TABLE_RATIO)
    fine, _ = sweep(mach, mesh, law, CASES["liftoff"], pos, fine_table, workers)
    ch = relative_change(coarse, fine)
    lines.append("")
    lines.append(
        f"spring table: {len(table)} vs {len(fine_table)} points "
        f"(step ratio {TABLE_RATIO} vs {FINE_TABLE_RATIO}), lift-off case, {stats}: "
        "largest change " + ", ".join(f"{q} {v:.3f} %" for q, v in zip(QUANTITIES, ch))
    )
    text = "\n".join(lines) + "\n"
    (out / "study.md").write_text(text)
    print(text)


#: the ribbed table's mesh study: (label, mesh, cases); the finest is last.
RIB_STUDY_MESHES = [
    (
        "40x20, 1 + 2 layers",
        {"nx": 40, "ny": 20, "layers": 1, "rib_layers": 2},
        ("variant3", "variant2"),
    ),
    ("80x40, 1 + 2 layers", {"nx": 80, "ny": 40, "layers": 1, "rib_layers": 2}, ("variant3",)),
    (
        "40x20, 2 + 2 layers",
        {"nx": 40, "ny": 20, "layers": 2, "rib_layers": 2},
        ("variant3", "variant2"),
    ),
    (
        "40x20, 2 + 4 layers",
        {"nx": 40, "ny": 20, "layers": 2, "rib_layers": 4},
        ("variant3", "variant2"),
    ),
]


def rib_study(workers: int) -> None:
    """Mesh convergence of the ribbed machine (plate + rib brick layers, in-plane grid): the
    largest change from the finest model per quantity (:func:`relative_change`), printed."""
    mach = read_machine(HERE / "machines" / "ribbed.toml")
    law = element_law(mach)
    table = spring_table(law, TABLE_RATIO)
    results = {}
    for label, spec, cases in RIB_STUDY_MESHES:
        mesh = mesh_for(mach, {"element": "C3D20R", **spec})
        for case in cases:
            t0 = datetime.datetime.now()
            rails = CASES[case]
            results[label, case], _ = sweep(mach, mesh, law, rails, STUDY_POSITIONS, table, workers)
            dt = (datetime.datetime.now() - t0).total_seconds()
            print(f"{label}, {case}: {len(mesh['coords'])} nodes, {dt:.0f} s", flush=True)
    best = RIB_STUDY_MESHES[-1][0]
    print("| mesh | case | " + " | ".join(QUANTITIES) + " |\n" + "|---" * 8 + "|")
    for (label, case), errors in results.items():
        ch = relative_change(errors, results[best, case])
        print(f"| {label} | {case} | " + " | ".join(f"{v:.2f} %" for v in ch) + " |")
    a, b = (results[RIB_STUDY_MESHES[k][0], "variant3"] for k in (0, 1))
    ch = relative_change(a, b)
    print("| in-plane: 40x20 vs 80x40 | variant3 | " + " | ".join(f"{v:.2f} %" for v in ch) + " |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--machines", nargs="*", default=list(MACHINES))
    ap.add_argument("--cases", nargs="*", default=None)
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--study", action="store_true", help="only the mesh and table studies")
    ap.add_argument("--rib-study", action="store_true", help="only the ribbed mesh study")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.rib_study:
        rib_study(args.workers)
        return
    if args.study:
        study(args.workers, HERE)
        return
    meta = {
        "generator": "reference/calculix/make_reference.py",
        "ccx_version": ccx_version(),
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "mesh": DEFAULT_MESH,
        "spring_table_ratio": TABLE_RATIO,
        "machines": {},
    }
    meta_path = args.out / "reference.json"
    if meta_path.exists():
        old = json.loads(meta_path.read_text())
        meta["machines"] = old.get("machines", {})
        if set(args.machines) != set(MACHINES):  # a partial run: the file's date stays
            meta["date"] = old.get("date", meta["date"])
    for mname in args.machines:
        spec = MACHINES[mname]
        toml = HERE / "machines" / spec["toml"]
        mach = read_machine(toml)
        law = element_law(mach)
        table = spring_table(law, TABLE_RATIO)
        mesh = mesh_for(mach, DEFAULT_MESH)
        shutil.copy(toml, args.out / f"{mname}.toml")
        mmeta = meta["machines"].setdefault(mname, {"cases": {}})
        mmeta.update(
            date=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            toml=f"{mname}.toml",
            preload_force_N=mach["preload_force"],
            preload_approach_um=law["g0"] * 1e6,
            hertz_contact_um_at_10N=law["c_contact"] * 10 ** (2 / 3) * 1e6,
            mesh_nodes=len(mesh["coords"]),
            mesh_elements=len(mesh["elements"]),
            spring_table_points=len(table),
        )
        for case in args.cases or spec["cases"]:
            rails = CASES[case]
            positions = spec["positions"].get(case, spec["positions"]["default"])
            mesh_spec = spec.get("mesh", {}).get(case, DEFAULT_MESH)
            case_mesh = mesh_for(mach, mesh_spec)
            t0 = datetime.datetime.now()
            errors, forces = sweep(mach, case_mesh, law, rails, positions, table, args.workers)
            dt = (datetime.datetime.now() - t0).total_seconds()
            fname = f"{mname}_{case}.csv"
            write_csv(args.out / fname, list(mach["points"]), positions, errors, mach["points"])
            mmeta["cases"][case] = {
                "csv": fname,
                "rails": list(rails),
                "positions_mm": [round(x * 1e3, 6) for x in positions],
                "mesh": {**mesh_spec, "nodes": len(case_mesh["coords"])},
                "ccx_seconds": round(dt, 1),
                **forces,
            }
            print(f"{mname} {case}: {len(positions)} positions in {dt:.0f} s, {forces}", flush=True)
            meta_path.write_text(json.dumps(meta, indent=1) + "\n")


if __name__ == "__main__":
    main()
