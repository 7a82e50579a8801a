"""``diffguide tolerance``: the loosest rail grade that keeps an error measure within a limit at
a stated probability; the work is :func:`diffguide.jobs.tolerance_job`."""

import argparse
import sys

from ._common import add_machine_arguments
from ._study_options import add_study_arguments, split_devices


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


def settings_from_args(args):
    """The :class:`diffguide.jobs.ToleranceSettings` of the parsed options (checked there)."""
    from ..jobs import ToleranceSettings

    return ToleranceSettings(**{k: getattr(args, k) for k in ToleranceSettings.fields()
                                if hasattr(args, k)})


def run(args) -> int:
    from ..jobs import tolerance_job

    settings = settings_from_args(args)
    split_devices(args)  # before the first array
    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    res = tolerance_job(settings, progress=None if args.quiet else say)
    if not args.quiet:
        print(res.report())
    if args.out:
        for path in res.write(args.out):
            say(f"wrote {path}")
    return 0
