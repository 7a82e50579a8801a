r"""Equilibrium of one rigid carriage on its rail under an external wrench.

Unknown: the carriage pose ``q = (t, θ)`` (m, rad) at its origin, less ``tx``: rolling
elements carry no force along the rail, so the carriage's X position is the drive's business.
Equilibrium (the stationary
point of the convex potential :math:`Π(q) = \sum_j φ(a_j(q)) - W·q`):

.. math::  R(q) = \sum_j F(a_j(q))\,G_j + W = 0,

solved by Newton with a line search on Π in scaled unknowns (µm, µrad)
(:mod:`diffguide._core.newton`). Derivatives with respect to the load, the carriage parameters
(preload, law) and the rail deviation come from implicit differentiation
(the ``custom_jvp`` of :func:`diffguide._core.newton.solve_equilibrium`), never from unrolled
Newton iterations.
"""

import equinox as eqx
import jax
import jax.numpy as jnp

from .._core.newton import solve_equilibrium
from .._core.precision import require_x64
from .._core.result import RESULTS
from .._core.types import Array, Float, Int
from .carriage import Carriage

#: Scale of the unknowns: µm and µrad.
POSE_SCALE = 1e-6


class CarriageSolution(eqx.Module):
    """Equilibrium of a carriage.

    Attributes:
        pose: ``(tx, ty, tz, θx, θy, θz)`` of the carriage origin (m, rad).
        approaches: element approaches at equilibrium, ``(rows, n)`` (m).
        forces: element forces, ``(rows, n)`` (N).
        result: result code (``RESULTS.successful`` when converged).
        steps: Newton steps taken.
    """

    pose: Float[Array, "*batch 6"]
    approaches: Float[Array, "*batch rows n"]
    forces: Float[Array, "*batch rows n"]
    result: RESULTS
    steps: Int[Array, "*batch"]

    @property
    def converged(self) -> jax.Array:
        return self.result == RESULTS.successful


ALL_FREE = (1, 2, 3, 4, 5)
TRANSLATION_ONLY = (1, 2)


def _selection(free: tuple[int, ...]) -> jax.Array:
    """``S`` (6, d): the pose (in µm, µrad) from the free unknowns, ``q = S y``."""
    return jnp.eye(6)[:, jnp.array(free)]


def _potential(y, args):
    """Total potential Π = Σφ(a_j) − W·q (J) in the scaled unknowns."""
    carriage, load, rail, S = args
    pose = S @ y * POSE_SCALE
    return carriage.energy(carriage.approaches(pose, rail)) - jnp.dot(load, pose)


def _grad_hess(y, args):
    """Gradient (J/µm) and Hessian (J/µm²) of :func:`_potential`: −(wrench + W), −tangent."""
    carriage, load, rail, S = args
    a = carriage.approaches(S @ y * POSE_SCALE, rail)
    g = -S.T @ (carriage.wrench(a) + load) * POSE_SCALE
    H = -S.T @ carriage.tangent(a) @ S * POSE_SCALE**2
    return g, H


@eqx.filter_jit
def solve_carriage(
    carriage: Carriage,
    load: Float[Array, " 6"],
    rail: Float[Array, "n 2"] | None = None,
    *,
    initial_pose: Float[Array, " 6"] | None = None,
    tol: float = 1e-9,
    max_steps: int = 100,
    free: tuple[int, ...] = ALL_FREE,
    throw: bool = False,
) -> CarriageSolution:
    """Equilibrium pose of a rigid carriage.

    Arguments:
        carriage: the carriage (:class:`~diffguide.guideway.Carriage`).
        load: external wrench on the carriage at its origin, ``(Fx, Fy, Fz, Mx, My, Mz)``
            (N, N·m); e.g. ``(0, 0, -F, 0, 0, 0)`` presses it down on the rail. ``Fx`` is
            carried by the drive, not the elements, and is ignored; the pose's ``tx`` is 0.
        rail: rail deviation ``(e_y, e_z)`` (m) under each element, ``(n, 2)``; default straight.
        initial_pose: Newton's starting pose (m, rad); default zero.
        tol: stop when the Newton step is below ``tol`` µm / µrad.
        max_steps: Newton step limit (non-convergence is reported in ``result``).
        free: the pose components solved for (indices 1–5 of ``(tx, ty, tz, θx, θy, θz)``; the
            others are held at 0). ``tx`` is never free: rolling elements carry no force along
            the rail (the drive does), and ``load[0]`` is ignored. A carriage with one opposed
            pair of rows lifted off has a zero-stiffness roll mode about the crossing of the
            remaining load lines; hold the rotations (``free=TRANSLATION_ONLY``) to load it alone.
        throw: raise when the solve fails (``eqx.error_if``, works under ``jit``) instead of
            only reporting it in ``result`` (leave off under ``vmap``: one failure would fail
            the batch).

    Returns:
        :class:`CarriageSolution`.
    """
    require_x64("solve_carriage")
    load = jnp.asarray(load, dtype=float)
    if load.shape != (6,):
        raise ValueError(
            f"load must be a 6-vector (Fx, Fy, Fz, Mx, My, Mz), got shape {load.shape}"
        )
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
    S = _selection(free)
    y0 = (
        jnp.zeros(len(free))
        if initial_pose is None
        else S.T @ jnp.asarray(initial_pose) / POSE_SCALE
    )
    y, result, steps = solve_equilibrium(
        _potential,
        _grad_hess,
        y0,
        (carriage, load, rail, S),
        tol=tol,
        max_steps=max_steps,
        throw=throw,
    )
    pose = S @ y * POSE_SCALE
    a = carriage.approaches(pose, rail)
    return CarriageSolution(
        pose=pose, approaches=a, forces=carriage.element_forces(a), result=result, steps=steps
    )


def rail_under(carriage: Carriage, profile, position: float | Float[Array, ""]):
    """Rail deviation ``(e_y, e_z)`` (m) under the elements of a carriage centred at ``position``
    (m) on a rail with ``profile`` (:class:`~diffguide.guideway.rails.AbstractRailProfile`)."""
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
