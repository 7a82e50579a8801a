"""``diffguide import``: a measurement file in any supported layout -> the canonical long CSV."""

import argparse
import sys


def add_parser(sub) -> argparse.ArgumentParser:
    p = sub.add_parser(
        "import",
        help="convert a measurement file (long or wide layout, any separator, decimal comma) "
        "into the canonical long CSV that 'diffguide fit' reads",
        description="Read a measurement file - the long layout (one reading per row) or the wide "
        "'targets x runs' layout (ISO 230-2 style: metadata lines point, x_mm, y_mm, quantity, "
        "unit[, instrument, sigma, z_mm], then target_mm;run1_fwd;run1_bwd;...) - with ',', ';' "
        "or tab separators and decimal commas, units µm, mm, nm, in, µm/m, mm/m, µrad, mrad, "
        "arcsec, arcmin, deg, differential level pairs (a 'reference' column or run<k>_<dir>_ref "
        "columns: measuring minus reference), and write the canonical long CSV "
        "(position_mm,point,x_mm,y_mm,quantity,value,unit,sigma,run,direction,instrument,z_mm; "
        "µm and µm/m; position_mm = machine position - x0). Extra columns are ignored with a "
        "note. See README 'File formats'.",
    )
    p.add_argument("input", metavar="FILE", help="measurement file")
    p.add_argument(
        "--format",
        dest="layout",
        choices=("auto", "long", "wide"),
        default="auto",
        help="layout of FILE (default: detected from its first line)",
    )
    p.add_argument(
        "--x0-mm",
        type=float,
        default=None,
        help="machine coordinate (mm) of the table position x = 0 (the model's "
        "reference, the middle of the stroke); default: 0 for the long layout (its "
        "position_mm is x already), the middle of the measured targets for the wide one",
    )
    p.add_argument("--allow-many-positions", action="store_true",
                   help="merge a file with more than 1000 distinct table positions (refused "
                   "otherwise: thousands, nearly one per reading, is what swapped position and "
                   "value columns look like)")
    p.add_argument("--out", required=True, metavar="FILE.csv", help="canonical long CSV to write")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    from ..io.atomic import atomic_write_text
    from ..io.importers import format_long, import_readings
    from ..io.measurements import merge_readings

    notes: list[str] = []
    readings = import_readings(args.input, args.layout, args.x0_mm, notes)
    meas = merge_readings(readings, source=args.input, notes=notes,  # validates what fit sees
                          allow_many_positions=args.allow_many_positions)
    text = format_long(readings, comment=f"imported from {args.input} by diffguide import")
    atomic_write_text(args.out, text)
    if not args.quiet:
        for n in notes:
            print(f"diffguide import: note: {n}", file=sys.stderr)
        print(
            f"wrote {args.out}: {len(readings)} readings ({meas.n} merged rows in "
            f"{len(meas.channels)} channels)"
        )
    return 0
