"""``diffguide config``: write a machine configuration (TOML) to standard output or a file."""

import sys

from ._common import PRESETS


def add_parser(sub) -> None:
    p = sub.add_parser(
        "config",
        help="write a preset's machine configuration (TOML) to edit and pass with --config",
        description="Print every parameter of a machine as TOML, units in the key names "
        "(mm, GPa, N, kg/m3, degrees). Edit it and pass it to any command with --config FILE; "
        "with --check FILE, validate a file instead.",
    )
    p.add_argument("--preset", default="majda2012", choices=PRESETS, help="machine to write")
    p.add_argument(
        "--out", metavar="FILE.toml", help="write to this file instead of standard output"
    )
    p.add_argument("--check", metavar="MACHINE.toml", help="validate this file and report")
    p.add_argument("--explain", metavar="MACHINE.toml",
                   help="print the machine this file resolves to, each value with its source "
                   "(the file, the runner-block catalogue with what was published, chosen or "
                   "calibrated, or the default)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..io.atomic import atomic_write_text
    from ..io.config import default_config, dump_config, explain_config, load_config

    if args.explain:
        sys.stdout.write(explain_config(args.explain))
        return 0
    if args.check:
        cfg = load_config(args.check)
        if not args.quiet:
            print(f"{args.check}: valid ({len(cfg['points'])} control points)")
        return 0
    text = dump_config(default_config(), title=args.preset)
    if args.out:
        atomic_write_text(args.out, text)
    else:
        sys.stdout.write(text)
    return 0
