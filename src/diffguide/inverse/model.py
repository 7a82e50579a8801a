r"""The fit's forward model: the whitened residual of every merged measurement through the
differentiable machine, and its compiled linearisation.

For ``v = (c, q, ℓ)`` — all rail coefficients ``c`` (µm), the structural unknowns ``q`` (prior
σ) and the nuisance coefficients ``ℓ`` (lead error and alignment slopes, µm) —

.. math::  m_i(v) = E_{q_i}(P_i) + z_i\,A_{q_i}(P_i) + (Bℓ)_i,\qquad
           r_i = w_i\bigl(m_i - y_i - o_{c(i)}\bigr)/σ_i,

``E`` the joint errors (m, rad) of the machine at ``q`` (:func:`~diffguide.machine.kinematics.
joint_errors_traced`, every equilibrium differentiated implicitly), ``z_i`` the sensing point's
height (m) with the Abbe terms ``A_EXX = EBX``, ``A_EYX = −EAX``, ``B`` the nuisance columns
(:mod:`.problem`) and ``o_c`` each channel's zero, profiled out as its weighted mean misfit.
"""

import equinox as eqx
import jax
import jax.numpy as jnp

from .._core.aot import cached_program
from ..machine.kinematics import joint_errors_traced
from .basis import RailBasis
from .data import QUANTITIES
from .structure import MachineFamily

_UM = 1e-6
_EXX, _EYX = QUANTITIES.index("EXX"), QUANTITIES.index("EYX")
_EAX, _EBX = QUANTITIES.index("EAX"), QUANTITIES.index("EBX")


class _Problem(eqx.Module):
    """Everything the residual needs; arrays travel as arguments (never closed over).

    Positions and heights in m, values and σ in SI (m, rad), ``lead`` the nuisance columns
    (m per µm of coefficient), ``x_ref`` the model's reference position (m)."""

    family: MachineFamily
    positions: jax.Array
    pos_idx: jax.Array
    pt_idx: jax.Array
    q_idx: jax.Array
    value: jax.Array
    sigma: jax.Array
    weight: jax.Array
    z: jax.Array
    lead: jax.Array
    chan: jax.Array
    prior_sigma: jax.Array
    x_ref: jax.Array
    basis: RailBasis
    n_chan: int = eqx.field(static=True)
    n_q: int = eqx.field(static=True)

    @property
    def n_c(self) -> int:
        return self.basis.size


def _rails(c_um, prob: _Problem):
    """The rails of the coefficients ``c_um`` (µm; each profile's spline, then its joints'
    steps: :meth:`.basis.RailBasis.rails`)."""
    return prob.basis.rails(c_um.reshape(2, 2, prob.basis.per_profile) * _UM)


def _model(v, prob: _Problem):
    """Model values (SI) at every merged measurement, and whether every equilibrium converged;
    ``v = (c, q, ℓ)``: all rail coefficients (µm), structure, lead (µm)."""
    c = v[: prob.n_c]
    q = v[prob.n_c: prob.n_c + prob.n_q]
    ell = v[prob.n_c + prob.n_q:]
    machine = prob.family.machine(q * prob.prior_sigma)
    # Newton on all 30 DOF: the smaller program (this one is traced, differentiated and
    # compiled for a few calls, where the condensed solve's run time does not pay its compile)
    je = joint_errors_traced(
        machine, _rails(c, prob), prob.positions, prob.x_ref, condensed=False
    )
    E = je.errors[prob.pos_idx, prob.pt_idx]  # (N, 6)
    base = jnp.take_along_axis(E, prob.q_idx[:, None], axis=1)[:, 0]
    abbe = jnp.where(prob.q_idx == _EXX, E[:, _EBX], jnp.where(prob.q_idx == _EYX, -E[:, _EAX],
                                                                0.0))
    pred = base + prob.z * abbe + (prob.lead @ ell) * _UM
    return pred, jnp.all(je.converged)


def _data_residual_full(x, prob: _Problem):
    """Whitened residuals with the channel zeros profiled out, model values, convergence."""
    pred, ok = _model(x, prob)
    d = pred - prob.value
    w = prob.weight / prob.sigma**2
    off = jax.ops.segment_sum(w * d, prob.chan, prob.n_chan) / jnp.maximum(
        jax.ops.segment_sum(w, prob.chan, prob.n_chan), 1e-300)
    return prob.weight * (d - off[prob.chan]) / prob.sigma, pred, ok


def _linearise_traced(v, prob: _Problem):
    """Residual, Jacobian w.r.t. ``v = (c, q, ℓ)``, model values, convergence."""

    def f(t):
        r, pred, ok = _data_residual_full(t, prob)
        return r, (r, pred, ok)

    J, (r, pred, ok) = jax.jacfwd(f, has_aux=True)(v)
    return r, J, pred, ok


#: The compiled linearisation; with an export folder set (the command line sets one,
#: :mod:`diffguide._core.aot`) a later process reads the traced program back instead of
#: tracing it again (seconds); without one, the ``filter_jit`` function itself. (The key keeps
#: the module's former name, so that programs exported before stay valid.)
_linearise = cached_program(eqx.filter_jit(_linearise_traced), "inverse.fit._linearise")
