r"""The table from the user's FE code: a statically reduced (superelement) stiffness matrix.

A :class:`ReducedMatrix` is the table's stiffness reduced onto a set of retained DOF ``r`` (each
a node number and a DOF 1…6: ``ux, uy, uz, rx, ry, rz``), SI units, with the reduced self-weight
loads ``f_r`` (N, N·m), and the coordinates of the retained nodes (m, in the table frame: origin
at the table centre, X the travel, Z up, as a machine file's positions):

    K_r u_r = f_r + F_r,

``F_r`` the forces the carriages / the nut apply to the table. A CAD casting's reduction keeps:

- one **interface node** per carriage and one for the nut, tied rigidly to the footprint (CalculiX
  ``*RIGID BODY``: its ``REF NODE`` carries the translations, its ``ROT NODE`` the rotations as
  that node's DOF 1-3; Nastran/Abaqus: an RBE2 / ``*KINEMATIC COUPLING`` reference node with
  DOF 1-6) at the centre of the carriage's top face;
- one node per **control point** on the table top (translations). A point's rotations come
  either from rotational DOF of its own (a rotation node, or DOF 4-6), or — to leave the table
  untouched by a local rigid tie — from a few retained **neighbour nodes** around it: the
  small rotation ``θ`` that best fits their translations relative to the point in least squares,
  ``u_i - u_P ≈ θ × (p_i - p_P)`` (for four neighbours at ±h along X and Y on a flat top: the
  central differences ``θx = ∂uz/∂y``, ``θy = -∂uz/∂x``, ``θz = ½(∂uy/∂x - ∂ux/∂y)``, error
  O(h²)). Those are the rotations of the top face (its slope: what a level standing there
  tilts by). With a retained node **below** the point on the underside as well, roll and pitch
  are instead the rotation of the material fibre through the point, ``θx = -(u_y,top -
  u_y,below)/t``, ``θy = (u_x,top - u_x,below)/t`` (``t`` the distance between the two), which is
  what a shell model's rotations are (diffguide's own plate); the two differ by the transverse
  shear strain at the point. With the nodes under the neighbours too, yaw is the mid-surface's
  in-plane rotation (the mean of top and underside), as a shell's.

:func:`table_from_reduced` condenses every DOF other than the interfaces' out exactly,

    K = K_bb - K_bp K_pp⁻¹ K_pb,   f = f_b - K_bp K_pp⁻¹ f_p,
    [u_P, θ_P] = S u_r = (S_b - S_p K_pp⁻¹ K_pb) u_b + S_p K_pp⁻¹ f_p = R u_b + r0,

(``S`` selects / fits the point motion from the retained DOF) and returns the
:class:`~diffguide.fe.condense.CondensedTable` the machine uses in place of the plate's.
``node_modes`` are not available for an imported matrix (no mesh): the table's ``nodes`` are
empty, and whatever needs the motion of every node (the error field over the table) refuses it.
"""

from collections.abc import Mapping, Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._core.limits import MAX_REDUCED_DOFS
from .._core.rigid import rigid_transfer, skew
from .condense import CondensedTable

#: Relative tolerance of the rigid-body check: ``‖K Φ‖ ≤ tol ‖K‖ ‖Φ‖`` (a free-floating
#: table's reduced stiffness has the six rigid motions in its null space).
RIGID_TOL = 1e-6
#: Largest magnitude accepted in K (SI: N/m, N/rad, N·m/rad) and f (N, N·m). A machine table's
#: stiffness is ~1e8-1e10 N/m and a penalty tie's a few decades above; 1e30 is far beyond any
#: physical value, yet the products of a few entries that the condensation, the rigid-body
#: check and the solves form stay far below the overflow (~1.8e308) that would turn them into
#: inf and NaN (and a NaN passes a comparison that should fail).
MAX_ENTRY = 1e30


