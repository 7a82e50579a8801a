r"""Where the machine model stops meaning anything: checks of inputs and results against its
validity, as structured warnings (:class:`Validity`).

The model is a small-deflection one: Hertz/Palmgren contact of elements loaded around their
preload, carriage and table rotations small enough for ``u = t + θ × p``, rails known where the
elements roll. The rules (SI inside; the messages in mm, µm, µrad):

- **Contact range** (:data:`CONTACT_RANGE`): an element's approach beyond ``10 g₀`` (``g₀`` the
  preload approach, :attr:`~diffguide.guideway.Carriage.preload_approach`) carries
  ``10^α`` times its preload (α = 3/2 for balls: 32×, about 2.5 C at a preload of 8 % C) —
  beyond the static load rating, where the elastic contact law and the rail's fixed contact
  geometry no longer hold. Checked on the rails (:func:`rail_range`: the rail's departure from
  its best straight line under one carriage, which no rigid carriage motion can take up, ``>
  10 g₀``) and on the equilibrium (:func:`contact_range`: the largest element approach).
- **Lift-off of a whole carriage** (:func:`contact_range`): every element of a carriage
  unloaded (approach ``≤ 0``) at some position — the table then rests on three carriages or
  fewer, which the preloaded-guideway model does not describe.
- **Small rotations** (:data:`SMALL_ANGLE`): a joint rotation error above 1 mrad; the dropped
  second-order term ``θ²|p|/2`` is then 0.25 µm at the 0.5 m half-width of a table and grows
  with θ².
- **Rails extrapolated** (:func:`rail_extrapolation`): the elements visit rail beyond the
  samples the rails were given at (positions swept ± the carriages' reach); there the rail is
  a continuation of the interpolant, not data.
"""

import dataclasses

import equinox as eqx
import jax
import numpy as np

#: The contact's small-deflection range, in preload approaches ``g₀`` (module docstring).
CONTACT_RANGE = 10.0
#: The small-rotation bound of the kinematics (rad; module docstring).
SMALL_ANGLE = 1e-3


@dataclasses.dataclass(frozen=True)
class Validity:
    """One validity warning: ``code`` (a stable name), ``message`` (what, with numbers and units)
    and ``action`` (what to do)."""

    code: str
    message: str
    action: str = ""

    def __str__(self) -> str:
        return f"{self.message}; {self.action}" if self.action else self.message

    def as_dict(self) -> dict:
        """``{code, message, action}`` for a JSON report."""
        return {"code": self.code, "message": self.message, "action": self.action}


def visited_by_rail(machine, positions) -> dict[int, tuple[float, float]]:
    """``{rail index: (lo, hi)}`` (m): the rail length the elements of the carriages on each rail
    visit over ``positions`` (m) and the reference x = 0."""
    x = np.concatenate([np.asarray(positions, float).ravel(), [0.0]])
    xc = np.asarray(machine.carriage_x, float)
    xi = np.asarray(machine.carriage.xi, float)
    out = {}
    for r in sorted(set(machine.carriage_rail)):
        on = xc[[k for k, rk in enumerate(machine.carriage_rail) if rk == r]]
        out[r] = (float(x.min() + on.min() + xi.min()), float(x.max() + on.max() + xi.max()))
    return out


def rail_extrapolation(machine, positions, sampled: dict) -> list[Validity]:
    """A warning per rail whose samples ``sampled`` (``{rail index (0, 1): (lo, hi)}``, m; a
    rail absent is straight everywhere) do not cover the rail the elements visit over
    ``positions`` (m; :func:`visited_by_rail`)."""
    out = []
    for r, (lo, hi) in visited_by_rail(machine, positions).items():
        if r not in sampled:
            continue
        s_lo, s_hi = sampled[r]
        tol = 1e-6
        if lo < s_lo - tol or hi > s_hi + tol:
            out.append(Validity(
                "rail_extrapolated",
                f"rail {r + 1} is sampled over [{s_lo * 1e3:g}, {s_hi * 1e3:g}] mm but the "
                f"carriages roll over [{lo * 1e3:g}, {hi * 1e3:g}] mm: beyond its samples the "
                "rail is an extrapolation of the interpolant, not data",
                "give the rail's samples over the whole length the carriages visit (the stroke "
                "± the carriage spacing), or sweep fewer positions"))
    return out


def _departure(e, xi):
    """Largest departure (m) of ``e`` (``(..., n)`` samples at ``xi``) from its least-squares
    straight line along the last axis."""
    A = np.stack([np.ones_like(xi), xi - xi.mean()], axis=1)
    coef, *_ = np.linalg.lstsq(A, np.moveaxis(e, -1, 0).reshape(len(xi), -1), rcond=None)
    fit = (A @ coef).reshape((len(xi),) + e.shape[:-1])
    return float(np.max(np.abs(np.moveaxis(e, -1, 0) - fit), initial=0.0))


@eqx.filter_jit
def _rails_under_carriages(machine, rails, x):
    """:meth:`~diffguide.machine.Machine.rail_under_carriages` at every ``x`` (m): ``(n_pos, k,
    n, 2)``, one compiled program."""
    return jax.vmap(machine.rail_under_carriages, in_axes=(0, None))(x, rails)


