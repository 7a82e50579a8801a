r"""Batched forward sweeps for tolerance studies: many rail sets through one compiled call.

A batch of rail pairs (:class:`~diffguide.studies.random_rails.RailBatch`, a leading sample axis on
spline coefficients) and optionally of machines (:func:`stack_machines`) goes through
:func:`~diffguide.joint_errors` vmapped over the samples, in chunks of ``chunk_size``
samples (bounded memory; the last chunk is padded, so there is one compile), sharded over the
given JAX devices when there are several (``jax.shard_map`` over a 1-D ``"samples"`` mesh; each
device runs its own Newton loops). Per sample, only summary statistics come back unless
``keep_errors=True``:

- the range (peak to peak over the positions) of each joint error at each control point;
- the roll difference between corners ``i`` and ``j``:
  :math:`\max_x |E_{AX,i}(x) - E_{AX,j}(x)|`, the largest disagreement between two levels at
  the corners anywhere in the sweep (zero at ``x_ref``, where both are zero by definition);
- whether every position (and the reference position) converged. Batched solves report per
  sample: a sample that fails does not fail the batch.
"""

import dataclasses
import itertools
import time
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.precision import require_x64
from ..machine.equilibrium import Machine
from ..machine.errors import ERRORS
from ..machine.kinematics import ERROR_NAMES, joint_errors
from .random_rails import RailBatch, rails_from_coefficients

_EAX = ERROR_NAMES.index("EAX")


def default_corners(machine: Machine) -> tuple[str, ...]:
    """Control points off both table axes (``x ≠ 0`` and ``y ≠ 0``): the corners."""
    xy = np.asarray(machine.points_xy)
    xy = xy.reshape(-1, *xy.shape[-2:])[0]  # the first machine of a stacked batch
    return tuple(n for n, (x, y) in zip(machine.point_names, xy) if abs(x) > 1e-9 and abs(y) > 1e-9)


def stack_machines(machines: Sequence[Machine]) -> Machine:
    """One machine pytree whose array leaves carry a leading axis over ``machines`` (for
    ``batched_sweep(..., machine_batched=True)``). The machines must share their structure
    (mesh, carriage layout, control points) and differ only in values (e.g. preload, E)."""
    if len(machines) == 0:
        raise ValueError("machines must not be empty")
    dyn, static = zip(*(eqx.partition(m, eqx.is_array_like) for m in machines))
    if any(
        jax.tree_util.tree_structure(s) != jax.tree_util.tree_structure(static[0]) for s in static
    ):
        raise ValueError("machines must have the same structure to be stacked")
    stacked = jax.tree_util.tree_map(lambda *xs: np.stack([np.asarray(x) for x in xs]), *dyn)
    return eqx.combine(stacked, static[0])


@dataclasses.dataclass(frozen=True)
class MonteCarloResult:
    """Per-sample statistics of a batched sweep (NumPy, SI units).

    Attributes:
        positions: table positions (m). x_ref: reference position (m).
        point_names: control points. pairs: corner pairs ``(i, j)`` (names) of ``roll_difference``.
        ranges: ``(n_samples, n_points, 6)`` peak-to-peak range of EXX, EYX, EZX (m) and EAX,
            EBX, ECX (rad) at each point.
        roll_difference: ``(n_samples, n_pairs)`` ``max_x |EAX_i − EAX_j|`` (rad).
        converged: ``(n_samples,)`` every position of the sample converged.
        errors: ``(n_samples, n_pos, n_points, 6)`` all errors (SI) with ``keep_errors``, else None.
        stats: timings: ``wall_s`` (all), ``first_chunk_s`` (including compilation),
            ``samples_per_s`` (after the first chunk, when there are several), ``n_devices``,
            ``chunk_size``.
    """

    positions: np.ndarray
    x_ref: float
    point_names: tuple[str, ...]
    pairs: tuple[tuple[str, str], ...]
    ranges: np.ndarray
    roll_difference: np.ndarray
    converged: np.ndarray
    errors: np.ndarray | None
    stats: dict

    @property
    def n_samples(self) -> int:
        return self.ranges.shape[0]

    @property
    def max_roll_difference(self) -> np.ndarray:
        """``(n_samples,)``: the largest roll difference over all corner pairs (rad)."""
        if not self.pairs:
            return np.zeros(self.n_samples)
        return self.roll_difference.max(axis=1)

    def columns(self) -> dict[str, np.ndarray]:
        """Per-sample columns in user units (µm, µrad), names with units: ``sample``,
        ``converged``, ``{ERR}_range_{point}_{unit}``, ``roll_diff_{Pi}_{Pj}_urad``,
        ``roll_diff_max_urad``."""
        cols = {"sample": np.arange(self.n_samples), "converged": self.converged.astype(int)}
        for j, p in enumerate(self.point_names):
            for k, e in enumerate(ERRORS):
                cols[f"{e.name}_range_{p}_{e.unit}"] = self.ranges[:, j, k] * e.scale
        for q, (a, b) in enumerate(self.pairs):
            cols[f"roll_diff_{a}_{b}_urad"] = self.roll_difference[:, q] * 1e6
        if self.pairs:
            cols["roll_diff_max_urad"] = self.max_roll_difference * 1e6
        return cols

    def to_csv(self) -> str:
        """The :meth:`columns` as CSV text (one row per sample)."""
        cols = self.columns()
        lines = [",".join(cols)]
        data = np.column_stack([np.asarray(v, dtype=float) for v in cols.values()])
        ints = {"sample", "converged"}
        fmt = [("{:.0f}" if n in ints else "{:.6g}") for n in cols]
        for row in data:
            lines.append(",".join(f.format(v + 0.0) for f, v in zip(fmt, row)))
        return "\n".join(lines) + "\n"


