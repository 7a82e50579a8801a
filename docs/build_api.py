"""Build the API reference (HTML) from the docstrings with pdoc.

    python docs/build_api.py [OUT_DIR]        # default build/api; open OUT_DIR/index.html

Needs the ``docs`` extra (``pip install -e ".[docs]"``). The top-level package lists its public
API in ``__all__``, so its layers are named here explicitly.
"""

import sys
from pathlib import Path

MODULES = [
    "diffguide",
    "diffguide.contact",
    "diffguide.guideway",
    "diffguide.fe",
    "diffguide.machine",
    "diffguide.inverse",
    "diffguide.studies",
    "diffguide.io",
    "diffguide.plotting",
]


def build(out: Path) -> Path:
    """Write the reference into ``out``; returns its ``index.html``."""
    import matplotlib

    matplotlib.use("Agg")
    import pdoc

    pdoc.render.configure(docformat="restructuredtext", math=True, footer_text="diffguide")
    pdoc.pdoc(*MODULES, output_directory=Path(out))
    return Path(out) / "index.html"


if __name__ == "__main__":
    index = build(Path(sys.argv[1] if len(sys.argv) > 1 else "build/api"))
    print(f"wrote {index}")
