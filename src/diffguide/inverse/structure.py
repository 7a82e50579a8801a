r"""The machine's structure as unknowns of the fit: the table's stiffness and the preload.

Nobody knows the equivalent plate thickness of a cast, ribbed table or the real preload of a
worn carriage, and both change what a rail error does to the measured pitch, yaw and roll. The
fit therefore estimates them together with the rails, through the same model, with a prior the
user states (a value and a range).

Three structural unknowns, all dimensionless and on a log scale:

- ``log_thickness`` ``= ln(t / t₀)``: the equivalent plate thickness ``t`` of the table (bending
  stiffness ∝ t³, membrane and shear stiffness and weight ∝ t);
- ``log_preload`` ``= ln(F / F₀)``: the preload force per rolling element ``F`` (a preload
  fraction of C times the same factor);
- ``log_stiffness`` ``= ln(s / s₀)``: a scale ``s`` on the stiffness of a table imported from the
  user's FE model (:mod:`diffguide.fe.superelement`), which has no thickness: ``K → sK``, the
  sag under the self-weight ``r0 → r0/s``, the weight and the point recovery unchanged — exact
  (:func:`~diffguide.fe.superelement.scaled_table`), so no interpolation is needed. It stands
  for what the FE model gets wrong as a whole (the casting's modulus, the joints' compliance).

The preload enters the carriage directly (``Carriage.preload_force`` is a number of the model).
The table is condensed once per thickness at :data:`N_NODES` Chebyshev nodes of ``ln t`` over
the prior range (widened by :data:`MARGIN` on each side), and the arrays of the condensed table
that the equilibrium and the control points use (:data:`INTERPOLATED`: stiffness, loads, point
recovery) are interpolated between them by the Lagrange polynomial in ``ln t`` (the mesh-node
fields of the error maps stay at the prior thickness):

.. math::  T(u) = \sum_j T(u_j)\,\prod_{k≠j}\frac{u-u_k}{u_j-u_k},\qquad u = \ln t,

smooth and exactly differentiable, accurate to ~1e-6 relative over a factor-4 thickness range
(tested against a direct condensation between the nodes). Outside the nodes' range the thickness
is held at the bound (the fit reports that).

Prior: ``ln t ~ N(ln t_value, σ_t²)`` with the stated range read as ±2σ about the value (the
larger side), likewise for the preload. The posterior σ of each parameter is compared with its
prior σ: a parameter whose σ the data shrink by less than :data:`DETERMINED_RATIO` is reported as
*not determined by the data* (its value is the prior's, and its uncertainty is carried into the
rails' bands).
"""

import dataclasses
import logging
from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..fe.superelement import scaled_table

#: Interpolation nodes in ln(thickness).
N_NODES = 9
#: The nodes span the prior range widened by this factor on each side (in t).
MARGIN = 1.15
#: A parameter counts as determined by the data when its posterior σ is below this fraction of
#: its prior σ.
DETERMINED_RATIO = 0.7

_log = logging.getLogger("diffguide")
NAMES = ("thickness", "preload", "stiffness")
#: Fields of the condensed table interpolated in thickness.
INTERPOLATED = ("K", "f", "R", "r0")


@dataclasses.dataclass(frozen=True)
class Prior:
    """A structural parameter's prior: ``value`` and a plausible ``(lo, hi)`` range (same unit;
    thickness in m, preload as a fraction of C), read as ±2σ of a normal prior in the log."""

    value: float
    lo: float
    hi: float

    def __post_init__(self):
        if not (0 < self.lo <= self.value <= self.hi):
            raise ValueError(
                f"a prior needs 0 < lo <= value <= hi, got value {self.value!r}, range "
                f"({self.lo!r}, {self.hi!r})"
            )

    @property
    def sigma_log(self) -> float:
        """σ of ``ln(parameter)`` (the larger half-range over 2); at least 1e-3."""
        half = max(np.log(self.hi / self.value), np.log(self.value / self.lo))
        return max(half / 2.0, 1e-3)


@dataclasses.dataclass(frozen=True)
class StructurePriors:
    """Priors of the structural unknowns; ``None`` holds a parameter fixed at the machine's value.

    Attributes:
        thickness: equivalent plate thickness (m).
        preload: preload as a fraction of the carriage's dynamic capacity C (or of the machine's
            own preload when the machine was given directly: ``value`` is then the machine's
            fraction and only the ratios matter).
        stiffness: the scale on an imported table's stiffness (dimensionless; 1: the FE
            model's). Only for a machine whose table was condensed elsewhere (its thickness
            has no meaning); the family scales the base machine's table itself.
    """

    thickness: Prior | None = None
    preload: Prior | None = None
    stiffness: Prior | None = None

    def active(self) -> tuple[str, ...]:
        return tuple(n for n in NAMES if getattr(self, n) is not None)


def scaled_preload(machine, log_factor):
    """``machine`` with the preload force per rolling element (``Carriage.preload_force``, N)
    times ``e^log_factor`` (dimensionless, may be traced): the preload's perturbation, here for
    :meth:`MachineFamily.machine` and for the prediction's Jacobian in the preload
    (:func:`.posterior_sweep.perturbed_joint_errors`)."""
    return eqx.tree_at(lambda m: m.carriage.preload_force, machine,
                       machine.carriage.preload_force * jnp.exp(log_factor))


def _cheb_nodes(lo: float, hi: float, n: int) -> np.ndarray:
    k = np.arange(n)
    return 0.5 * (lo + hi) + 0.5 * (hi - lo) * np.cos(np.pi * (2 * k + 1) / (2 * n))[::-1]


