"""The random-rail study's options (``design``; the ``montecarlo`` and ``tolerance`` commands
have the same): the rails' model, the sweep, the batching, and the split of the CPU into JAX
devices that the batched sweep shards over (set before JAX starts)."""

import os

from ..jobs.study import KERNELS, MOUNTING_CHOICES, PLANES


def add_study_arguments(p) -> None:
    """The random rails' model (correlation, kernel, planes, mounting), the sweep (positions,
    mesh, rigid table), the batching and the seed: shared by ``design``, ``montecarlo`` and
    ``tolerance``."""
    p.add_argument("--corr-mm", type=float, default=200.0,
                   help="correlation length ℓ of the rail deviation (mm)")
    p.add_argument("--kernel", choices=tuple(KERNELS), default="se",
                   help="covariance: se = squared exponential exp(-τ²/2ℓ²); matern52 = Matérn 5/2")
    p.add_argument("--planes", choices=tuple(PLANES), default="both",
                   help="planes with straightness error")
    p.add_argument("--mounting", choices=MOUNTING_CHOICES, default="none",
                   help="mounting tolerance class of rail 2 relative to rail 1 (parallelism, "
                   "height difference; size-25 catalogue values)")
    p.add_argument("--positions", default=None,
                   help="table positions START:STOP:COUNT (mm; COUNT at most 100000); default: "
                   "the machine's whole stroke at 71 positions")
    p.add_argument("--rigid-table", action="store_true", help="infinitely stiff table")
    p.add_argument("--mesh", default=None,
                   help="table mesh NXxNY (elements); default the machine's own (majda2012: "
                   "20x10); refused for a table imported from an FE model")
    p.add_argument("--chunk", type=int, default=None,
                   help="samples per compiled call (default: 8 per CPU device, 1024 per GPU)")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.add_argument("--cpu-devices", type=int, default=None,
                   help="on CPU, split the cores into this many JAX devices and shard over them "
                   "(default: one per core; 1 = no sharding)")


def split_cpu_into_devices(n: int | None = None) -> bool:
    """Expose the host's cores as ``n`` JAX CPU devices (default: all cores), so that
    :func:`~diffguide.batched_sweep` shards over them and runs one Newton stream per core.

    XLA runs the small, batched operations of a sweep mostly on one thread; separate devices run
    in parallel (bench/bench_montecarlo.py measures the throughput). Sets
    ``--xla_force_host_platform_device_count`` in ``XLA_FLAGS``, which only takes effect before
    JAX initializes its backends (the first array). Returns whether it could still take effect.
    Accelerators are unaffected (``jax.devices()`` stays the GPUs).
    """
    n = (os.cpu_count() or 1) if n is None else int(n)
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_force_host_platform_device_count" in flags:
        return False
    from .._core.compat import backends_initialized

    if backends_initialized():  # None (cannot be told): set the flag and hope
        return False
    os.environ["XLA_FLAGS"] = f"{flags} --xla_force_host_platform_device_count={n}".strip()
    return True
