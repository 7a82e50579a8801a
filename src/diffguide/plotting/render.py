"""Figures drawn and saved by a second Python process, so that a command's figures cost it
(almost) no time.

Importing matplotlib and drawing a command's PNG files takes about two seconds of one core on a
small machine. The command line starts :class:`FigureWorker` first thing: the worker process
imports matplotlib on the other core while the main process imports JAX and computes; when the
results are there, the main process sends the figure jobs (a builder's name and its arguments:
NumPy arrays and plain data) and writes its other files meanwhile; :meth:`FigureWorker.wait`
returns when the PNG files are on disk. Where no worker runs (it could not start, it died, or
the caller never started one) the same jobs are drawn in this process: the files are the same
either way.

The worker never imports JAX: only NumPy, matplotlib and :mod:`diffguide.plotting`.

Protocol (pickle over the worker's stdin/stdout, one message each way per batch): the main
process sends ``(folder, [(file name, FigureJob), ...], dpi)``; the worker answers ``None``
when every file is written, or the formatted traceback of the first failure.
"""

from __future__ import annotations

import dataclasses
import importlib
import os
import pickle
import subprocess
import sys
import traceback
from pathlib import Path


@dataclasses.dataclass(frozen=True)
class FigureJob:
    """A figure to draw: ``builder`` (``"module:function"`` in :mod:`diffguide.plotting`,
    returning a matplotlib ``Figure``) called with ``args`` and ``kwargs`` (picklable)."""

    builder: str
    args: tuple = ()
    kwargs: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        module, _, name = self.builder.partition(":")
        if not module.startswith("diffguide.plotting.") or not name:
            raise ValueError(
                f"builder must be 'diffguide.plotting.<module>:<function>', got {self.builder!r}"
            )

    def draw(self):
        """The Figure (drawn in this process)."""
        module, _, name = self.builder.partition(":")
        return getattr(importlib.import_module(module), name)(*self.args, **self.kwargs)


def save_jobs(folder: Path, jobs: list[tuple[str, FigureJob]], dpi: int) -> None:
    """Draw every job and save it as ``folder / name`` (in this process)."""
    for name, job in jobs:
        job.draw().savefig(Path(folder) / name, dpi=dpi)


class FigureWorker:
    """A process that draws figures (module docstring); a context manager that stops it.

    ``FigureWorker()`` starts nothing; :meth:`start` starts the process. Where it fails to start
    or dies, the jobs are drawn here: the files are written either way.
    """

    def __init__(self):
        self._proc: subprocess.Popen | None = None
        self._pending: list[tuple[Path, list, int, bool]] = []

    def start(self) -> FigureWorker:
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "diffguide.plotting.render"],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                env={**os.environ, "MPLBACKEND": "Agg"},  # the child's own setting: files only
            )
        except OSError:
            self._proc = None
        return self

    @property
    def running(self) -> bool:
        return self._proc is not None and self._proc.poll() is None

    def submit(self, folder: Path, jobs: list[tuple[str, FigureJob]], dpi: int = 110) -> None:
        """Send ``jobs`` to the worker (returns at once); where no worker runs they are drawn
        here in :meth:`wait`."""
        sent = False
        if self.running:
            try:
                pickle.dump((str(folder), jobs, dpi), self._proc.stdin)
                self._proc.stdin.flush()
                sent = True
            except (OSError, pickle.PicklingError):
                self.close()
        self._pending.append((Path(folder), jobs, dpi, sent))

    def wait(self) -> None:
        """Return when every submitted figure is saved. A figure that fails raises
        ``RuntimeError`` with the worker's traceback; a worker that died (or never started)
        leaves its jobs to be drawn here."""
        pending, self._pending = self._pending, []
        for folder, jobs, dpi, sent in pending:
            if sent and self._proc is not None:
                try:
                    answer = pickle.load(self._proc.stdout)
                except (EOFError, OSError, pickle.UnpicklingError):  # died: draw them here
                    self.close()
                else:
                    if answer is None:
                        continue
                    self.close()
                    raise RuntimeError(f"drawing the figures failed:\n{answer}")
            save_jobs(folder, jobs, dpi)

    def close(self) -> None:
        """Stop the worker (it exits when its input closes)."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            proc.stdin.close()
        except OSError:
            pass
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()

    def __enter__(self) -> FigureWorker:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _serve(stdin, stdout) -> None:
    """The worker's loop: import matplotlib's machinery at once, then draw what arrives."""
    import matplotlib.backends.backend_agg  # noqa: F401
    import matplotlib.figure  # noqa: F401

    while True:
        try:
            folder, jobs, dpi = pickle.load(stdin)
        except EOFError:
            return
        try:
            save_jobs(Path(folder), jobs, dpi)
            answer = None
        except Exception:  # reported to the main process, which raises it
            answer = traceback.format_exc()
        pickle.dump(answer, stdout)
        stdout.flush()


if __name__ == "__main__":
    _serve(sys.stdin.buffer, sys.stdout.buffer)
    sys.stdout.flush()
    os._exit(0)  # every file is written: skip the interpreter's teardown (~0.2 s)
