r"""The per-sample error measure of a design and its derivatives w.r.t. the design variables,
through the batched Monte Carlo sweep, with common random numbers.

For design variables ``x`` (SI) the machine ``M(x)`` is built once per iterate, traced, together
with its ``k`` tangents ``∂M/∂x_j`` (forward mode: :func:`jax.jvp` of
:func:`~diffguide.machine.build.build_machine`, one per variable — the condensation's
derivative). Each rail sample ``i`` of the fixed batch then gives its measure ``m_i(M)`` (the
same per-sample sweep as :func:`~diffguide.studies.montecarlo.batched_sweep`) and, by forward
mode through the equilibrium's implicit tangent, ``dm_i/dx_j = ∂m_i/∂M · ∂M/∂x_j``; samples go
in padded chunks of one compiled shape, sharded over the JAX devices when there are several
(``jax.shard_map`` over the samples, as :func:`~diffguide.studies.montecarlo.batched_sweep`).

Forward mode, not :func:`jax.grad`: a design has a few variables and reverse mode through the
vmapped implicit solves stores every solve's tape (:mod:`~diffguide.studies.sensitivity`); the
two give the same derivative.

The measures are those of :mod:`~diffguide.studies.tolerance`: ``"roll_difference"`` (the
largest ``max_x |E_AX,i − E_AX,j|`` over corner pairs, rad) or ``"range:ERR:POINT"``. Both are
maxima, differentiable wherever the position (and pair) attaining the maximum is unique — almost
everywhere; the derivative is then that of the maximising term.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..machine.build import build_machine
from ..machine.kinematics import ERROR_NAMES
from ..machine.spec import MachineSpec
from .design_space import apply_all
from .montecarlo import _corner_pairs, _pad, _per_sample, _placement, default_chunk_size
from .random_rails import RailBatch
from .tolerance import parse_range_measure


def _pick(out, measure_index):
    if measure_index is None:
        return jnp.max(out["roll_difference"])
    point, err = measure_index
    return out["ranges"][point, err]


@eqx.filter_jit
def _machine_and_tangents(spec, names, x):
    def dyn(x):
        return eqx.filter(build_machine(apply_all(spec, names, x)), eqx.is_inexact_array)

    eye = jnp.eye(x.shape[0], dtype=x.dtype)
    return jax.vmap(lambda t: jax.jvp(dyn, (x,), (t,)), out_axes=(None, 0))(eye)


@eqx.filter_jit
def _chunk(dyn, tangents, vertical, horizontal, positions, x_ref, *, static, start, spacing,
           pair_idx, measure_index, grad, mesh):
    def local(dyn, tangents, vertical, horizontal, positions, x_ref):
        def one(v, h):
            def f(d):
                out = _per_sample(eqx.combine(d, static), v, h, positions, x_ref, start,
                                  spacing, pair_idx, False)
                return _pick(out, measure_index), out["converged"]

            if not grad:
                y, ok = f(dyn)
                return y, jnp.zeros(0), ok
            y, dy, ok = jax.vmap(lambda t: jax.jvp(f, (dyn,), (t,), has_aux=True),
                                 out_axes=(None, 0, None))(tangents)
            return y, dy, ok

        return jax.vmap(one)(vertical, horizontal)

    if mesh is None:
        return local(dyn, tangents, vertical, horizontal, positions, x_ref)
    P = jax.sharding.PartitionSpec
    spec = (P(), P(), P("samples"), P("samples"), P(), P())
    return jax.shard_map(local, mesh=mesh, in_specs=spec, out_specs=P("samples"),
                         check_vma=False)(
        dyn, tangents, vertical, horizontal, positions, x_ref)


class DesignSweep:
    """The measure of every sample of a fixed rail batch for a design ``x`` (SI), and its
    derivatives: ``sweep(x, grad=True) -> (m (n,), dm/dx (n, k), converged (n,))``.

    Arguments:
        spec: the machine (its mesh as built). names: the design variables
            (:data:`~diffguide.studies.design_space.VARIABLES`). rails: the samples (common to
            every ``x``). positions: table positions (m). measure: ``"roll_difference"`` or
            ``"range:ERR:POINT"``. x_ref: reference position (m). chunk_size: samples per
            compiled call (default :func:`~diffguide.studies.montecarlo.default_chunk_size`;
            rounded up to a multiple of the device count). devices: JAX devices to shard each
            chunk's samples over (default ``jax.devices()``; the machine and its tangents are
            replicated), as :func:`~diffguide.studies.montecarlo.batched_sweep`.
    """

    def __init__(self, spec: MachineSpec, names, rails: RailBatch, positions, measure: str, *,
                 x0, x_ref: float = 0.0, chunk_size: int | None = None, devices=None):
        self.spec, self.names = spec, tuple(names)
        self.rails = rails
        self.positions = jnp.asarray(np.atleast_1d(np.asarray(positions, dtype=float)))
        self.x_ref = jnp.asarray(float(x_ref))
        machine = build_machine(apply_all(spec, self.names, jnp.asarray(x0, dtype=float)))
        self.static = eqx.partition(machine, eqx.is_inexact_array)[1]
        names_p = machine.point_names
        _, self.pair_idx = _corner_pairs(machine, None)
        if measure == "roll_difference":
            if not self.pair_idx:
                raise ValueError("measure 'roll_difference' needs two corner points (off both "
                                 f"table axes); the machine's points: {', '.join(names_p)}")
            self.measure_index = None
        else:
            err, point = parse_range_measure(measure)
            if point not in names_p:
                raise ValueError(f"measure {measure!r}: no control point {point!r}; the "
                                 f"machine's points: {', '.join(names_p)}")
            self.measure_index = (names_p.index(point), ERROR_NAMES.index(err))
        devices = list(jax.devices() if devices is None else devices)
        if chunk_size is not None and not (int(chunk_size) == chunk_size and chunk_size >= 1):
            raise ValueError(f"chunk_size must be an integer >= 1, got {chunk_size!r}")
        n_dev = len(devices)
        c = min(int(chunk_size or default_chunk_size(devices)), len(rails))
        self.chunk = -(-c // n_dev) * n_dev  # a multiple of the device count
        self.mesh, self.put = _placement(devices)
        self.calls = 0

    def __call__(self, x, *, grad: bool = True):
        x = jnp.asarray(np.asarray(x, dtype=float))
        self.calls += 1
        dyn, tangents = _machine_and_tangents(self.spec, self.names, x)
        v_all = np.asarray(self.rails.vertical, dtype=float)
        h_all = np.asarray(self.rails.horizontal, dtype=float)
        n, c = len(self.rails), self.chunk
        ys, dys, oks = [], [], []
        for lo in range(0, n, c):
            hi = min(lo + c, n)
            y, dy, ok = _chunk(dyn, tangents, self.put(_pad(v_all[lo:hi], c)),
                               self.put(_pad(h_all[lo:hi], c)), self.positions, self.x_ref,
                               static=self.static, start=self.rails.start,
                               spacing=self.rails.spacing, pair_idx=self.pair_idx,
                               measure_index=self.measure_index, grad=grad, mesh=self.mesh)
            ys.append(np.asarray(y)[: hi - lo])
            oks.append(np.asarray(ok)[: hi - lo])
            if grad:
                dys.append(np.asarray(dy)[: hi - lo])
        m = np.concatenate(ys)
        dm = np.concatenate(dys) if grad else None
        return m, dm, np.concatenate(oks).astype(bool)
