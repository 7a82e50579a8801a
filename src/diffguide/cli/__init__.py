"""Command-line interface: ``diffguide <command> ...``.

Each command lives in its own module exposing ``add_parser(subparsers)`` (which registers the
sub-command and sets ``func``); :mod:`._common` adds the flags all commands share. Parsing
imports neither JAX nor matplotlib (``--help`` and ``--version`` answer at once); the command
then sets up JAX (float64, the compilation cache, see :func:`._runtime.prepare_runtime`).
"""

import argparse
import contextlib
import importlib
import importlib.util
import os
import sys

from . import _interrupt
from ._common import (
    EXIT_BAD_INPUT,
    EXIT_CODES,
    EXIT_INTERNAL,
    HelpFormatter,
    add_common_arguments,
    normalise_mesh,
)
from ._interrupt import EXIT_INTERRUPTED
from ._outputs import check_outputs
from ._runtime import prepare_runtime

#: command -> its module in diffguide.cli
_COMMANDS = {
    "config": "config",
    "stiffness": "stiffness",
    "table": "table",
    "simulate": "simulate",
    "import": "import_",
    "fit": "fit",
    "montecarlo": "montecarlo",
    "tolerance": "tolerance",
    "design": "design",
    "plan": "plan",
    "predict": "predict",
}


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    from .._core.version import __version__

    deps = []
    for dist in ("jax", "jaxlib", "equinox"):
        try:
            deps.append(f"{dist} {version(dist)}")
        except PackageNotFoundError:
            deps.append(f"{dist} missing")
    return f"diffguide {__version__} ({', '.join(deps)}; Python {sys.version.split()[0]})"


class _Version(argparse.Action):
    """``--version``: one unwrapped line (diffguide, its numerical stack, Python)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, **kw):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        print(_version())
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="diffguide",
        description="Linear guideways under an elastic machine-tool table: rail errors -> "
        "joint kinematic errors, and back (SI inside; mm, µm, µm/m at the edges). "
        "'diffguide COMMAND --help' lists a command's options.",
        epilog=EXIT_CODES,
        formatter_class=HelpFormatter,
    )
    parser.add_argument(
        "-V", "--version", action=_Version, help="print the versions of diffguide and its stack"
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, module in _COMMANDS.items():
        if importlib.util.find_spec(f"diffguide.cli.{module}") is None:  # not built yet
            continue
        importlib.import_module(f"diffguide.cli.{module}").add_parser(sub)
        add_common_arguments(sub.choices[name], name)
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
    """Run one command; returns the exit status (see ``EXIT_CODES``)."""
    parser = build_parser()
    args = parser.parse_args(_glue_negative_ranges(sys.argv[1:] if argv is None else list(argv)))
    if "matplotlib" not in sys.modules:
        # files only: no display needed. A caller that has matplotlib already (a notebook)
        # keeps its backend and its figures: the commands draw on bare figures
        os.environ["MPLBACKEND"] = "Agg"
    previous = _interrupt.install()  # every Ctrl-C recorded, even one whose exception is lost
    try:
        code = _run(args)
    except KeyboardInterrupt:
        code = EXIT_INTERRUPTED
    finally:
        _interrupt.restore(previous)
    if _interrupt.interrupted() or code == EXIT_INTERRUPTED:  # the checkpoint at exit
        print(f"diffguide {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return code


def _run(args) -> int:
    """The command, its errors mapped to exit codes (``KeyboardInterrupt`` goes through)."""
    from ..plotting import bare_figures
    from ..plotting.render import FigureWorker

    args.figures = FigureWorker()
    try:
        check_outputs(args, args.command)  # writable, with space: refused before any work
        if getattr(args, "figure_worker", False) and not getattr(args, "no_plots", False):
            args.figures.start()  # before JAX: it imports matplotlib on the other core meanwhile
        normalise_mesh(args, args.command)
        # the command's table and program caches, active while it runs (none: --no-cache)
        caches = prepare_runtime(args) or contextlib.nullcontext()
        with caches, bare_figures():  # the commands' figures are files: none made through pyplot
            return int(args.func(args) or 0)
    except (ValueError, OSError) as exc:  # bad input: one line, no traceback
        if _interrupt.interrupted():  # an error caused by a lost interrupt: 130, said once
            return EXIT_INTERRUPTED
        print(f"diffguide {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Exception:  # a bug: the traceback, and exit status 1
        if _interrupt.interrupted():
            return EXIT_INTERRUPTED
        import traceback

        traceback.print_exc()
        print(
            f"diffguide {args.command}: internal error (exit status 1); please report it with "
            "the traceback above",
            file=sys.stderr,
        )
        return EXIT_INTERNAL
    finally:
        args.figures.close(kill=_interrupt.interrupted())  # interrupted: no 5 s wait for it


def console_main() -> None:
    """The ``diffguide`` command: :func:`main`, then the process ends without tearing down the
    interpreter.

    By then every output is written and closed (atomically) and the exit handlers have run;
    what is skipped is the destruction of JAX's compiled programs and of the module graph,
    which costs about half a second on a small machine for nothing.
    """
    import atexit

    _interrupt.install()  # here too: a Ctrl-C during the exit handlers counts as well
    try:
        code = main()
    except KeyboardInterrupt:  # before main's handler, or while main reports the first one
        code = None
    finally:  # past the last checkpoint: a Ctrl-C is recorded, never raised (atexit would print
        _interrupt.hold()  # its traceback; so would the last line and the flush below)
    try:
        atexit._run_exitfuncs()  # logging, JAX and anything else registered
    except KeyboardInterrupt:
        pass
    if code is None or (_interrupt.interrupted() and code != EXIT_INTERRUPTED):
        with contextlib.suppress(OSError, ValueError):
            print("diffguide: interrupted", file=sys.stderr)
        code = EXIT_INTERRUPTED
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a reader gone (a closed pipe): the status still counts
            pass
    os._exit(code)


if __name__ == "__main__":
    console_main()
