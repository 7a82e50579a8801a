"""``diffguide montecarlo``: joint-error distributions for random rails (a tolerance study)."""

import argparse
import os
import sys
import time

import numpy as np

from .._core.limits import MAX_SAMPLES, MAX_STUDY_BYTES, check_range, gigabytes
from ._common import add_machine_arguments
from .simulate import default_positions, parse_mesh, parse_positions

_KERNELS = {"se": "squared_exponential", "matern52": "matern52"}
_PLANES = {
    "both": ("vertical", "horizontal"),
    "vertical": ("vertical",),
    "horizontal": ("horizontal",),
}


# diffguide.studies.random_rails.MOUNTING_CLASSES, named here so that --help imports no JAX
# (tests/test_cli_common.py checks they agree)
MOUNTING_CHOICES = ("none", "precision", "size25-ZB", "size25-ZA", "size25-ZO")


def add_study_arguments(p) -> None:
    """The random rails' model (correlation, kernel, planes, mounting), the sweep (positions,
    mesh, rigid table), the batching and the seed: shared by ``montecarlo`` and ``tolerance``."""
    p.add_argument("--corr-mm", type=float, default=200.0,
                   help="correlation length ℓ of the rail deviation (mm)")
    p.add_argument("--kernel", choices=tuple(_KERNELS), default="se",
                   help="covariance: se = squared exponential exp(-τ²/2ℓ²); matern52 = Matérn 5/2")
    p.add_argument("--planes", choices=tuple(_PLANES), default="both",
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


def add_parser(sub) -> None:
    p = sub.add_parser(
        "montecarlo",
        help="distribution of the joint-error ranges and corner roll differences for random rails",
        description="Draw random rail pairs (a stationary Gaussian process per rail and plane, "
        "with the given RMS and correlation length, plus a mounting-tolerance class for rail 2), "
        "solve the sweep for each in batched, compiled chunks, and write per sample the range of "
        "each joint error at each control point (µm, µrad) and the largest roll difference "
        "between each pair of corners over the sweep (µrad).",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    add_machine_arguments(p)
    p.add_argument("--samples", type=int, default=1000,
                   help=f"number of random rail pairs (1..{MAX_SAMPLES})")
    p.add_argument("--rail-rms-um", type=float, default=5.0,
                   help="RMS straightness deviation σ of each rail and plane (µm)")
    add_study_arguments(p)
    p.add_argument("--out", required=True, help="output CSV (one row per sample)")
    p.add_argument("--plot", help="output figure (PNG) of the distributions")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=run)


class _Progress:
    """Plain-text progress on stderr: one updating line on a terminal, else a line per ~10 %."""

    def __init__(self, stream, enabled: bool):
        self.stream, self.enabled = stream, enabled
        self.tty = enabled and stream.isatty()
        self.t0 = time.perf_counter()
        self.first = None  # (time, done) after the first chunk, which includes compilation
        self.last_tenth = -1

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        text = f"  {done}/{total} samples ({done / total:4.0%}), {now - self.t0:.0f} s"
        if self.first is None:
            self.first = (now, done)
            text += f" (first chunk, with compilation: {now - self.t0:.1f} s)"
        elif done > self.first[1]:
            rate = (done - self.first[1]) / max(now - self.first[0], 1e-9)
            text += f", {rate:.0f} samples/s"
            if done < total:
                text += f", about {(total - done) / rate:.0f} s left"
        if self.tty:
            self.stream.write("\r" + text.ljust(78) + ("\n" if done == total else ""))
            self.stream.flush()
        else:
            tenth = int(10 * done / total)
            if tenth != self.last_tenth or done == total:
                self.last_tenth = tenth
                print(text, file=self.stream, flush=True)


def _check(args) -> None:
    check_range(args.samples, 1, MAX_SAMPLES, "--samples", "about 4 kB of memory per sample")
    if not (np.isfinite(args.rail_rms_um) and 0 <= args.rail_rms_um <= 1e4):
        raise ValueError(f"--rail-rms-um must be in 0..10000 µm, got {args.rail_rms_um}")
    check_study(args)


def check_study(args) -> None:
    """Range checks of :func:`add_study_arguments`' options (``ValueError`` naming the flag)."""
    if not (np.isfinite(args.corr_mm) and 1 <= args.corr_mm <= 1e5):
        raise ValueError(f"--corr-mm must be in 1..100000 mm, got {args.corr_mm}")
    if args.chunk is not None and not 1 <= args.chunk <= 100_000:
        raise ValueError(f"--chunk must be in 1..100000, got {args.chunk}")
    if args.cpu_devices is not None and not 1 <= args.cpu_devices <= 256:
        raise ValueError(f"--cpu-devices must be in 1..256, got {args.cpu_devices}")


def summary(result) -> str:
    """Percentiles (5, 50, 95 %) of the ranges at each point and of the corner roll differences."""
    ok = result.converged
    lines = ["percentiles over converged samples (5 % / 50 % / 95 %):"]
    from ..machine.errors import ERRORS

    head = "  point " + "".join(f"{e.name + ' ' + e.unit:>24}" for e in ERRORS)
    lines.append(head)
    for j, p in enumerate(result.point_names):
        cells = []
        for k in range(6):
            values = result.ranges[ok, j, k] * 1e6
            q = np.percentile(values, [5, 50, 95]) if ok.any() else [np.nan] * 3
            cells.append(f"{q[0]:7.3g}/{q[1]:7.3g}/{q[2]:7.3g}")
        lines.append(f"  {p:5} " + "".join(f"{c:>24}" for c in cells))
    if result.pairs and ok.any():
        q = np.percentile(result.max_roll_difference[ok] * 1e6, [5, 50, 95])
        lines.append(
            f"  largest roll difference between corners: {q[0]:.3g} / {q[1]:.3g} / {q[2]:.3g} µrad"
        )
    return "\n".join(lines)


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


def _check_size(n: int, n_coeffs: int, corr_mm: float) -> None:
    """Refuse a study whose rails and results would exceed ``MAX_STUDY_BYTES``, before they are
    drawn (a short correlation length needs more spline coefficients per rail)."""
    from ..studies.random_rails import study_bytes

    need = study_bytes(n, n_coeffs)
    if need > MAX_STUDY_BYTES:
        most = MAX_STUDY_BYTES // study_bytes(1, n_coeffs)
        raise ValueError(f"--samples {n} with --corr-mm {corr_mm:g} (rails of {n_coeffs} spline "
                         f"coefficients per rail and plane) need about {gigabytes(need)}; allowed "
                         f"up to {most} samples at this --corr-mm ({gigabytes(MAX_STUDY_BYTES)})")


def study_setup(args, rms: float, say):
    """The machine, positions (m), rail model (RMS ``rms``, m) and knots of a random-rails
    study from its command line (:func:`add_study_arguments`): ``(name, machine, positions,
    model, knots)``."""
    from ..inverse.fit import visited_range
    from ..jobs.machine import config_machine
    from ..studies.random_rails import GaussianRailModel, default_knots
    from ._common import machine_config

    cfg = machine_config(args)
    positions = default_positions(cfg) if args.positions is None else parse_positions(
        args.positions)
    half = cfg["machine"]["stroke_mm"] / 2
    if np.max(np.abs(positions)) * 1e3 > half + 1e-9:
        raise ValueError(
            f"--positions must lie within the ±{half:g} mm stroke of "
            f"{args.config or args.preset}, got {args.positions!r}"
        )
    nx, ny = parse_mesh(args.mesh) if args.mesh else (None, None)
    model = GaussianRailModel(rms, args.corr_mm * 1e-3, _KERNELS[args.kernel],
                              _PLANES[args.planes])
    name = args.config or args.preset
    if cfg.get("table_source"):
        say(f"building the {name} machine (table imported from "
            f"{cfg['table_source']['given']}) ...")
    else:
        say(f"building the {name} machine (table mesh {args.mesh or 'of the machine file'}) ...")
    machine = config_machine(cfg, nx=nx, ny=ny)  # --mesh on an imported table: refused
    # the rails must cover what the elements visit: the default ±0.6 m knots (majda2012) or,
    # for a longer machine, the visited range with a margin
    lo, hi = visited_range(machine, positions)
    knots = default_knots(model.correlation_length)
    if lo < knots[0] or hi > knots[0] + (knots[2] - 3) * knots[1]:
        knots = default_knots(model.correlation_length, start=lo - 0.05, end=hi + 0.05)
    _check_size(max(args.samples, getattr(args, "check_samples", 0)), knots[2], args.corr_mm)
    if args.rigid_table:
        machine = machine.with_rigid_table()
    return name, machine, positions, model, knots


def run(args) -> int:
    from ..io.atomic import atomic_savefig, atomic_write_text  # here: --help imports no JAX

    _check(args)
    if args.cpu_devices is None or args.cpu_devices > 1:
        split_cpu_into_devices(args.cpu_devices)  # before the first array; no-op afterwards

    from ..studies.montecarlo import batched_sweep
    from ..studies.random_rails import sample_rails

    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    name, machine, positions, model, knots = study_setup(args, args.rail_rms_um * 1e-6, say)
    rails = sample_rails(args.seed, args.samples, model, args.mounting, knots=knots)
    import jax

    say(
        f"{args.samples} samples x {len(positions)} positions, rails σ = {args.rail_rms_um:g} µm, "
        f"ℓ = {args.corr_mm:g} mm ({args.kernel}, {args.planes}), mounting {args.mounting}; "
        f"{len(jax.devices())} device(s) ({jax.devices()[0].platform}); the first chunk compiles"
    )
    result = batched_sweep(
        machine, rails, positions, chunk_size=args.chunk,
        progress=_Progress(sys.stderr, not args.quiet),
    )
    atomic_write_text(args.out, result.to_csv())
    say(f"wrote {args.out}")
    n_bad = int((~result.converged).sum())
    if n_bad:
        print(
            f"diffguide montecarlo: warning: {n_bad} of {result.n_samples} samples did not "
            "converge (converged = 0 in the CSV; left out of the statistics and the plot)",
            file=sys.stderr,
        )
    say(summary(result))
    if args.plot:
        from ..plotting import figure_of
        from ..plotting.montecarlo import plot_monte_carlo

        table = "rigid table" if args.rigid_table else "elastic table"
        title = (
            f"{name}, {table}: rails σ = {args.rail_rms_um:g} µm, ℓ = {args.corr_mm:g} mm "
            f"({args.kernel}, {args.planes}), mounting {args.mounting}, {len(positions)} positions"
        )
        fig = figure_of(plot_monte_carlo(result, title))
        atomic_savefig(fig, args.plot, dpi=110)
        say(f"wrote {args.plot}")
    if n_bad == result.n_samples:
        print("diffguide montecarlo: error: no sample converged", file=sys.stderr)
        return 3
    return 0