class ReducedMatrix(eqx.Module):
    """A statically reduced stiffness matrix with its retained DOF, SI units.

    Attributes:
        K: (n, n) symmetric stiffness (N/m, N/rad, N·m/rad) over ``dofs``.
        dofs: the retained DOF ``(node, dof)``, dof 1-6 = ux, uy, uz, rx, ry, rz (a CalculiX
            ``ROT NODE``'s DOF 1-3 are rotations: :func:`table_from_reduced` is told which
            nodes are rotation nodes).
        f: (n,) reduced self-weight loads (N, N·m), or zeros.
        source: where it came from (a file name), for error messages.
    """

    K: np.ndarray
    dofs: tuple[tuple[int, int], ...] = eqx.field(static=True)
    f: np.ndarray
    source: str = eqx.field(static=True, default="reduced matrix")

    def __check_init__(self):
        n = len(self.dofs)
        if np.shape(self.K) != (n, n):
            raise ValueError(
                f"{self.source}: K must be ({n}, {n}) for {n} retained DOF, got {np.shape(self.K)}"
            )
        if np.shape(self.f) != (n,):
            raise ValueError(f"{self.source}: f must have {n} entries, got {np.shape(self.f)}")
        if len(set(self.dofs)) != n:
            raise ValueError(f"{self.source}: a retained (node, dof) appears twice")
        if n > MAX_REDUCED_DOFS:
            raise ValueError(f"{self.source}: {n} retained DOF; allowed 1..{MAX_REDUCED_DOFS}")
        for node, d in self.dofs:
            if not 1 <= d <= 6:
                raise ValueError(f"{self.source}: node {node} has DOF {d}; allowed 1..6")
        K = np.asarray(self.K)
        self._check_entries(K, "K")
        self._check_entries(np.asarray(self.f), "f")
        scale = np.abs(K).max() if K.size else 0.0
        if np.abs(K - K.T).max(initial=0.0) > 1e-8 * scale:
            raise ValueError(f"{self.source}: K is not symmetric")

    def _check_entries(self, a: np.ndarray, name: str) -> None:
        """``ValueError`` naming the file and the first entry of ``a`` (``K`` or ``f``) that is
        not finite or exceeds :data:`MAX_ENTRY` in magnitude (SI)."""
        with np.errstate(invalid="ignore"):
            bad = ~(np.abs(a) <= MAX_ENTRY)  # NaN included
        if not bad.any():
            return
        where = np.argwhere(bad)[0]
        dofs = " and ".join(f"node {self.dofs[i][0]} DOF {self.dofs[i][1]}" for i in where)
        index = ",".join(str(i + 1) for i in where)
        raise ValueError(
            f"{self.source}: {name}[{index}] ({dofs}) = {a[tuple(where)]:g}"
            + (f" (and {int(bad.sum()) - 1} more)" if bad.sum() > 1 else "")
            + f": every entry must be finite and at most {MAX_ENTRY:g} in magnitude (SI); "
            "a larger one is not a stiffness and overflows the solves")

    def index(self, node: int, dof: int, what: str) -> int:
        """Row of ``(node, dof)``; ``KeyError`` naming ``what`` if it is not retained."""
        try:
            return self.dofs.index((int(node), int(dof)))
        except ValueError:
            raise KeyError(
                f"{self.source}: {what} needs node {node} DOF {dof}, which is not a retained DOF "
                "of the reduced matrix (retain it in the reduction)"
            ) from None

    def scaled(self, length_unit: float) -> "ReducedMatrix":
        """The matrix in SI from a file in length unit ``length_unit`` (m per unit, e.g. 1e-3
        for mm) and N: translations ``u = L u'``, moments ``M = L M'``, so
        ``K_tt = K'_tt / L``, ``K_tr = K'_tr``, ``K_rr = L K'_rr``, ``f_t = f'_t``,
        ``f_r = L f'_r`` (rotation DOF: 4-6, so merge a CalculiX rotation node's DOF with
        :func:`with_rotation_nodes` first)."""
        rot = np.array([d > 3 for _, d in self.dofs])
        s = np.where(rot, 1.0, 1.0 / length_unit)  # u' = s u
        L = float(length_unit)
        K = L * (s[:, None] * np.asarray(self.K) * s[None, :])
        f = L * s * np.asarray(self.f)
        return ReducedMatrix(K=K, dofs=self.dofs, f=f, source=self.source)


def with_rotation_nodes(rm: ReducedMatrix, rot_nodes: Mapping[int, int]) -> ReducedMatrix:
    """``rm`` with each rotation node's DOF 1-3 renamed as DOF 4-6 of its reference node
    (CalculiX ``*RIGID BODY, REF NODE=a, ROT NODE=b``: ``{b: a}``)."""
    dofs = []
    for node, d in rm.dofs:
        if node in rot_nodes:
            if d > 3:
                raise ValueError(f"{rm.source}: rotation node {node} has DOF {d}; allowed 1..3")
            dofs.append((int(rot_nodes[node]), d + 3))
        else:
            dofs.append((node, d))
    return ReducedMatrix(K=rm.K, dofs=tuple(dofs), f=rm.f, source=rm.source)


