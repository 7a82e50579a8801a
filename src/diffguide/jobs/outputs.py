"""Writing the files of the single-file jobs (``simulate``, ``predict``, ``montecarlo``,
``tolerance``, ``import``): each file atomically (:mod:`diffguide.io.atomic`), in order."""

from pathlib import Path


class Figure:
    """A matplotlib figure to be saved as PNG at ``dpi`` (dots per inch)."""

    def __init__(self, figure, dpi: int):
        self.figure, self.dpi = figure, dpi


def write_files(files: dict) -> list[str]:
    """Write ``{path: text or Figure}`` in order, each atomically; returns the paths."""
    from ..io.atomic import atomic_savefig, atomic_write_text

    for path, content in files.items():
        if isinstance(content, Figure):
            atomic_savefig(content.figure, path, dpi=content.dpi)
        else:
            atomic_write_text(path, content)
    return [str(p) for p in files]


def renamed(files: dict, first: str | Path | None) -> dict:
    """``files`` with its first path replaced by ``first`` (``None``: as it is)."""
    if first is None or not files:
        return dict(files)
    items = list(files.items())
    return {str(first): items[0][1], **dict(items[1:])}
