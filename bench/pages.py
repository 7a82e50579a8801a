"""What the bench scripts that write generated pages share: the machine's name and the
replacement of a page's block between its markers (imports nothing of the bench, so that
make_table.py, suite_table.py and test_matrix.py can all use it)."""

import platform
import re
import sys
from pathlib import Path


def cpu_model() -> str:
    """The CPU's model name (Linux ``/proc/cpuinfo``), else ``platform.processor()``."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()



def write_between(page: Path, begin: str, end: str, block: str) -> None:
    """Replace the text of ``page`` from the marker ``begin`` to ``end`` (both included; the
    ``block`` carries them) by ``block``; exit naming the page if the markers are missing."""
    text = page.read_text(encoding="utf-8")
    pattern = re.compile(re.escape(begin) + ".*?" + re.escape(end), re.S)
    if not pattern.search(text):
        sys.exit(f"{page}: no {begin} ... {end} markers")
    page.write_text(pattern.sub(lambda _: block, text), encoding="utf-8")
