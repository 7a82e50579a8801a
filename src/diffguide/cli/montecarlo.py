"""``diffguide montecarlo``: joint-error distributions for random rails (a tolerance study);
the work is :func:`diffguide.jobs.montecarlo_job`."""

import argparse
import sys
import time

from .._core.limits import MAX_SAMPLES
from ._common import add_machine_arguments
from ._study_options import add_study_arguments, split_devices


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


def settings_from_args(args):
    """The :class:`diffguide.jobs.MontecarloSettings` of the parsed options (checked there)."""
    from ..jobs import MontecarloSettings

    return MontecarloSettings(**{k: getattr(args, k) for k in MontecarloSettings.fields()
                                 if hasattr(args, k)})


def run(args) -> int:
    from ..jobs import montecarlo_job

    settings = settings_from_args(args)
    split_devices(args)  # before the first array
    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    res = montecarlo_job(settings, progress=say,
                         sample_progress=_Progress(sys.stderr, not args.quiet))
    out, *rest = res.write(args.out)
    say(f"wrote {out}")
    if res.n_failed:
        print(
            f"diffguide montecarlo: warning: {res.n_failed} of {res.result.n_samples} samples "
            "did not converge (converged = 0 in the CSV; left out of the statistics and the "
            "plot)", file=sys.stderr,
        )
    say(res.summary())
    for path in rest:
        say(f"wrote {path}")
    if res.exit_code:
        print("diffguide montecarlo: error: no sample converged", file=sys.stderr)
    return res.exit_code
