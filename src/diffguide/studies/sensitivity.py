r"""Sensitivity studies of location-dependent roll: a scalar measure and rail influence maps.

*Roll spread* — how much the roll (EAX) differs between the corners of the table, one number in
µrad: the RMS over positions ``x_i`` and corners ``c`` of each corner's roll minus the corners'
mean roll at that position,

.. math::  D = \sqrt{\frac{1}{N C}\sum_i\sum_c \bigl(E_{AX,c}(x_i) - \bar E_{AX}(x_i)\bigr)^2}.

A rigid table gives ``D = 0`` (every point rolls alike); the elastic table's ``D`` is the roll a
level at one corner cannot see at the others. Where ``D > 0``, ``D`` is smooth in everything
the model is smooth in, so ``jax.grad``/``jax.jvp`` through :func:`diffguide.build_machine` and
:func:`diffguide.joint_errors` give its derivatives (implicit differentiation of the
equilibrium). At ``D = 0`` — perfect rails, or any rigid-table machine — ``D`` is a norm at its
zero, like ``|a|`` (the spread grows in proportion to the rail error whichever its sign), so it
has no derivative there, and ``jax.grad``/``jacfwd`` return NaN (the square root's slope at 0
times a zero). To differentiate about such a point use the mean square
``roll_spread(roll, squared=True)`` (``D²``, µrad²): smooth everywhere, gradient 0 at ``D = 0``.

*Influence map* — the roll at each corner and table position caused by a unit bump on a rail:
``∂E_AX,c(x_i)/∂c_k`` for the B-spline coefficients ``c_k`` of a
:class:`~diffguide.guideway.rails.SplineRail`, by forward mode (:func:`jax.jacfwd`; never ``jacrev``
here: reverse mode through the vmapped implicit solves stores every solve's tape, tens of
seconds and gigabytes for a sweep). Units rad/m =
µrad per µm of coefficient (a coefficient of 1 µm is a bump of peak 2/3 µm centred at
``s₀ + (k−1)h``, ``4h`` wide at its base).
"""

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.types import Array, Float
from ..guideway.rails import SplineRail, knot_centres
from ..machine.equilibrium import Machine
from ..machine.kinematics import ERROR_NAMES, JointErrors, joint_errors

#: The four corner points of the ``majda2012`` preset.
CORNERS = ("P1", "P2", "P3", "P4")
_EAX = ERROR_NAMES.index("EAX")


def corner_roll(errors: JointErrors, points: Sequence[str] = CORNERS) -> Float[Array, "n_pos c"]:
    """Roll EAX (rad) at ``points`` over the sweep, shape ``(n_pos, len(points))``."""
    idx = [errors.point_names.index(p) for p in points]
    return errors.errors[:, idx, _EAX]


def roll_spread(roll: Float[Array, "n_pos c"], *, squared: bool = False) -> Float[Array, ""]:
    """Roll spread ``D`` (module docstring) of corner rolls ``roll`` (rad), in µrad.

    With ``squared`` the mean square ``D²`` (µrad²), which unlike ``D`` is differentiable at
    ``D = 0`` (where ``jax.grad`` of ``D`` is NaN: module docstring)."""
    roll = jnp.asarray(roll) * 1e6
    dev = roll - jnp.mean(roll, axis=1, keepdims=True)
    msq = jnp.mean(dev**2)
    return msq if squared else jnp.sqrt(msq)


def spline_rails(
    rails, *, start: float = -0.6, stop: float = 0.6, spacing: float = 0.02
) -> tuple[SplineRail, SplineRail]:
    """The profiles ``rails`` (e.g. :func:`~diffguide.paper_variant`) as B-spline rails.

    Sampled every ``spacing / 4`` over ``[start, stop]`` (m) and fitted with knot spacing
    ``spacing`` (m); the coefficients (m) are then the inputs of :func:`influence_map`.
    """
    s = np.linspace(start, stop, int(round((stop - start) / spacing)) * 4 + 1)
    out = []
    for rail in rails:
        ey, ez = (np.asarray(v) for v in rail(jnp.asarray(s)))
        fit = SplineRail.fit(s, ez, ey, spacing=spacing, start=start, end=stop)
        out.append(fit)
    return tuple(out)


def bump_centres(rail: SplineRail) -> np.ndarray:
    """Rail coordinate ``s`` (m) at the centre of each coefficient's basis function."""
    return knot_centres(rail.start, rail.spacing, rail.n_coeffs)


def influence_map(
    machine: Machine,
    rails: tuple[SplineRail, SplineRail],
    positions: Float[Array, " n_pos"],
    *,
    rail: int = 0,
    plane: str = "vertical",
    points: Sequence[str] = CORNERS,
    x_ref: float = 0.0,
) -> Float[Array, "n_pos c n"]:
    """Roll at ``points`` per unit B-spline coefficient of one rail, by forward-mode AD.

    Arguments:
        machine: the machine. rails: the two rails (the state the map is linearised about).
        positions: table positions (m). rail: 0 (rail 1) or 1 (rail 2).
        plane: ``"vertical"`` or ``"horizontal"`` coefficients. points: the points.
        x_ref: reference position (m).

    Returns:
        ``∂E_AX/∂c`` with shape ``(n_pos, len(points), n_coeffs)``: rad per m, i.e. µrad per µm.
    """
    if plane not in ("vertical", "horizontal"):
        raise ValueError(f"plane must be 'vertical' or 'horizontal', got {plane!r}")
    if rail not in (0, 1):
        raise ValueError(f"rail must be 0 or 1, got {rail!r}")
    return _influence(machine, rails, positions, x_ref, rail, plane, tuple(points))


@eqx.filter_jit
def _influence(machine, rails, positions, x_ref, rail, plane, points):
    base = rails[rail]
    other = rails[1 - rail]

    def roll(c):
        h, v = (base.horizontal, c) if plane == "vertical" else (c, base.vertical)
        r = SplineRail(base.start, base.spacing, v, h)
        pair = (r, other) if rail == 0 else (other, r)
        return corner_roll(joint_errors(machine, pair, positions, x_ref), points)

    c0 = base.vertical if plane == "vertical" else base.horizontal
    return jax.jacfwd(roll)(jnp.asarray(c0))
