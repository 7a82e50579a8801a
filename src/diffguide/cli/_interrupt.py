"""Ctrl-C that always stops a command.

A ``KeyboardInterrupt`` raised at an unlucky moment can be swallowed: Python prints and drops
an exception raised in a garbage-collection callback or a ``__del__`` (JAX runs such callbacks),
and the run would go on to replace its outputs and exit 0. So the command's SIGINT handler
*records* each interrupt before raising as usual, and the command checks the record at its
checkpoints - before staging its outputs, before committing them, and at exit - and stops with
exit status 130 without committing.

Two more places where a Ctrl-C printed a traceback instead of the one line: an interrupt raised
inside a garbage-collection callback or ``__del__`` is reported by Python's "unraisable" hook
(``Exception ignored in: ...`` with the traceback) — while the handler is installed that hook
drops a ``KeyboardInterrupt`` (it is recorded already); and one raised inside an exit handler
(``atexit``) is printed by ``atexit`` itself — past the command's last checkpoint, :func:`hold`
makes a SIGINT only recorded, never raised.
"""

import signal
import sys
import threading

#: exit status of an interrupted command (128 + SIGINT, as a shell reports it)
EXIT_INTERRUPTED = 130

_count = 0


_hook = None  # the unraisable hook :func:`install` replaced


def _handler(signum, frame):
    global _count
    _count += 1
    raise KeyboardInterrupt


def _record(signum, frame):
    global _count
    _count += 1


def _unraisable(unraisable) -> None:
    """Python's unraisable hook, less the ``KeyboardInterrupt`` the handler recorded."""
    if isinstance(unraisable.exc_value, KeyboardInterrupt) or (
            isinstance(unraisable.exc_type, type)
            and issubclass(unraisable.exc_type, KeyboardInterrupt)):
        return
    (_hook or sys.__unraisablehook__)(unraisable)


def install():
    """Install the recording SIGINT handler (main thread only; elsewhere nothing is done) and
    clear the record. Returns the previous handler, for :func:`restore`, or ``None``.

    Installed inside an installed handler (the ``diffguide`` command installs it, then the
    command's :func:`~diffguide.cli.main` does), the record is kept: a Ctrl-C that arrived
    between the two, its exception lost, still counts."""
    global _count, _hook
    if threading.current_thread() is not threading.main_thread():
        _count = 0
        return None
    if signal.getsignal(signal.SIGINT) not in (_handler, _record):
        _count = 0
    if sys.unraisablehook is not _unraisable:
        _hook, sys.unraisablehook = sys.unraisablehook, _unraisable
    return signal.signal(signal.SIGINT, _handler)


def restore(previous) -> None:
    """Put back the handler :func:`install` replaced (and, leaving the outermost install,
    Python's unraisable hook)."""
    global _hook
    if previous is not None and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, previous)
        if previous not in (_handler, _record) and sys.unraisablehook is _unraisable:
            sys.unraisablehook, _hook = _hook or sys.__unraisablehook__, None


def hold() -> None:
    """From now on a SIGINT is recorded (:func:`interrupted`) and not raised: the process is
    past its last checkpoint (its exit handlers, its last line, its exit status)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _record)


def interrupted() -> bool:
    """Whether a SIGINT arrived since :func:`install` (even one whose exception was lost)."""
    return _count > 0


def checkpoint() -> None:
    """Raise ``KeyboardInterrupt`` where a SIGINT arrived, caught or not."""
    if _count:
        raise KeyboardInterrupt
