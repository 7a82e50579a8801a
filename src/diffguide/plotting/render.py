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
when every file is written, or ``(exception or None, formatted traceback)`` of the first failure
(the exception where it pickles: an ``OSError`` is raised again as such).
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
        if not sys.executable or getattr(sys, "frozen", False):
            return self  # no Python interpreter to start (embedded or frozen): drawn here
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "diffguide.plotting.render"],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                env={**os.environ, "MPLBACKEND": "Agg"},  # the child's own setting: files only
            )
        except (OSError, ValueError, TypeError):
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
                message = pickle.dumps((str(folder), jobs, dpi))
                self._proc.stdin.write(message)
                self._proc.stdin.flush()
                sent = True
            except Exception:  # not picklable (TypeError, AttributeError, ...) or a dead pipe
                self.close(kill=True)
        self._pending.append((Path(folder), jobs, dpi, sent))

    def wait(self) -> None:
        """Return when every submitted figure is saved. A figure that fails raises its error
        (``OSError`` as such: a full disk, a missing folder; any other as ``RuntimeError``) with
        the worker's traceback; a worker that died (or never started) leaves its jobs to be
        drawn here."""
        pending, self._pending = self._pending, []
        for folder, jobs, dpi, sent in pending:
            if sent and self._proc is not None:
                try:
                    answer = pickle.load(self._proc.stdout)
                except (EOFError, OSError, pickle.UnpicklingError):  # died: draw them here
                    self.close(kill=True)
                else:
                    if answer is None:
                        continue
                    self.close(kill=True)
                    error, trace = answer
                    if isinstance(error, OSError):
                        error.add_note(f"(in the figures' process)\n{trace}")
                        raise error
                    raise RuntimeError(f"drawing the figures failed:\n{trace}")
            save_jobs(folder, jobs, dpi)

    def close(self, kill: bool = False) -> None:
        """Stop the worker: at once where it has nothing to draw (or ``kill``), else when it
        has saved what it was sent (it exits when its input closes; 5 s at most)."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        if kill or not any(sent for *_, sent in self._pending):
            proc.kill()
        else:
            try:
                proc.stdin.close()
            except OSError:
                pass
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
        proc.wait()
        for pipe in (proc.stdin, proc.stdout):
            try:
                pipe.close()
            except OSError:
                pass

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
        except Exception as exc:  # reported to the main process, which raises it
            trace = traceback.format_exc()
            try:
                pickle.dumps(exc)
            except Exception:
                exc = None
            answer = (exc, trace)
        pickle.dump(answer, stdout)
        stdout.flush()


if __name__ == "__main__":
    _serve(sys.stdin.buffer, sys.stdout.buffer)
    sys.stdout.flush()
    os._exit(0)  # every file is written: skip the interpreter's teardown (~0.2 s)