class RetainedPoint(eqx.Module):
    """A control point of an imported table: a retained node, and how its rotation is known.

    Attributes:
        name: the control point's name (as in the machine file).
        node: the retained node on the table top at the point (its DOF 1-3 retained).
        neighbours: retained nodes around it (DOF 1-3) whose translations give the rotation by
            least squares (module docstring); empty: the node's own DOF 4-6 must be retained.
        rigid_to: the index of the interface (in ``interfaces``) whose rigid tie holds the point
            (a point on a carriage or nut footprint): it moves with that interface's reference
            node, and only its coordinates are needed (its DOF need not be retained).
        below: a retained node (DOF 1-3) straight under the point on the underside, or None:
            roll and pitch then come from the fibre between the two (module docstring), yaw
            from the neighbours. neighbours_below: the nodes under the neighbours, in their
            order (needs ``below``): yaw from the mid-surface (the mean of each top node and
            the one below it), as a shell's in-plane rotation, instead of the top face's.
    """

    name: str = eqx.field(static=True)
    node: int = eqx.field(static=True)
    neighbours: tuple[int, ...] = eqx.field(static=True, default=(), converter=tuple)
    rigid_to: int | None = eqx.field(static=True, default=None)
    below: int | None = eqx.field(static=True, default=None)
    neighbours_below: tuple[int, ...] = eqx.field(static=True, default=(), converter=tuple)


def _coords(coords: Mapping[int, Sequence[float]], node: int, what: str, source: str):
    if node not in coords:
        raise KeyError(f"{source}: {what} needs the coordinates of node {node}, not given")
    xyz = np.asarray(coords[node], dtype=float)
    if xyz.shape != (3,) or not np.all(np.isfinite(xyz)):
        raise ValueError(f"{source}: node {node} coordinates must be 3 finite numbers (m)")
    return xyz


def _point_rows(rm, coords, pt: RetainedPoint, interfaces) -> np.ndarray:
    """``S`` for one point: (6, n), its (u, θ) as a linear map of the retained DOF."""
    n = len(rm.dofs)
    S = np.zeros((6, n))
    what = f"control point {pt.name!r}"
    if pt.rigid_to is not None:
        if not 0 <= pt.rigid_to < len(interfaces):
            raise ValueError(f"{rm.source}: {what}: rigid_to = {pt.rigid_to} is not an "
                             f"interface index (0..{len(interfaces) - 1})")
        ref = interfaces[pt.rigid_to]
        T = rigid_transfer(_coords(coords, pt.node, what, rm.source)
                           - _coords(coords, ref, what, rm.source), np)
        for d in range(6):
            S[:, rm.index(ref, d + 1, what + " (its interface)")] = T[:, d]
        return S
    for k in range(3):
        S[k, rm.index(pt.node, k + 1, what)] = 1.0
    if not pt.neighbours:
        if pt.below is not None:
            raise ValueError(f"{rm.source}: {what}: a node below needs neighbours too (they "
                             "give the yaw)")
        for k in range(3):
            S[3 + k, rm.index(pt.node, k + 4, what + " (its rotations; or give neighbours)")] = 1
        return S
    p0 = _coords(coords, pt.node, what, rm.source)
    # u_i - u_P = θ × d_i = -[d_i]× θ: least squares over the neighbours
    A = np.concatenate([-skew(_coords(coords, q, what, rm.source) - p0, np) for q in pt.neighbours])
    if np.linalg.matrix_rank(A) < 3:
        raise ValueError(
            f"{rm.source}: {what}: neighbours {pt.neighbours} do not fix a rotation (give at "
            "least two not in line with the point)"
        )
    G = np.linalg.pinv(A)  # (3, 3 n_nb)
    for j, q in enumerate(pt.neighbours):
        for k in range(3):
            col = G[:, 3 * j + k]
            S[3:, rm.index(q, k + 1, what + " (a neighbour)")] += col
            S[3:, rm.index(pt.node, k + 1, what)] -= col
    if pt.below is not None:
        S[3:5] = _fibre_rows(rm, coords, pt, what)
    if pt.neighbours_below:
        S[5] = _mid_surface_yaw(rm, coords, pt, G[2], what)
    return S


def _mid_surface_yaw(rm, coords, pt: RetainedPoint, g, what) -> np.ndarray:
    """The row of ``θz`` from the mid-surface: the least-squares row ``g`` of the top-face
    neighbours applied to the mean of each top node and the node below it."""
    if pt.below is None or len(pt.neighbours_below) != len(pt.neighbours):
        raise ValueError(f"{rm.source}: {what}: neighbours_below needs below, and one node per "
                         f"neighbour ({len(pt.neighbours)})")
    row = np.zeros(len(rm.dofs))
    for top, low in zip(pt.neighbours, pt.neighbours_below):  # the point's: _fibre_rows
        _straight_under(rm, coords, top, low, what)
    for j, (q, qb) in enumerate(zip(pt.neighbours, pt.neighbours_below)):
        for k in range(3):
            for node, sign in ((q, 0.5), (qb, 0.5), (pt.node, -0.5), (pt.below, -0.5)):
                row[rm.index(node, k + 1, what + " (mid-surface yaw)")] += sign * g[3 * j + k]
    return row


