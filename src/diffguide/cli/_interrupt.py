"""Ctrl-C that always stops a command.

A ``KeyboardInterrupt`` raised at an unlucky moment can be swallowed: Python prints and drops
an exception raised in a garbage-collection callback or a ``__del__`` (JAX runs such callbacks),
and the run would go on to replace its outputs and exit 0. So the command's SIGINT handler
*records* each interrupt before raising as usual, and the command checks the record at its
checkpoints - before staging its outputs, before committing them, and at exit - and stops with
exit status 130 without committing.
"""

import signal
import threading

#: exit status of an interrupted command (128 + SIGINT, as a shell reports it)
EXIT_INTERRUPTED = 130

_count = 0


def _handler(signum, frame):
    global _count
    _count += 1
    raise KeyboardInterrupt


def install():
    """Install the recording SIGINT handler (main thread only; elsewhere nothing is done) and
    clear the record. Returns the previous handler, for :func:`restore`, or ``None``.

    Installed inside an installed handler (the ``diffguide`` command installs it, then the
    command's :func:`~diffguide.cli.main` does), the record is kept: a Ctrl-C that arrived
    between the two, its exception lost, still counts."""
    global _count
    if threading.current_thread() is not threading.main_thread():
        _count = 0
        return None
    if signal.getsignal(signal.SIGINT) is not _handler:
        _count = 0
    return signal.signal(signal.SIGINT, _handler)


def restore(previous) -> None:
    """Put back the handler :func:`install` replaced."""
    if previous is not None and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, previous)


def interrupted() -> bool:
    """Whether a SIGINT arrived since :func:`install` (even one whose exception was lost)."""
    return _count > 0


def checkpoint() -> None:
    """Raise ``KeyboardInterrupt`` where a SIGINT arrived, caught or not."""
    if _count:
        raise KeyboardInterrupt
