r"""A carriage (runner block) on its rail: rows of preloaded rolling elements, rigid carriage body.

Carriage frame: origin at the centre of the carriage's top face (where it is bolted to the table),
X along the rail, Y across, Z up. A carriage has ``n_rows`` rows; row ``r`` has its element contact
points at ``(ξ_i, y_r, z_r)`` (the ``n`` offsets ``ξ_i`` are the same for every row: "constant
topology", elements fixed in the carriage frame while the rail is sampled under them) and a unit
load direction ``n_r`` (in the Y–Z plane): the direction of the force an element applies to the
carriage.

With carriage pose ``q = (t, θ)`` (translation, m; small rotation, rad) and rail deviation
``e(s)`` (m) under the element, the approach of element ``j`` is

.. math::  a_j = g_0 - c_j + n_j \cdot \bigl(e(s_j) - t - θ × p_j\bigr),

``g₀`` the preload approach, ``c_j`` an optional end-crowning relief. The elements' wrench on the
carriage (about its origin) is :math:`\sum_j F(a_j)\,[n_j;\; p_j × n_j]`.
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._core.checks import concrete
from .._core.types import Array, Float
from ..contact.laws import AbstractContactLaw, HertzBall, PalmgrenRoller, RivinBall
from ..contact.smoothing import element_energy, element_force, element_stiffness


def _concrete_positive(name, value, unit):
    if not concrete(value):  # traced: checked elsewhere or not at all
        return
    if not bool(np.all(np.asarray(value) > 0)):
        raise ValueError(f"{name} must be > 0 {unit}, got {value!r}")


class Carriage(eqx.Module):
    """A rigid carriage with rows of preloaded rolling elements.

    Arguments:
        law: the element contact law (:class:`~diffguide.contact.HertzBall`, ...).
        row_yz: contact point of each row in the carriage frame, ``(n_rows, 2)`` (y, z) in m.
        row_normals: unit load direction of each row, ``(n_rows, 2)`` (n_y, n_z).
        xi: element offsets along X from the carriage centre, ``(n,)`` in m.
        preload_force: force per element at preload, F_pre (N), > 0.
        eps_ratio: smoothing length as a fraction of the preload approach, ε = eps_ratio·g₀;
            (0, 1). The force is the exact law for a ≥ ε and exactly 0 for a ≤ −ε.
        crowning: approach relief of each element, ``(n,)`` in m (0 = none).
    """

    law: AbstractContactLaw
    row_yz: Float[Array, "rows 2"]
    row_normals: Float[Array, "rows 2"]
    xi: Float[Array, " n"]
    preload_force: float | Float[Array, ""]
    eps_ratio: float = 0.02
    crowning: Float[Array, " n"] | None = None
    jacobian_cache: Float[Array, "rows n 6"] | None = None

    def __check_init__(self):
        yz = np.shape(self.row_yz)
        if len(yz) != 2 or yz[1] != 2 or yz[0] < 1:
            raise ValueError(f"row_yz must have shape (n_rows >= 1, 2), got {yz}")
        if np.shape(self.row_normals) != yz:
            raise ValueError(
                f"row_normals must have the shape of row_yz {yz}, got {np.shape(self.row_normals)}"
            )
        if np.ndim(self.xi) != 1 or np.shape(self.xi)[0] < 1:
            raise ValueError(
                f"xi (element offsets) must be a 1-D array of >= 1 elements, got shape "
                f"{np.shape(self.xi)}"
            )
        _concrete_positive("preload_force (per element)", self.preload_force, "N")
        if concrete(self.eps_ratio) and not 0.0 < float(self.eps_ratio) < 1.0:
            raise ValueError(f"eps_ratio must be in (0, 1), got {self.eps_ratio!r}")
        if concrete(self.row_normals) and not np.allclose(
                np.linalg.norm(np.asarray(self.row_normals), axis=1), 1.0, atol=1e-9):
            raise ValueError("row_normals must be unit vectors")

    def resolved(self) -> "Carriage":
        """This carriage with its contact law's coefficient and its element Jacobian evaluated
        once (see :meth:`~diffguide.contact.AbstractContactLaw.resolved`): for solvers."""
        return dataclasses.replace(self, law=self.law.resolved(), jacobian_cache=self.jacobian())

    @property
    def n_rows(self) -> int:
        return np.shape(self.row_yz)[0]

    @property
    def n_elements(self) -> int:
        """Elements per row."""
        return np.shape(self.xi)[0]

    @property
    def preload_approach(self) -> Float[Array, ""]:
        """g₀ (m): the approach at which an element carries ``preload_force``."""
        return self.law.approach(self.preload_force)

    @property
    def eps(self) -> Float[Array, ""]:
        """Smoothing length ε (m)."""
        return self.eps_ratio * self.preload_approach

    @property
    def length(self) -> float:
        """Length of the loaded zone, first to last element plus one pitch (m)."""
        xi = np.asarray(self.xi)
        pitch = (xi[-1] - xi[0]) / max(len(xi) - 1, 1)
        return float(xi[-1] - xi[0] + pitch)

    def points(self) -> Float[Array, "rows n 3"]:
        """Contact points ``p_j`` in the carriage frame (m)."""
        xi = jnp.asarray(self.xi, dtype=float)
        yz = jnp.asarray(self.row_yz, dtype=float)
        rows, n = yz.shape[0], xi.shape[0]
        return jnp.stack(
            [
                jnp.broadcast_to(xi[None, :], (rows, n)),
                jnp.broadcast_to(yz[:, 0:1], (rows, n)),
                jnp.broadcast_to(yz[:, 1:2], (rows, n)),
            ],
            axis=-1,
        )

    def normals(self) -> Float[Array, "rows 3"]:
        """Load directions ``n_r`` as 3-vectors (0, n_y, n_z)."""
        nrm = jnp.asarray(self.row_normals, dtype=float)
        return jnp.concatenate([jnp.zeros_like(nrm[:, :1]), nrm], axis=1)

    def jacobian(self) -> Float[Array, "rows n 6"]:
        """``G_j = [n_j; p_j × n_j]``: ``a_j = a_j⁰ − G_j·q``, wrench ``= Σ F_j G_j`` (m, m·m)."""
        if self.jacobian_cache is not None:
            return self.jacobian_cache
        p = self.points()
        nrm = jnp.broadcast_to(self.normals()[:, None, :], p.shape)
        return jnp.concatenate([nrm, jnp.cross(p, nrm)], axis=-1)

    def approaches(
        self, pose: Float[Array, " 6"], rail: Float[Array, "n 2"]
    ) -> Float[Array, "rows n"]:
        """Element approaches (m) for carriage pose ``(t, θ)`` (m, rad) and the rail deviation
        ``(e_y, e_z)`` (m) under each element (shared by all rows)."""
        G = self.jacobian()
        nrm = self.normals()
        rail_dev = nrm[:, None, 1] * rail[None, :, 0] + nrm[:, None, 2] * rail[None, :, 1]
        crown = 0.0 if self.crowning is None else jnp.asarray(self.crowning)[None, :]
        return self.preload_approach - crown + rail_dev - G @ pose

    def element_forces(self, a: Float[Array, "rows n"]) -> Float[Array, "rows n"]:
        """Smoothed compression-only element forces (N) at approaches ``a`` (m)."""
        return element_force(a, self.law.stiffness_constant(), self.law.exponent, self.eps)

    def element_stiffnesses(self, a: Float[Array, "rows n"]) -> Float[Array, "rows n"]:
        """Tangent stiffnesses dF/da (N/m) at approaches ``a`` (m)."""
        return element_stiffness(a, self.law.stiffness_constant(), self.law.exponent, self.eps)

    def energy(self, a: Float[Array, "rows n"]) -> Float[Array, ""]:
        """Stored elastic energy of all elements (J)."""
        return jnp.sum(
            element_energy(a, self.law.stiffness_constant(), self.law.exponent, self.eps)
        )

    def wrench(self, a: Float[Array, "rows n"]) -> Float[Array, " 6"]:
        """Force (N) and moment (N·m, about the carriage origin) of the elements on the carriage."""
        return jnp.einsum("rn,rnk->k", self.element_forces(a), self.jacobian())

    def tangent(self, a: Float[Array, "rows n"]) -> Float[Array, "6 6"]:
        """``d(wrench)/d(pose) = −Σ k_j G_j G_jᵀ`` (N/m, N, N·m/rad)."""
        G = self.jacobian()
        return -jnp.einsum("rn,rni,rnj->ij", self.element_stiffnesses(a), G, G)


def row_layout(
    upper_yz: tuple[float, float],
    lower_yz: tuple[float, float],
    contact_angle_deg: float = 45.0,
    arrangement: str = "O",
) -> tuple[np.ndarray, np.ndarray]:
    """Four rows, symmetric about the rail's mid-plane, at a contact angle from the vertical.

    Arguments:
        upper_yz: (|y|, z) of the two upper rows (m), which carry downward loads.
        lower_yz: (|y|, z) of the two lower rows (m), which carry upward loads.
        contact_angle_deg: angle of the load lines from the vertical (degrees), in (0, 90).
        arrangement: ``"O"``: each load line points away from the rail's mid-plane (the
            back-to-back arrangement with the larger roll stiffness); ``"X"``: towards it.

    Returns:
        ``(row_yz, row_normals)`` for :class:`Carriage`, rows ordered upper-left, upper-right,
        lower-left, lower-right.
    """
    if arrangement not in ("O", "X"):
        raise ValueError(f"arrangement must be 'O' or 'X', got {arrangement!r}")
    if not 0.0 < contact_angle_deg < 90.0:
        raise ValueError(f"contact_angle_deg must be in (0, 90) degrees, got {contact_angle_deg!r}")
    s, c = np.sin(np.radians(contact_angle_deg)), np.cos(np.radians(contact_angle_deg))
    out = 1.0 if arrangement == "O" else -1.0
    yz, nrm = [], []
    for (y, z), nz in ((upper_yz, c), (lower_yz, -c)):
        for side in (-1.0, 1.0):
            yz.append((side * y, z))
            nrm.append((out * side * s, nz))
    return np.array(yz), np.array(nrm)


def element_offsets(n: int, pitch: float) -> np.ndarray:
    """``n`` element offsets (m) at ``pitch`` (m), centred on the carriage."""
    if int(n) != n or n < 1:
        raise ValueError(f"n (elements per row) must be an integer >= 1, got {n!r}")
    if not pitch > 0:
        raise ValueError(f"pitch must be > 0 m, got {pitch!r}")
    return (np.arange(n) - (n - 1) / 2) * pitch


def four_row_carriage(
    law: AbstractContactLaw,
    *,
    n: int,
    pitch: float,
    capacity: float,
    preload_fraction: float,
    upper_yz: tuple[float, float],
    lower_yz: tuple[float, float],
    contact_angle_deg: float = 45.0,
    arrangement: str = "O",
    eps_ratio: float = 0.02,
) -> Carriage:
    """A four-row carriage whose catalogue preload is a fraction of its dynamic capacity.

    The preload force ``preload_fraction·capacity`` (N) is divided equally over the ``4n``
    elements, which gives the force per element and, through the law, ``g₀``.

    Arguments:
        law: element contact law. n: elements per row. pitch: element pitch (m).
        capacity: dynamic load capacity C (N). preload_fraction: preload as a fraction of C,
            in (0, 1) (catalogue classes: 2 %, 8 %, 13 %).
        upper_yz, lower_yz, contact_angle_deg, arrangement: see :func:`row_layout`.
        eps_ratio: smoothing length / preload approach.
    """
    if concrete(capacity) and not capacity > 0:
        raise ValueError(f"capacity (dynamic load capacity C) must be > 0 N, got {capacity!r}")
    if concrete(preload_fraction) and not 0.0 < preload_fraction < 1.0:
        raise ValueError(
            f"preload_fraction must be in (0, 1) (a preload below the capacity C), got "
            f"{preload_fraction!r}"
        )
    row_yz, row_normals = row_layout(upper_yz, lower_yz, contact_angle_deg, arrangement)
    xi = element_offsets(n, pitch)
    per_element = preload_fraction * capacity / (4 * n)
    return Carriage(law, row_yz, row_normals, xi, per_element, eps_ratio)


class CarriageSpec(eqx.Module):
    """A four-row runner block, SI units: what :func:`carriage_from_spec` builds a
    :class:`Carriage` from (the ``[carriage]`` section of a machine file; two size-25 blocks
    in :mod:`diffguide.guideway.blocks`).

    Arguments:
        law: ``"hertz"`` (balls, exact Hertz), ``"rivin"`` (balls, the paper's eq. 1) or
            ``"roller"`` (Palmgren line contact).
        ball_diameter: ball diameter d (m; balls). groove_conformity: groove diameter / ball
            diameter, D/d > 1 (balls). roller_length: effective roller length (m; rollers).
        E: Young's modulus of elements and grooves (Pa). nu: their Poisson ratio.
        elements_per_row: rolling elements per row. pitch: element pitch (m).
        contact_angle_deg: load line angle from the vertical (degrees). arrangement: ``"O"`` or
            ``"X"`` (:func:`row_layout`).
        upper_row_yz, lower_row_yz: (|y|, z) of the upper and lower rows below the carriage's top
            face (m).
        capacity: dynamic load capacity C (N). preload_fraction: preload as a fraction of C (may
            be traced). smoothing_fraction: smoothing length ε / preload approach.
    """

    law: str = eqx.field(static=True)
    ball_diameter: float
    groove_conformity: float
    roller_length: float
    E: float
    nu: float
    elements_per_row: int = eqx.field(static=True)
    pitch: float = eqx.field(static=True)
    contact_angle_deg: float = eqx.field(static=True)
    arrangement: str = eqx.field(static=True)
    upper_row_yz: tuple[float, float] = eqx.field(static=True)
    lower_row_yz: tuple[float, float] = eqx.field(static=True)
    capacity: float | Float[Array, ""]
    preload_fraction: float | Float[Array, ""]
    smoothing_fraction: float = 0.02

    def __check_init__(self):
        if self.law not in LAWS:
            raise ValueError(f"law must be one of {LAWS}, got {self.law!r}")

    def contact_law(self) -> AbstractContactLaw:
        """The element contact law (SI)."""
        d = self.ball_diameter
        if self.law == "hertz":
            return HertzBall(d, self.groove_conformity * d, self.E, self.nu)
        if self.law == "rivin":
            return RivinBall(d, self.groove_conformity * d, self.E, self.nu)
        return PalmgrenRoller(self.roller_length)


#: The contact laws a :class:`CarriageSpec` can name.
LAWS = ("hertz", "rivin", "roller")


def carriage_from_spec(spec: CarriageSpec) -> Carriage:
    """The :class:`Carriage` of a runner-block specification (:func:`four_row_carriage`)."""
    return four_row_carriage(
        spec.contact_law(),
        n=spec.elements_per_row,
        pitch=spec.pitch,
        capacity=spec.capacity,
        preload_fraction=spec.preload_fraction,
        upper_yz=spec.upper_row_yz,
        lower_yz=spec.lower_row_yz,
        contact_angle_deg=spec.contact_angle_deg,
        arrangement=spec.arrangement,
        eps_ratio=spec.smoothing_fraction,
    )