def _per_sample(machine, vertical, horizontal, positions, x_ref, start, spacing, pair_idx, keep):
    rails = rails_from_coefficients(start, spacing, vertical, horizontal)
    je = joint_errors(machine, rails, positions, x_ref)
    e = je.errors
    out = {
        "ranges": jnp.max(e, axis=0) - jnp.min(e, axis=0),
        "converged": jnp.all(je.converged),
    }
    if pair_idx:
        i, j = (jnp.asarray(v) for v in zip(*pair_idx))
        roll = e[:, :, _EAX]
        out["roll_difference"] = jnp.max(jnp.abs(roll[:, i] - roll[:, j]), axis=0)
    if keep:
        out["errors"] = e
    return out


@eqx.filter_jit
def _chunk(
    machine,
    vertical,
    horizontal,
    positions,
    x_ref,
    *,
    start,
    spacing,
    pair_idx,
    keep,
    machine_batched,
    mesh,
):
    def local(machine, vertical, horizontal, positions, x_ref):
        def one(m, v, h):
            return _per_sample(m, v, h, positions, x_ref, start, spacing, pair_idx, keep)

        return jax.vmap(one, in_axes=(0 if machine_batched else None, 0, 0))(
            machine, vertical, horizontal
        )

    if mesh is None:
        return local(machine, vertical, horizontal, positions, x_ref)
    P = jax.sharding.PartitionSpec
    dyn, static = eqx.partition(machine, eqx.is_array)

    def local_dyn(dyn, vertical, horizontal, positions, x_ref):
        return local(eqx.combine(dyn, static), vertical, horizontal, positions, x_ref)

    spec = P("samples")
    sharded = jax.shard_map(
        local_dyn,
        mesh=mesh,
        in_specs=(spec if machine_batched else P(), spec, spec, P(), P()),
        out_specs=spec,
        check_vma=False,
    )
    return sharded(dyn, vertical, horizontal, positions, x_ref)


#: Samples per device and chunk. On CPU small chunks are fastest: every sample of a chunk runs
#: in lockstep until the slowest has converged, and the working set of a large chunk (a 30 × 30
#: tangent per position and sample) falls out of cache. Measured on 2 cores
#: (bench/bench_montecarlo.py): 2–8 samples per chunk took ~1.5× less CPU time than 16 and
#: ~3× less than 256. Accelerators want wide batches.
_CHUNK_PER_DEVICE = {"cpu": 8}
_CHUNK_PER_ACCELERATOR = 1024


def default_chunk_size(devices: Sequence[jax.Device] | None = None) -> int:
    """Default samples per chunk: 8 per CPU device, 1024 per accelerator."""
    devices = list(jax.devices() if devices is None else devices)
    per = _CHUNK_PER_DEVICE.get(devices[0].platform, _CHUNK_PER_ACCELERATOR)
    return per * len(devices)


def _pad(a: np.ndarray, n: int) -> np.ndarray:
    """Pad the leading axis to ``n`` by repeating the last entry (a real, solvable sample)."""
    if a.shape[0] == n:
        return a
    return np.concatenate([a, np.repeat(a[-1:], n - a.shape[0], axis=0)])


def _corner_pairs(machine: Machine, corners):
    """The pairs of ``corners`` (default :func:`default_corners`) whose roll differences are
    reported, by name and by point index."""
    names = machine.point_names
    corners = default_corners(machine) if corners is None else tuple(corners)
    bad = [c for c in corners if c not in names]
    if bad:
        raise ValueError(f"corners must be control points {names}, got {bad}")
    pairs = tuple(itertools.combinations(corners, 2))
    return pairs, tuple((names.index(a), names.index(b)) for a, b in pairs)


def _batched_arrays(dyn, n: int):
    """A stacked machine's arrays (host copies), each checked to have ``n`` samples."""
    sizes = {np.shape(x)[0] for x in jax.tree_util.tree_leaves(dyn)}
    if sizes != {n}:
        raise ValueError(
            f"with machine_batched, every array of machine needs a leading axis of "
            f"len(rails) = {n}; got leading sizes {sorted(sizes)}"
        )
    return jax.tree_util.tree_map(np.asarray, dyn)


def _placement(devices):
    """The sample mesh over several devices (None for one) and a function putting a chunk's
    array on them."""
    mesh = jax.sharding.Mesh(np.array(devices), ("samples",)) if len(devices) > 1 else None
    if mesh is not None:
        place = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("samples"))
        return mesh, lambda a: jax.device_put(a, place)
    return mesh, lambda a: jax.device_put(a, devices[0])