def _straight_under(rm, coords, top: int, low: int, what) -> np.ndarray:
    """``p_low - p_top`` (m), refused unless ``low`` lies straight under ``top``."""
    d = _coords(coords, low, what + " (below)", rm.source) - _coords(coords, top, what,
                                                                      rm.source)
    if not (d[2] < 0 and np.hypot(d[0], d[1]) <= 1e-6 * abs(d[2])):
        raise ValueError(f"{rm.source}: {what}: node {low} (below) is not straight under node "
                         f"{top}: offset {np.round(d * 1e3, 6).tolist()} mm")
    return d


def _fibre_rows(rm, coords, pt: RetainedPoint, what) -> np.ndarray:
    """Rows of ``(θx, θy)``: the rotation of the fibre from the point to the node ``below``
    (``u_below - u_P = θ × d``, ``d = p_below - p_P`` straight down)."""
    d = _straight_under(rm, coords, pt.node, pt.below, what)
    rows = np.zeros((2, len(rm.dofs)))
    # (θ × d)_x = θy dz, (θ × d)_y = -θx dz
    for k, (row, sign) in enumerate(((1, -1.0), (0, 1.0))):  # θx from uy, θy from ux
        rows[k, rm.index(pt.below, row + 1, what + " (below)")] += sign / d[2]
        rows[k, rm.index(pt.node, row + 1, what)] -= sign / d[2]
    return rows


def check_rigid_modes(rm: ReducedMatrix, coords: Mapping[int, Sequence[float]],
                      tol: float = RIGID_TOL) -> float:
    """``‖K Φ‖ / (‖K‖ ‖Φ‖)`` for the six rigid motions ``Φ`` of the retained nodes; a
    ``ValueError`` if above ``tol`` (the matrix is not a free-floating table's: a constrained
    DOF, a wrong DOF map, or a reduction that did not condense — CalculiX 2.20's
    ``*SUBSTRUCTURE GENERATE`` writes the uncondensed ``K_bb``; see the docs)."""
    Phi = np.zeros((len(rm.dofs), 6))
    for i, (node, d) in enumerate(rm.dofs):
        xyz = _coords(coords, node, "the rigid-body check", rm.source)
        Phi[i] = rigid_transfer(xyz, np)[d - 1]
    K = np.asarray(rm.K, float)
    scale = np.abs(K).max(initial=0.0)
    with np.errstate(all="ignore"):
        Ks = K / scale  # the ratio is scale-free; scaled, its norms cannot overflow
        ratio = float(np.linalg.norm(Ks @ Phi) / (np.linalg.norm(Ks) * np.linalg.norm(Phi)))
    if not ratio <= tol:  # NaN (a zero, non-finite or overflowing matrix) fails too
        raise ValueError(
            f"{rm.source}: the matrix does not leave the table's rigid motions free "
            f"(‖KΦ‖/‖K‖‖Φ‖ = {ratio:.2e} > {tol:.0e}): a DOF is constrained, the node "
            "coordinates or rotation nodes are wrong, or the file holds an uncondensed matrix"
        )
    return ratio


def weight_at_interfaces(ref_points, mass: float, cog, gravity: float = 9.81) -> np.ndarray:
    """Interface loads (6 per interface; N, N·m) of a table known by its mass (kg) and centre
    of gravity ``cog`` (m), under ``gravity`` (m/s², along -Z): vertical forces ``F_k`` at the
    reference points with the weight's resultant and moments, ``ΣF_k = -m g``,
    ``Σ F_k (x_k, y_k) = -m g (x_c, y_c)``, of least norm. An approximation of the reduced
    self-weight vector: the carriage loads of a rigid table (exact for three interfaces not in
    line), with no sag between them (the sag at a point is a constant; it cancels from the
    joint errors)."""
    ref = np.asarray(ref_points, dtype=float)
    if not mass > 0:
        raise ValueError(f"mass must be > 0 kg, got {mass}")
    c = np.asarray(cog, dtype=float)
    A = np.stack([np.ones(len(ref)), ref[:, 0], ref[:, 1]])
    w = mass * gravity
    Fz = np.linalg.lstsq(A, -w * np.array([1.0, c[0], c[1]]), rcond=None)[0]
    if np.abs(A @ Fz + w * np.array([1.0, c[0], c[1]])).max() > 1e-9 * w:
        raise ValueError("the interfaces cannot carry the weight at the centre of gravity "
                         "(all in one line?)")
    f = np.zeros((len(ref), 6))
    f[:, 2] = Fz
    # Fz at a reference point at height z_k: no moment about it (force through the point)
    return f.reshape(-1)


