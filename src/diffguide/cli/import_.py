"""``diffguide import``: measurement files in any supported layout, or read through a profile,
-> one canonical long CSV (``--explain``: what was read, and how)."""

import argparse
import sys

from ..jobs.inputs import load_profile_args
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


def explain_lines(infos) -> list[str]:
    """``--explain``'s lines, one block per file."""
    out = []
    for info in infos:
        out.append(f"{info['file']}:")
        out.append(f"  layout: {info.get('layout')}; encoding: {info.get('encoding')}; "
                   f"separator: {info.get('separator')!r}; decimal mark: "
                   f"{info.get('decimal')!r}")
        if info.get("metadata"):
            out.append("  metadata: " + "; ".join(f"{k} = {v}" for k, v in
                                                  info["metadata"].items()))
        if info.get("header"):
            out.append(f"  header (line {info['header_line']}): {', '.join(info['header'])}")
        for block in info.get("blocks", []):
            out.append(f"  block {block}")
        if info.get("position_column"):
            out.append(f"  positions: column {info['position_column']!r}")
        for col, what in info.get("columns", {}).items():
            shown = ", ".join(what[:4]) + (f" (+{len(what) - 4} more)" if len(what) > 4 else "")
            out.append(f"  column {col!r} -> {shown}")
        if info.get("channels"):
            out.append(f"  channels: {', '.join(info['channels'])}")
        out.append(f"  x0 = {info['x0_mm']:g} mm ({info['x0_source']})")
        read = [f"{info['readings']} readings" if "readings" in info else "",
                f"{info['rows']} table rows" if "rows" in info else "",
                f"{info['missing_cells']} empty cells (missing readings)"
                if info.get("missing_cells") else "",
                f"lines skipped: {', '.join(map(str, info['lines_skipped'][:10]))}"
                if info.get("lines_skipped") else "",
                f"sections skipped: {', '.join(info['blocks_skipped'][:6])}"
                if info.get("blocks_skipped") else ""]
        out.append("  " + "; ".join(r for r in read if r))
    return out


def draft(args) -> int:
    """``--draft-profile``: the draft of FILE's profile, written atomically (refused over an
    existing file unless ``--overwrite-draft``); what is left to write, on the console."""
    from ..io.profile_draft import draft_profile, write_draft

    if len(args.input) != 1 or args.profile or args.out:
        raise ValueError("--draft-profile drafts one FILE's profile (without --profile and "
                         "--out); then read it: --profile OUT.toml")
    points = None
    if args.config or args.preset:
        from ._common import machine_config

        points = machine_config(args)["points"]
    text, todo = draft_profile(args.input[0], args.encoding, points)
    write_draft(args.draft_profile, text, args.overwrite_draft)
    if not args.quiet:
        left = (f"{len(todo)} line(s) marked REQUIRED to complete: {', '.join(todo)}" if todo
                else "nothing marked REQUIRED; confirm the lines marked CHECK")
        print(f"wrote {args.draft_profile}: draft profile for {args.input[0]}; {left}; then: "
              f"diffguide import {args.input[0]} --profile {args.draft_profile} --explain")
    return 0


def run(args) -> int:
    from ..io.atomic import atomic_write_text
    from ..io.importers import format_long, import_many
    from ..io.measurements import merge_readings

    if args.draft_profile is not None:
        return draft(args)
    if args.out is None and not args.explain:
        raise ValueError("diffguide import: --out FILE.csv is required (or --explain)")
    notes: list[str] = []
    infos: list[dict] = []
    readings = import_many(args.input, args.layout, args.x0_mm, notes, infos,
                           profile=load_profile_args(args, args.input), encoding=args.encoding)
    for info in infos:
        mine = [r for r in readings if r.source == info["file"]]
        info["readings"] = len(mine)
        info["channels"] = sorted({f"{r.quantity} at {r.point} ({r.instrument})" for r in mine})
    source = ", ".join(args.input)
    meas = merge_readings(readings, source=source, notes=notes,  # validates what fit sees
                          allow_many_positions=args.allow_many_positions,
                          allow_conflicts=args.accept_file_conflicts)
    if args.explain:
        print("\n".join(explain_lines(infos)))
    if args.out is not None:
        x0 = "; ".join(f"{i['file']}: x0 = {i['x0_mm']:g} mm" for i in infos)
        text = format_long(readings, comment=f"imported from {source} by diffguide import\n"
                                             f"positions are table positions x ({x0})")
        atomic_write_text(args.out, text)
    if not args.quiet:
        for n in notes:
            print(f"diffguide import: note: {n}", file=sys.stderr)
        print(f"{'wrote ' + args.out if args.out else 'read'}: {len(readings)} readings from "
              f"{len(args.input)} file(s) ({meas.n} merged rows in {len(meas.channels)} "
              "channels)")
    return 0
