"""Command-line interface: ``diffguide <command> ...``.

Each command lives in its own module exposing ``add_parser(subparsers)`` (which registers the
sub-command and sets ``func``). The CLI enables float64 before anything is computed.
"""

import argparse
import importlib
import importlib.util
import sys

_COMMANDS = ("config", "stiffness", "table", "simulate", "fit", "montecarlo")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="diffguide",
        description="Linear guideways under an elastic machine-tool table: rail errors -> "
        "joint kinematic errors (SI inside; mm, µm, µm/m at the edges).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in _COMMANDS:
        if importlib.util.find_spec(f"diffguide.cli.{name}") is None:  # not built yet
            continue
        importlib.import_module(f"diffguide.cli.{name}").add_parser(sub)
    return parser


def _glue_negative_ranges(argv: list[str]) -> list[str]:
    """``--positions -350:350:71`` → ``--positions=-350:350:71`` (argparse would read the value,
    which starts with '-', as an option)."""
    out, i = [], 0
    while i < len(argv):
        if argv[i].startswith("--") and "=" not in argv[i] and i + 1 < len(argv):
            nxt = argv[i + 1]
            if nxt.startswith("-") and ":" in nxt and nxt[1:2].isdigit():
                out.append(f"{argv[i]}={nxt}")
                i += 2
                continue
        out.append(argv[i])
        i += 1
    return out


def main(argv: list[str] | None = None) -> int:
    import matplotlib

    from .._core.precision import enable_x64

    matplotlib.use("Agg")  # files only: no display needed
    enable_x64()
    parser = build_parser()
    args = parser.parse_args(_glue_negative_ranges(sys.argv[1:] if argv is None else list(argv)))
    try:
        return int(args.func(args) or 0)
    except (ValueError, OSError) as exc:  # bad input: one line, no traceback
        print(f"diffguide {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
