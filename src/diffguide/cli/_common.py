"""What every command shares: the machine (``--preset`` / ``--config``), ``--quiet``, the mesh
(``--mesh NXxNY``), the help layout and the exit codes (the JAX set-up and the compilation
cache: :mod:`._runtime`).

Nothing here imports JAX or matplotlib: ``diffguide --help`` must answer at once.
"""

import argparse
import os

from .._core.limits import MAX_MESH_DIVISIONS

PRESETS = ("majda2012",)

# One OpenBLAS thread for NumPy and SciPy (and JAX's CPU LAPACK kernels, which call SciPy's):
# the commands' dense algebra is on matrices of ~10² rows, where threads gain nothing, and on
# a machine shared with other jobs OpenBLAS's waiting threads stalled it several-fold
# (bench/bench_cli.py measures the commands). OpenBLAS reads this when NumPy is first
# imported, so it is set here, before any command imports NumPy; set OPENBLAS_NUM_THREADS
# yourself to override it.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

#: exit statuses of every command (also in the README and each ``--help`` epilogue)
EXIT_OK, EXIT_INTERNAL, EXIT_BAD_INPUT, EXIT_NOT_CONVERGED = 0, 1, 2, 3

EXIT_CODES = """\
exit status:
  0  success
  2  bad input or options (one line on stderr naming the file, line/key and allowed range;
     nothing written)
  3  a solve did not converge (fit: results written and flagged in report.json; other
     commands: the positions are named and nothing is written)
  1  internal error (a bug: please report it with the traceback)
  130  interrupted (Ctrl-C): the outputs are the earlier ones or the complete new ones"""

#: commands that build the table mesh, and so take ``--mesh``
MESH_COMMANDS = ("table", "simulate", "fit", "montecarlo", "plan", "tolerance", "design")

class HelpFormatter(argparse.HelpFormatter):
    """Wraps paragraphs, keeps indented blocks (the exit-code table) as written, and shows a
    default once, only where the help text does not already state it."""

    def _fill_text(self, text, width, indent):
        out = []
        for para in text.split("\n\n"):
            if "\n " in para or para.startswith(" ") or para.startswith("exit status"):
                out.append("\n".join(indent + line for line in para.splitlines()))
            else:
                out.append(super()._fill_text(para, width, indent))
        return "\n\n".join(out)

    def _get_help_string(self, action):
        text = action.help or ""
        if (
            "%(default)" in text
            or "default" in text.lower()
            or action.default in (None, False, True, argparse.SUPPRESS)
            or action.option_strings == []
        ):
            return text
        return text + " (default: %(default)s)"


def add_machine_arguments(p, presets: tuple[str, ...] = PRESETS) -> None:
    p.add_argument(
        "--preset",
        default="majda2012",
        choices=presets,
        help="built-in machine (the paper's vertical machining centre)",
    )
    p.add_argument(
        "--config",
        metavar="MACHINE.toml",
        help="machine configuration file (TOML, units in the key names; see "
        "'diffguide config'); overrides --preset",
    )


def say(args, text: str) -> None:
    """Print a progress line unless ``--quiet``."""
    if not args.quiet:
        print(text, flush=True)


def machine_config(args) -> dict:
    """The validated configuration chosen by ``--config`` or ``--preset``
    (:func:`diffguide.jobs.study.machine_config`)."""
    from ..jobs.study import machine_config as config

    return config(args)


def machine_spec(args):
    """The :class:`~diffguide.machine.spec.MachineSpec` (SI) chosen by ``--config`` or
    ``--preset``."""
    from ..io.config import spec_from_config

    return spec_from_config(machine_config(args))


def parse_mesh_text(text: str, most: int = MAX_MESH_DIVISIONS) -> tuple[int, int]:
    """``"20x10"`` → ``(20, 10)``, each in ``1..most`` (:func:`diffguide.jobs.positions.
    parse_mesh`, the one parser of ``--mesh``)."""
    from ..jobs.positions import parse_mesh

    return parse_mesh(text, most)


def _has(p: argparse.ArgumentParser, flag: str) -> bool:
    return flag in p._option_string_actions


def add_common_arguments(p: argparse.ArgumentParser, name: str) -> None:
    """Give the sub-command ``name`` the flags every command shares (those it does not define
    itself), the help layout and the exit-code epilogue."""
    p.formatter_class = HelpFormatter
    p.epilog = EXIT_CODES if not p.epilog else p.epilog + "\n\n" + EXIT_CODES
    g = p.add_argument_group("common options")
    if not _has(p, "--quiet"):
        g.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    if name in MESH_COMMANDS:
        if not _has(p, "--mesh"):
            g.add_argument(
                "--mesh",
                metavar="NXxNY",
                default=None,
                help="table mesh: uniform divisions along X and Y before the footprint lines "
                "(default: the machine's, 20x10 for majda2012)",
            )
    g.add_argument(
        "--cache-dir",
        metavar="DIR",
        default=None,
        help="persistent JAX compilation cache, and condensed tables in its 'tables' "
        "sub-folder: a second run of the same command compiles almost nothing and condenses "
        "nothing (default: $DIFFGUIDE_CACHE_DIR, else ~/.cache/diffguide/jax)",
    )
    g.add_argument(
        "--no-cache",
        action="store_true",
        help="use neither the compilation cache nor the cache of condensed tables",
    )


def normalise_mesh(args, name: str) -> None:
    """One mesh for the command: ``--mesh NXxNY`` sets ``args.nx``/``args.ny`` (``None``
    without it: the machine's own mesh); a clear ``ValueError`` for a malformed ``--mesh``."""
    if name not in MESH_COMMANDS:
        return
    mesh = getattr(args, "mesh", None)
    args.nx, args.ny = (None, None) if mesh is None else parse_mesh_text(mesh)
