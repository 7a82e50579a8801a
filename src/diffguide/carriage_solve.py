r"""Equilibrium of one rigid carriage on its rail under an external wrench.

Unknown: the carriage pose ``q = (t, θ)`` (m, rad) at its origin, less ``tx``: rolling
elements carry no force along the rail, so the carriage's X position is the drive's business. Equilibrium (the stationary
point of the convex potential :math:`Π(q) = \sum_j φ(a_j(q)) - W·q`):

.. math::  R(q) = \sum_j F(a_j(q))\,G_j + W = 0,

solved by Newton with a line search on Π (:mod:`diffguide._newton`), polished by optimistix
Newton on scaled unknowns (µm, µrad) and residuals (kN, kN·(10 mm)), so one
tolerance serves displacements and forces (PITFALLS.md). Derivatives with respect to the load,
the carriage parameters (preload, law) and the rail deviation come from implicit differentiation
(``optimistix.ImplicitAdjoint``), never from unrolled Newton iterations.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx

from ._newton import solve_equilibrium
from ._precision import require_x64
from ._types import Array, Float, Int
from .guideway import Carriage

#: Scales: unknowns in µm and µrad, residual forces in kN and moments in kN·(10 mm).
POSE_SCALE = 1e-6
FORCE_SCALE = 1e3
MOMENT_SCALE = 1e3 * 1e-2


class CarriageSolution(eqx.Module):
    """Equilibrium of a carriage.

    Attributes:
        pose: ``(tx, ty, tz, θx, θy, θz)`` of the carriage origin (m, rad).
        approaches: element approaches at equilibrium, ``(rows, n)`` (m).
        forces: element forces, ``(rows, n)`` (N).
        result: optimistix result code (``optx.RESULTS.successful`` when converged).
        steps: Newton steps taken.
    """

    pose: Float[Array, "*batch 6"]
    approaches: Float[Array, "*batch rows n"]
    forces: Float[Array, "*batch rows n"]
    result: optx.RESULTS
    steps: Int[Array, "*batch"]

    @property
    def converged(self) -> jax.Array:
        return self.result == optx.RESULTS.successful


_SCALES = (FORCE_SCALE,) * 3 + (MOMENT_SCALE,) * 3
ALL_FREE = (1, 2, 3, 4, 5)
TRANSLATION_ONLY = (1, 2)


def _pose(y, free):
    """Pose (m, rad) from the free unknowns (µm, µrad); the other components are held at 0."""
    return jnp.zeros(6).at[jnp.array(free)].set(y) * POSE_SCALE


def _potential(y, args, free):
    """Total potential Π = Σφ(a_j) − W·q (J) in the scaled unknowns."""
    carriage, load, rail = args
    pose = _pose(y, free)
    return carriage.energy(carriage.approaches(pose, rail)) - jnp.dot(load, pose)


def _grad_hess(y, args, free):
    """Gradient (J/µm) and Hessian (J/µm²) of :func:`_potential`: −(wrench + W), −tangent."""
    carriage, load, rail = args
    a = carriage.approaches(_pose(y, free), rail)
    idx = jnp.array(free)
    g = -(carriage.wrench(a) + load)[idx] * POSE_SCALE
    H = -carriage.tangent(a)[idx][:, idx] * POSE_SCALE**2
    return g, H


def _residual(y, args, free):
    carriage, load, rail = args
    a = carriage.approaches(_pose(y, free), rail)
    wrench = carriage.wrench(a) + load
    return wrench[jnp.array(free)] / jnp.array([_SCALES[i] for i in free])


@eqx.filter_jit
def solve_carriage(
    carriage: Carriage,
    load: Float[Array, " 6"],
    rail: Float[Array, "n 2"] | None = None,
    *,
    initial_pose: Float[Array, " 6"] | None = None,
    rtol: float = 1e-10,
    atol: float = 1e-10,
    max_steps: int = 100,
    throw: bool = False,
    free: tuple[int, ...] = ALL_FREE,
) -> CarriageSolution:
    """Equilibrium pose of a rigid carriage.

    Arguments:
        carriage: the carriage (:class:`~diffguide.guideway.Carriage`).
        load: external wrench on the carriage at its origin, ``(Fx, Fy, Fz, Mx, My, Mz)``
            (N, N·m); e.g. ``(0, 0, -F, 0, 0, 0)`` presses it down on the rail. ``Fx`` is
            carried by the drive, not the elements, and is ignored; the pose's ``tx`` is 0.
        rail: rail deviation ``(e_y, e_z)`` (m) under each element, ``(n, 2)``; default straight.
        initial_pose: Newton's starting pose (m, rad); default zero.
        rtol, atol: Newton tolerances on the scaled problem (µm, µrad, kN).
        max_steps: Newton step limit.
        throw: raise on non-convergence instead of reporting it in ``result``.
        free: the pose components solved for (indices 1–5 of ``(tx, ty, tz, θx, θy, θz)``; the
            others are held at 0). ``tx`` is never free: rolling elements carry no force along
            the rail (the drive does), and ``load[0]`` is ignored. A carriage with one opposed
            pair of rows lifted off has a zero-stiffness roll mode about the crossing of the
            remaining load lines; hold the rotations (``free=TRANSLATION_ONLY``) to load it alone.

    Returns:
        :class:`CarriageSolution`.
    """
    require_x64("solve_carriage")
    load = jnp.asarray(load, dtype=float)
    if load.shape != (6,):
        raise ValueError(f"load must be a 6-vector (Fx, Fy, Fz, Mx, My, Mz), got shape {load.shape}")
    if rail is None:
        rail = jnp.zeros((carriage.n_elements, 2))
    rail = jnp.asarray(rail, dtype=float)
    if rail.shape != (carriage.n_elements, 2):
        raise ValueError(
            f"rail must have shape (n_elements={carriage.n_elements}, 2) (e_y, e_z per element), "
            f"got {rail.shape}"
        )
    carriage = carriage.resolved()
    free = tuple(sorted(set(free)))
    if not free or not set(free) <= set(ALL_FREE):
        raise ValueError(f"free must be a non-empty subset of {ALL_FREE}, got {free!r}")
    y0 = (
        jnp.zeros(len(free))
        if initial_pose is None
        else jnp.asarray(initial_pose)[jnp.array(free)] / POSE_SCALE
    )
    sol = solve_equilibrium(
        functools.partial(_potential, free=free),
        functools.partial(_grad_hess, free=free),
        functools.partial(_residual, free=free),
        y0,
        (carriage, load, rail),
        rtol=rtol,
        atol=atol,
        max_steps=max_steps,
        throw=throw,
    )
    pose = _pose(sol.value, free)
    a = carriage.approaches(pose, rail)
    return CarriageSolution(
        pose=pose,
        approaches=a,
        forces=carriage.element_forces(a),
        result=sol.result,
        steps=sol.stats["num_steps"],
    )


def rail_under(carriage: Carriage, profile, position: float | Float[Array, ""]):
    """Rail deviation ``(e_y, e_z)`` (m) under the elements of a carriage centred at ``position``
    (m) on a rail with ``profile`` (:class:`~diffguide.rails.AbstractRailProfile`)."""
    ey, ez = profile(position + jnp.asarray(carriage.xi, dtype=float))
    return jnp.stack([ey, ez], axis=-1)


DIRECTIONS = {"down": (2, -1.0), "up": (2, 1.0), "lateral": (1, 1.0)}


@eqx.filter_jit
def _characteristics(carriage, wrenches):
    return eqx.filter_vmap(lambda w: solve_carriage(carriage, w, free=TRANSLATION_ONLY))(wrenches)


def static_characteristics(
    carriage: Carriage, loads: Float[Array, " m"]
) -> dict[str, tuple[Float[Array, " m"], CarriageSolution]]:
    """Deflection of the carriage under downward, upward and lateral loads (the paper's Fig. 3).

    The force acts at the carriage origin (centre of its top face) through a fixture that
    lets the carriage translate across the rail but not rotate, as in catalogue stiffness
    measurements. ``"down"`` is −Z, ``"up"`` +Z, ``"lateral"`` +Y. All directions and loads are
    solved in one compiled, vmapped call.

    Arguments:
        carriage: the carriage. loads: load magnitudes (N), ≥ 0.

    Returns:
        ``{direction: (deflection, solutions)}``: deflection along the load (m, positive in
        the load's direction) and the batched :class:`CarriageSolution`.
    """
    loads = jnp.asarray(loads, dtype=float)
    m = loads.shape[0]
    wrenches = jnp.zeros((len(DIRECTIONS) * m, 6))
    for k, (axis, sign) in enumerate(DIRECTIONS.values()):
        wrenches = wrenches.at[k * m : (k + 1) * m, axis].set(sign * loads)
    sols = _characteristics(carriage, wrenches)
    out = {}
    for k, (name, (axis, sign)) in enumerate(DIRECTIONS.items()):
        part = jax.tree_util.tree_map(lambda v: v[k * m : (k + 1) * m], sols)
        out[name] = (sign * part.pose[:, axis], part)
    return out