def lagrange_weights(u, nodes: np.ndarray):
    """Lagrange basis polynomials at ``u`` for ``nodes`` (products: smooth through the nodes)."""
    nodes = np.asarray(nodes, dtype=float)
    n = nodes.shape[0]
    w = []
    for j in range(n):
        others = np.delete(nodes, j)
        w.append(jnp.prod(u - jnp.asarray(others)) / float(np.prod(nodes[j] - others)))
    return jnp.stack(w)


class MachineFamily(eqx.Module):
    """A machine whose table thickness and preload are parameters (see the module docstring).

    Build with :meth:`build`; evaluate with :meth:`machine`.

    Attributes:
        base: the machine at the prior values (its static structure: points, carriages, rails).
        tables: the :data:`INTERPOLATED` fields of the condensed table at every node, stacked
            on a leading axis.
        nodes: the nodes ``ln t`` (static).
        thickness0: the base machine's thickness (m). preload0: its preload fraction.
        priors: the priors (static).
        stiffness0: the base machine's stiffness scale (its table is the given machine's
            scaled by it).
    """

    base: eqx.Module
    tables: dict | None
    nodes: tuple[float, ...] = eqx.field(static=True)
    thickness0: float = eqx.field(static=True)
    preload0: float = eqx.field(static=True)
    priors: StructurePriors = eqx.field(static=True)
    stiffness0: float = eqx.field(static=True, default=1.0)

    @classmethod
    def build(
        cls,
        make_machine: Callable[..., eqx.Module],
        priors: StructurePriors,
        *,
        progress: Callable[[str], None] | None = None,
    ) -> "MachineFamily":
        """Condense the table at the interpolation nodes.

        Arguments:
            make_machine: ``make_machine(thickness=t, preload_fraction=p)`` →
                :class:`~diffguide.machine.Machine` (``t`` in m, ``p`` a fraction of C; each
                keyword is passed only when that parameter has a prior; everything else at its
                configured value).
            priors: which parameters are unknown, with their priors.
            progress: called with a line of text per condensation (optional).
        """
        t0 = priors.thickness.value if priors.thickness is not None else None
        kw = {}
        if priors.preload is not None:
            kw["preload_fraction"] = priors.preload.value
        base = make_machine(**kw, **({} if t0 is None else {"thickness": t0}))
        preload0 = priors.preload.value if priors.preload is not None else 1.0
        s0 = 1.0
        if priors.stiffness is not None:
            s0 = float(priors.stiffness.value)
            if s0 != 1.0:
                base = eqx.tree_at(lambda m: m.table, base, scaled_table(base.table, s0))
        if priors.thickness is None:
            return cls(base, None, (), 0.0, preload0, priors, s0)
        p = priors.thickness
        lo, hi = np.log(p.lo / MARGIN), np.log(p.hi * MARGIN)
        nodes = _cheb_nodes(lo, hi, N_NODES)
        tables = []
        for k, u in enumerate(nodes):
            line = f"condensing the table at thickness {np.exp(u) * 1e3:.1f} mm " \
                   f"({k + 1}/{len(nodes)})"
            _log.info(line)
            if progress is not None:
                progress(line)
            tables.append(make_machine(thickness=float(np.exp(u)), **kw).table)
        # stacked in NumPy (an eager jnp.stack compiles a small program per shape)
        stacked = {
            k: jnp.asarray(np.stack([np.asarray(getattr(t, k)) for t in tables]))
            for k in INTERPOLATED
        }
        return cls(base, stacked, tuple(float(u) for u in nodes), float(t0), preload0, priors,
                   s0)

    @property
    def names(self) -> tuple[str, ...]:
        return self.priors.active()

    @property
    def n_params(self) -> int:
        return len(self.names)

    def prior_sigma(self) -> np.ndarray:
        return np.array([getattr(self.priors, n).sigma_log for n in self.names])

    def prior_mean(self) -> np.ndarray:
        """Prior mean of each unknown (log of value over the base machine's value): 0."""
        return np.zeros(self.n_params)

    def bounds(self) -> np.ndarray:
        """``(n_params, 2)`` bounds of the unknowns (the thickness nodes' range; preload and
        stiffness ±3, a factor 20)."""
        out = []
        for n in self.names:
            if n == "thickness":
                out.append((self.nodes[0] - np.log(self.thickness0),
                            self.nodes[-1] - np.log(self.thickness0)))
            else:
                out.append((-3.0, 3.0))
        return np.array(out)

    def machine(self, params):
        """The machine at ``params`` (the unknowns in the order of :attr:`names`; may be traced)."""
        m = self.base
        params = jnp.asarray(params, dtype=float)
        for i, n in enumerate(self.names):
            if n == "thickness":
                u = jnp.clip(params[i] + np.log(self.thickness0), self.nodes[0], self.nodes[-1])
                w = lagrange_weights(u, np.asarray(self.nodes))
                fields = [jnp.tensordot(w, self.tables[k], axes=1) for k in INTERPOLATED]
                m = eqx.tree_at(lambda mm: [getattr(mm.table, k) for k in INTERPOLATED], m,
                                fields)
            elif n == "stiffness":
                m = eqx.tree_at(lambda mm: mm.table, m,
                                scaled_table(m.table, jnp.exp(params[i])))
            else:
                m = scaled_preload(m, params[i])
        return m

    def values(self, params) -> dict[str, float]:
        """The physical value of each unknown (thickness in m, preload as a fraction, stiffness
        as a scale)."""
        out = {}
        for i, n in enumerate(self.names):
            if n == "thickness":
                out[n] = float(self.thickness0 * np.exp(params[i]))
            elif n == "stiffness":
                out[n] = float(self.stiffness0 * np.exp(params[i]))
            else:
                out[n] = float(self.preload0 * np.exp(params[i]))
        return out