def table_from_reduced(
    rm: ReducedMatrix,
    coords: Mapping[int, Sequence[float]],
    interfaces: Sequence[int],
    points: Sequence[RetainedPoint],
    *,
    weight: tuple[float, Sequence[float], float] | None = None,
    check: bool = True,
) -> CondensedTable:
    """Condense an imported reduced matrix onto its interface nodes (module docstring).

    Args:
        rm: the reduced matrix (SI; rotation nodes already merged, :func:`with_rotation_nodes`).
        coords: ``{node: (x, y, z)}`` (m), at least the interface nodes, the points and their
            neighbours (all retained nodes for the rigid-body check).
        interfaces: one node per carriage (in the machine's carriage order), then the nut's;
            each with its six DOF retained. Reference points = these nodes' coordinates.
        points: the control points, in the machine's point order.
        weight: ``(mass, cog, g)`` (kg, m, m/s²) when the file has no self-weight vector: the
            loads of :func:`weight_at_interfaces` are added to ``f``.
        check: check the six rigid motions are free (:func:`check_rigid_modes`).

    Returns:
        :class:`~diffguide.fe.condense.CondensedTable` with empty ``nodes`` / ``node_modes``.
    """
    n = len(rm.dofs)
    if check:
        check_rigid_modes(rm, coords)
    b = [rm.index(node, d, f"interface {k} (node {node})")
         for k, node in enumerate(interfaces) for d in range(1, 7)]
    if len(set(b)) != len(b):
        raise ValueError(f"{rm.source}: an interface node is given twice")
    p = np.setdiff1d(np.arange(n), b)
    S = (np.concatenate([_point_rows(rm, coords, pt, interfaces) for pt in points])
         if points else np.zeros((0, n)))
    K = np.asarray(rm.K, dtype=float)
    f = np.asarray(rm.f, dtype=float)
    Kpp, Kpb = K[np.ix_(p, p)], K[np.ix_(p, b)]
    try:
        L = np.linalg.cholesky(Kpp)
    except np.linalg.LinAlgError:
        raise ValueError(
            f"{rm.source}: the DOF other than the interfaces' are not held by them (K_pp is not "
            "positive definite): a retained node is not attached to the table"
        ) from None
    X = np.linalg.solve(L.T, np.linalg.solve(L, np.concatenate([Kpb, f[p, None]], axis=1)))
    Kc = K[np.ix_(b, b)] - Kpb.T @ X[:, :-1]
    fc = f[b] - Kpb.T @ X[:, -1]
    R = S[:, b] - S[:, p] @ X[:, :-1]
    r0 = S[:, p] @ X[:, -1]
    ref = np.stack([_coords(coords, node, "an interface", rm.source) for node in interfaces])
    if weight is not None:
        fc = fc + weight_at_interfaces(ref, *weight)
    return CondensedTable(
        K=jnp.asarray(0.5 * (Kc + Kc.T)),
        f=jnp.asarray(fc),
        R=jnp.asarray(R),
        r0=jnp.asarray(r0),
        node_modes=jnp.zeros((0, 6, len(b))),
        node_u0=jnp.zeros((0, 6)),
        ref_points=jnp.asarray(ref),
        nodes=jnp.zeros((0, 3)),
    )


def scaled_table(table: CondensedTable, scale) -> CondensedTable:
    """``table`` with its stiffness scaled by ``scale`` (> 0; may be traced): the imported
    matrix's one structural unknown for a fit (its thickness has no meaning). ``K_r → s K_r``
    scales ``K`` by ``s``, leaves ``R`` (a ratio of stiffnesses) and ``f`` (the loads) unchanged,
    and divides ``r0`` (the sag under the loads) by ``s``; exact, closed form."""
    s = jnp.asarray(scale, dtype=float)
    return CondensedTable(K=s * table.K, f=table.f, R=table.R, r0=table.r0 / s,
                          node_modes=table.node_modes, node_u0=table.node_u0 / s,
                          ref_points=table.ref_points, nodes=table.nodes)