def _run_chunks(launch, starts, n, progress, t0):
    """Every chunk's results (padding cut off), each next chunk queued before waiting for the
    one before; and the seconds to the first chunk's results."""
    parts: list[dict] = []
    t_first = None
    pending = launch(starts[0])
    for k in range(len(starts)):
        hi, out = pending
        if k + 1 < len(starts):  # queue the next chunk before waiting for this one
            pending = launch(starts[k + 1])
        parts.append({key: np.asarray(val)[: hi - starts[k]] for key, val in out.items()})
        if t_first is None:
            t_first = time.perf_counter() - t0
        if progress is not None:
            progress(hi, n)
    return parts, t_first


def batched_sweep(
    machine: Machine,
    rails: RailBatch,
    positions,
    x_ref: float = 0.0,
    *,
    corners: Sequence[str] | None = None,
    chunk_size: int | None = None,
    devices: Sequence[jax.Device] | None = None,
    machine_batched: bool = False,
    keep_errors: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> MonteCarloResult:
    """Joint errors of every rail set in ``rails`` over ``positions``, batched, chunked, sharded.

    Each sample is exactly :func:`~diffguide.machine.kinematics.joint_errors` of ``rails.rails(i)``
    (same solver, same tolerances), vmapped.

    Arguments:
        machine: the machine; with ``machine_batched``, a :func:`stack_machines` pytree with one
            machine per sample.
        rails: the rail pairs, ``len(rails)`` samples.
        positions: table positions (m). x_ref: reference position (m).
        corners: control points whose pairwise roll differences are reported (default
            :func:`default_corners`).
        chunk_size: samples per compiled call (memory bound; rounded up to a multiple of the
            device count). The last chunk is padded, so every chunk has the same shape. Default
            :func:`default_chunk_size`.
        devices: JAX devices to shard each chunk over (default ``jax.devices()``).
        keep_errors: also return every error curve (``n_samples × n_pos × n_points × 6``).
        progress: called as ``progress(done, total)`` after each chunk.

    Returns:
        :class:`MonteCarloResult`.
    """
    require_x64("batched_sweep")
    if not isinstance(rails, RailBatch):
        raise ValueError(f"rails must be a RailBatch, got {type(rails).__name__}")
    devices = list(jax.devices() if devices is None else devices)
    if chunk_size is None:
        chunk_size = default_chunk_size(devices)
    if int(chunk_size) != chunk_size or chunk_size < 1:
        raise ValueError(f"chunk_size must be an integer >= 1, got {chunk_size!r}")
    n = len(rails)
    positions = np.atleast_1d(np.asarray(positions, dtype=float))
    if positions.ndim != 1:
        raise ValueError(f"positions must be 1-D, got shape {positions.shape}")
    names = machine.point_names
    pairs, pair_idx = _corner_pairs(machine, corners)
    dyn, static = eqx.partition(machine, eqx.is_array_like)
    if machine_batched:
        dyn = _batched_arrays(dyn, n)
    n_dev = len(devices)
    chunk = int(-(-min(chunk_size, n) // n_dev) * n_dev)
    mesh, put = _placement(devices)

    vertical = np.asarray(rails.vertical, dtype=float)
    horizontal = np.asarray(rails.horizontal, dtype=float)
    if not machine_batched and mesh is None:  # commit the machine's arrays to the one device
        arrays, rest = eqx.partition(machine, eqx.is_array)
        machine = eqx.combine(jax.device_put(arrays, devices[0]), rest)
    pos_dev = jnp.asarray(positions)
    xref_dev = jnp.asarray(float(x_ref))
    kw = dict(
        start=rails.start,
        spacing=rails.spacing,
        pair_idx=pair_idx,
        keep=keep_errors,
        machine_batched=machine_batched,
        mesh=mesh,
    )

    def launch(lo):
        hi = min(lo + chunk, n)
        v = put(_pad(vertical[lo:hi], chunk))
        h = put(_pad(horizontal[lo:hi], chunk))
        m = machine
        if machine_batched:
            m = eqx.combine(
                jax.tree_util.tree_map(lambda a: put(_pad(a[lo:hi], chunk)), dyn), static
            )
        return hi, _chunk(m, v, h, pos_dev, xref_dev, **kw)  # asynchronous

    t0 = time.perf_counter()
    parts, t_first = _run_chunks(launch, list(range(0, n, chunk)), n, progress, t0)
    wall = time.perf_counter() - t0
    cat = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    rest = n - min(chunk, n)
    stats = {
        "wall_s": wall,
        "first_chunk_s": t_first,
        "samples_per_s": rest / (wall - t_first) if rest > 0 and wall > t_first else float("nan"),
        "n_devices": n_dev,
        "chunk_size": chunk,
    }
    return MonteCarloResult(
        positions=positions,
        x_ref=float(x_ref),
        point_names=names,
        pairs=pairs,
        ranges=cat["ranges"],
        roll_difference=cat.get("roll_difference", np.zeros((n, 0))),
        converged=cat["converged"].astype(bool),
        errors=cat.get("errors"),
        stats=stats,
    )
