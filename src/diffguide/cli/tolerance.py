"""``diffguide tolerance``: the loosest rail grade that keeps an error measure within a limit at
a stated probability (:func:`diffguide.studies.tolerance.allocate_grade`)."""

import argparse
import json
import sys

import numpy as np

from ._common import add_machine_arguments
from .montecarlo import add_study_arguments, check_study, split_cpu_into_devices, study_setup


def add_parser(sub) -> None:
    p = sub.add_parser(
        "tolerance",
        help="the loosest rail straightness grade for which an error stays within a limit",
        description="Tolerance allocation: the largest RMS straightness of the rails (µm; a "
        "stationary Gaussian process per rail and plane, with the given correlation length, plus "
        "rail 2's mounting class, fixed) for which MEASURE stays within LIMIT with the given "
        "probability, by a root-find on the Monte Carlo quantile with the same random rails at "
        "every trial grade; its 95 % interval from the quantile's order statistics; then a "
        "plain Monte Carlo on fresh rails at that grade as a check.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    add_machine_arguments(p)
    p.add_argument("--measure", default="roll_difference",
                   help="'roll_difference' (the largest roll difference between two corners over "
                   "the sweep, µrad) or 'range:ERR:POINT' (the range of one joint error at one "
                   "control point, e.g. range:EBX:P1; µm for EXX/EYX/EZX, µrad for angles)")
    p.add_argument("--limit", type=float, required=True,
                   help="the limit on MEASURE (µm or µrad, as MEASURE)")
    p.add_argument("--probability", type=float, default=0.95,
                   help="the probability that MEASURE stays within LIMIT")
    p.add_argument("--samples", type=int, default=256,
                   help="random rail pairs of the search (the same at every trial grade)")
    p.add_argument("--check-samples", type=int, default=256,
                   help="fresh random rail pairs of the check at the grade found (0: no check)")
    add_study_arguments(p)
    p.add_argument("--out", help="also write the result as JSON (µm, µrad)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=run)


def _check(args) -> None:
    if not 16 <= args.samples <= 1_000_000:
        raise ValueError(f"--samples must be in 16..1000000, got {args.samples}")
    if not 0 <= args.check_samples <= 1_000_000:
        raise ValueError(f"--check-samples must be in 0..1000000, got {args.check_samples}")
    if not (np.isfinite(args.limit) and args.limit > 0):
        raise ValueError(f"--limit must be a number > 0 (µm or µrad), got {args.limit}")
    if not 0 < args.probability < 1:
        raise ValueError(f"--probability must be in (0, 1), got {args.probability}")
    check_study(args)


def report(res, unit: str) -> str:
    """The result in words (µm, µrad)."""
    lo, hi = res.interval
    lines = [f"rail straightness grade for {res.measure} <= {res.limit * 1e6:g} {unit} at "
             f"probability {res.probability:g}: {res.grade * 1e6:.3g} µm RMS per rail and plane "
             f"(95 % interval {lo * 1e6:.3g} .. {hi * 1e6:.3g} µm from {res.n_samples} samples; "
             f"{len(res.evaluations)} batched sweeps, {res.seconds:.0f} s)"]
    if res.failed:
        lines.append(f"  {res.failed} samples did not converge at that grade (counted as "
                     "breaking the limit)")
    if res.check is not None:
        c = res.check
        verdict = ("consistent" if c.holds else "NOT consistent: the search's samples are "
                   "not representative, use more --samples")
        lines.append(f"check on {c.n} fresh samples at that grade: {c.fraction:.1%} within the "
                     f"limit (95 % interval {c.interval[0]:.1%} .. {c.interval[1]:.1%}) against "
                     f"the search's {c.claimed[0]:.1%} .. {c.claimed[1]:.1%}: {verdict}")
    return "\n".join(lines)


def as_json(res, unit: str) -> dict:
    """The result for ``--out`` (µm for grades; the measure's unit for its values)."""
    out = {"measure": res.measure, "unit": unit, "limit": res.limit * 1e6,
           "probability": res.probability, "grade_um": res.grade * 1e6,
           "interval_um": [v * 1e6 for v in res.interval], "samples": res.n_samples,
           "failed": res.failed, "seconds": res.seconds,
           "evaluations": [{"grade_um": s * 1e6, "quantile_low": lo * 1e6, "quantile": q * 1e6,
                            "quantile_high": hi * 1e6} for s, lo, q, hi in res.evaluations]}
    if res.check is not None:
        c = res.check
        out["check"] = {"samples": c.n, "seed": c.seed, "fraction": c.fraction,
                        "interval": list(c.interval), "claimed": list(c.claimed),
                        "holds": c.holds}
    return out


def run(args) -> int:
    from ..io.atomic import atomic_write_text  # here: --help imports no JAX

    _check(args)
    if args.cpu_devices is None or args.cpu_devices > 1:
        split_cpu_into_devices(args.cpu_devices)  # before the first array; no-op afterwards
    from ..studies.tolerance import allocate_grade, measure_unit

    unit = measure_unit(args.measure)  # a malformed --measure fails here, before any solve
    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    name, machine, positions, model, knots = study_setup(args, 1e-6, say)
    say(f"searching the grade: {args.samples} samples x {len(positions)} positions per trial "
        f"(the first compiles)")
    res = allocate_grade(
        machine, positions, measure=args.measure, limit=args.limit * 1e-6,
        probability=args.probability, correlation_length=model.correlation_length,
        kernel=model.kernel, planes=model.planes,
        mounting=None if args.mounting == "none" else args.mounting,
        n_samples=args.samples, check_samples=args.check_samples, seed=args.seed,
        knots=knots, chunk_size=args.chunk, progress=None if args.quiet else say,
    )
    if not args.quiet:
        print(report(res, unit))
    if args.out:
        atomic_write_text(args.out, json.dumps(as_json(res, unit), indent=2) + "\n")
        say(f"wrote {args.out}")
    return 0