def _sampled_under_carriages(machine, sample, x):
    """:func:`_rails_under_carriages` from a host evaluation of the rails, ``sample(r, s) ->
    (e_y, e_z)`` (m at ``s`` in m, any shape): ``(n_pos, k, n, 2)``, nothing compiled."""
    xi = np.asarray(machine.carriage.xi, float)
    cx = np.asarray(machine.carriage_x, float)
    out = np.zeros((len(x), len(cx), len(xi), 2))
    for k, r in enumerate(machine.carriage_rail):
        ey, ez = sample(r, x[:, None] + cx[k] + xi)
        out[:, k, :, 0], out[:, k, :, 1] = ey, ez
    return out


def rail_range(machine, rails, positions, *, sample=None) -> list[Validity]:
    """A warning when the rails, under any carriage at ``positions`` (m), depart from a straight
    line by more than the contact's small-deflection range ``CONTACT_RANGE·g₀`` (module
    docstring): a rigid carriage cannot follow them, so its elements would be loaded beyond the
    contact law's range. ``sample``: the same rails evaluated on the host, ``sample(r, s) ->
    (e_y, e_z)`` (m at ``s`` in m, any shape; rail ``r`` = 0, 1), where the caller has that
    (a fit's spline basis): then no program is compiled for the check."""
    g0 = float(machine.carriage.preload_approach)
    xi = np.asarray(machine.carriage.xi, float)
    if xi.size < 3:
        return []
    x = np.unique(np.asarray(positions, float).ravel())
    # every position in one batched evaluation (a loop over positions ran the rails' spline
    # op by op per position in eager JAX: seconds for a fit's 71 positions)
    under = (np.asarray(_rails_under_carriages(machine, rails, x)) if sample is None
             else _sampled_under_carriages(machine, sample, x))
    worst = _departure(np.moveaxis(under, -1, 1), xi)  # (n_pos, 2 planes, k, n) → along n
    if worst <= CONTACT_RANGE * g0:
        return []
    return [Validity(
        "rail_beyond_contact_range",
        f"the rails depart from a straight line under one carriage by up to "
        f"{worst * 1e6:.4g} µm, beyond the contact's small-deflection range "
        f"{CONTACT_RANGE:g} × the preload approach = {CONTACT_RANGE * g0 * 1e6:.3g} µm: the "
        "results are outside the model's validity",
        "check the rail file's units (µm) and content; real rails depart by a few µm over a "
        "carriage length")]


def contact_range(machine, rails, errors) -> list[Validity]:
    """Warnings from the equilibrium ``errors`` (:class:`~.kinematics.JointErrors` of ``machine``
    on ``rails``): an element approach beyond the small-deflection range, a whole carriage
    lifted off (module docstring)."""
    import jax

    from .equilibrium import _contacts

    x = np.asarray(errors.positions, float)
    u = np.asarray(errors.interface, float)
    carriage = machine.carriage.resolved()
    machine_r = dataclasses.replace(machine, carriage=carriage)
    a = np.stack([np.asarray(_contacts(machine_r, jax.numpy.asarray(ui),
                                       machine_r.rail_under_carriages(xv, rails)))
                  for xv, ui in zip(x, u)])  # (n_pos, k, rows, n)
    g0 = float(carriage.preload_approach)
    out = []
    amax = float(np.max(a))
    if amax > CONTACT_RANGE * g0:
        out.append(Validity(
            "contact_beyond_range",
            f"an element approach reaches {amax * 1e6:.4g} µm, {amax / g0:.3g} × the preload "
            f"approach {g0 * 1e6:.3g} µm (small-deflection range {CONTACT_RANGE:g} ×): the "
            "contact law does not hold there",
            "check the rails' deviations and units"))
    lifted = np.all(a.reshape(a.shape[0], a.shape[1], -1) <= 0.0, axis=-1)  # (n_pos, k)
    if lifted.any():
        pos, k = np.nonzero(lifted)
        where = ", ".join(f"{x[p] * 1e3:g} mm" for p in np.unique(pos)[:5])
        out.append(Validity(
            "carriage_lift_off",
            f"carriage(s) {', '.join(str(int(c) + 1) for c in np.unique(k))} lift off entirely "
            f"(every element unloaded) at {where}{' ...' if len(np.unique(pos)) > 5 else ''}: "
            "the table no longer rests on its four carriages",
            "the results there are outside the preloaded-guideway model; check the rails"))
    return out


def large_rotations(errors_rad, what: str = "the joint errors") -> list[Validity]:
    """A warning when any rotation in ``errors_rad`` (rad, any shape) exceeds
    :data:`SMALL_ANGLE`."""
    r = float(np.max(np.abs(np.asarray(errors_rad, float)), initial=0.0))
    if not r > SMALL_ANGLE:
        return []
    return [Validity(
        "rotation_beyond_small_angle",
        f"{what} reach a rotation of {r * 1e6:.4g} µrad, beyond the model's small-rotation "
        f"bound {SMALL_ANGLE * 1e6:g} µrad",
        "check the data's units and content; a guideway's angular errors are tens of µrad")]
