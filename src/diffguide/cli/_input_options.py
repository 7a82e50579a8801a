"""How measurement files are read, as options (``import`` and ``fit`` share them): nothing
heavy imported, so ``--help`` stays fast."""

import argparse


def x0_value(text: str):
    """``--x0-mm``'s value: a number (mm) or ``middle``."""
    if text.strip().lower() == "middle":
        return "middle"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a number (mm) or 'middle', got {text!r}") from None


def add_input_options(p, several: str) -> None:
    """The options that say how measurement files are read (import and fit share them)."""
    p.add_argument("--profile", metavar="NAME|FILE.toml", action="append", default=None,
                   help="read the file(s) through a profile: a built-in one ("
                   "exx, iso230-2-summary, 6dof, long, wide) or a TOML file mapping a vendor's "
                   "table onto the readings (README 'File formats', docs/file-formats.md); "
                   "once for every file, or once per file in their order ('auto': that file "
                   "in a canonical layout); default: the canonical long/wide layouts, detected")
    p.add_argument("--profile-set", metavar="[PROFILE:]KEY=VALUE", action="append",
                   default=None,
                   help="set a [reading] key of the profile (repeatable), e.g. point=P5, "
                   "x_mm=0, sign=-1; with several --profile options, name the one it is for: "
                   "exx:point=P5 (it applies to the files read through that profile only)")
    p.add_argument("--accept-file-conflicts", action="store_true",
                   help="merge files that read a channel with opposite signs (refused by "
                   "default, naming both: a reversed sensor), each conflict then a note")
    p.add_argument("--encoding", default=None, metavar="NAME",
                   help="text encoding of the file(s): utf-8, utf-16, cp1252, latin-1 or any "
                   "Python codec name; default: the profile's, else detected (byte-order mark, "
                   "UTF-16's NUL bytes, UTF-8, else cp1252)")
    p.add_argument("--x0-mm", type=x0_value, default=None, metavar="MM|middle",
                   help="machine coordinate (mm) of the table position x = 0 (the model's "
                   "reference, mid-stroke) in the measurement file(s): x = position - x0; "
                   "'middle': the middle of the measured targets" + several + "; default: the "
                   "file's own statement (a wide file's x0_mm line, a profile's x0_mm), else 0 "
                   "in every layout (fit: also the compensation table's x0 unless "
                   "--machine-x0-mm; simulate's --x0-mm only places its compensation table)")
