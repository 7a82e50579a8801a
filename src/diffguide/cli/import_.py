"""``diffguide import``: measurement files in any supported layout, or read through a profile,
-> one canonical long CSV (``--explain``: what was read, and how); the work is
:func:`diffguide.jobs.import_job`."""

import argparse
import sys

from ._common import PRESETS
from ._input_options import add_input_options


def add_parser(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "import",
        help="convert measurement files (long or wide layout, or any table through a profile; "
        "several files merge into one data set) into the canonical long CSV that 'diffguide "
        "fit' reads; --explain shows what was read",
        description="Read measurement files - the long layout (one reading per row), the wide "
        "'targets x runs' layout (metadata lines point, x_mm, y_mm, quantity, unit[, "
        "instrument, sigma, z_mm, x0_mm], then target_mm;run1_fwd;run1_bwd;...), or any "
        "vendor table through a profile (--profile: built-in exx, iso230-2-summary, 6dof, "
        "long, wide, or a TOML file) - in UTF-8, UTF-16 or cp1252, with ',', ';', tab or "
        "whitespace separators and decimal commas, units µm, mm, nm, in, µin, µm/m, mm/m, "
        "µrad, mrad, rad, arcsec, arcmin, deg, differential level pairs, and write the "
        "canonical long CSV (µm and µm/m; position_mm = machine position - x0). Several files "
        "are one data set (a point at two places, or a channel at two heights, is refused "
        "naming both files). Extra columns are ignored with a note. See README 'File formats'.",
    )
    p.add_argument("input", metavar="FILE", nargs="+", help="measurement file(s)")
    p.add_argument("--format", dest="layout", choices=("auto", "long", "wide"), default="auto",
                   help="layout of FILE without --profile (default: detected from its first "
                   "line)")
    add_input_options(p, " of all the files")
    p.add_argument("--allow-many-positions", action="store_true",
                   help="merge a file with more than 1000 distinct table positions (refused "
                   "otherwise: thousands, nearly one per reading, is what swapped position and "
                   "value columns look like)")
    p.add_argument("--explain", action="store_true",
                   help="print what was read and how: layout or profile, encoding, separator, "
                   "decimal mark, columns -> quantities and units, metadata, x0, rows read and "
                   "lines skipped (--out is then optional)")
    p.add_argument("--out", metavar="FILE.csv", default=None, help="canonical long CSV to write")
    p.add_argument("--draft-profile", metavar="OUT.toml", default=None,
                   help="write a draft profile for FILE from its own layout and metadata "
                   "(separator, decimal mark, encoding, header row, position column and unit, "
                   "value columns and units, run/direction columns, metadata lines) and stop; "
                   "complete its lines marked REQUIRED, then --profile OUT.toml "
                   "(docs/file-formats.md, 'Draft profiles'); an existing OUT.toml is refused")
    p.add_argument("--overwrite-draft", action="store_true",
                   help="with --draft-profile: replace an existing OUT.toml")
    p.add_argument("--preset", default=None, choices=PRESETS,
                   help="with --draft-profile: list this machine's control points in the draft")
    p.add_argument("--config", metavar="MACHINE.toml", default=None,
                   help="with --draft-profile: list this machine's control points in the draft")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=run)
    return p


def settings_from_args(args):
    """The :class:`diffguide.jobs.ImportSettings` of the parsed options (checked there)."""
    from ..jobs import ImportSettings

    return ImportSettings(**{k: getattr(args, k) for k in ImportSettings.fields()
                             if hasattr(args, k)})


def run(args) -> int:
    from ..jobs import import_job

    res = import_job(settings_from_args(args))
    if res.draft is not None:  # --draft-profile: what is left to write, on the console
        path, = res.write()
        if not args.quiet:
            todo = res.todo
            left = (f"{len(todo)} line(s) marked REQUIRED to complete: {', '.join(todo)}"
                    if todo else "nothing marked REQUIRED; confirm the lines marked CHECK")
            print(f"wrote {path}: draft profile for {args.input[0]}; {left}; then: "
                  f"diffguide import {args.input[0]} --profile {path} --explain")
        return 0
    if args.explain:
        print("\n".join(res.explain_lines()))
    res.write()
    if not args.quiet:
        for n in res.notes:
            print(f"diffguide import: note: {n}", file=sys.stderr)
        meas = res.measurements
        print(f"{'wrote ' + args.out if args.out else 'read'}: {len(res.readings)} readings from "
              f"{len(args.input)} file(s) ({meas.n} merged rows in {len(meas.channels)} "
              "channels)")
    return 0
