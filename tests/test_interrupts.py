"""Ctrl-C gives one line and exit status 130, never a traceback, in the two places where it did
(``bench/kill_soak.py`` with the signal sent to the process group: ``Exception ignored in:
<function _xla_gc_callback ...> ... KeyboardInterrupt`` in 1 of 10 interrupted fits): an
interrupt raised inside a garbage-collection callback (Python's unraisable hook printed it) and
one raised inside an exit handler (``atexit`` printed it). Each is made to happen at once here:
in process for the hook, in a subprocess of ``diffguide config`` for the two of them end to
end (about a second each: no fit)."""

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from diffguide.cli import _interrupt
from diffguide.cli._interrupt import EXIT_INTERRUPTED

ROOT = Path(__file__).resolve().parents[1]


class _RaisesInDel:
    def __init__(self, exc):
        self.exc = exc

    def __del__(self):
        raise self.exc


def test_the_handler_drops_an_interrupt_lost_in_a_callback_and_nothing_else(monkeypatch):
    seen = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: seen.append(u.exc_type))
    before = sys.unraisablehook
    outer = _interrupt.install()
    try:
        _RaisesInDel(KeyboardInterrupt())  # dropped at once: unraisable
        assert seen == []
        _RaisesInDel(RuntimeError("a real bug in a __del__"))  # still reported
        assert seen == [RuntimeError]
    finally:
        _interrupt.restore(outer)
    assert sys.unraisablehook is before and signal.getsignal(signal.SIGINT) is outer
    _interrupt.hold()  # past the last checkpoint: recorded, not raised
    try:
        signal.raise_signal(signal.SIGINT)
        assert _interrupt.interrupted()
    finally:
        signal.signal(signal.SIGINT, outer)


SCRIPT = """
import atexit, gc, os, signal, sys
sys.argv = ["diffguide", "config", "--out", sys.argv[1]]
where = os.environ["WHERE"]
if where == "atexit":
    atexit.register(lambda: (signal.raise_signal(signal.SIGINT), print("exit handler done")))
from diffguide.cli import console_main
if where == "gc":
    def once(phase, info, done=[]):
        if not done and phase == "start":
            done.append(1)
            signal.raise_signal(signal.SIGINT)
    gc.callbacks.append(once)
    _orig = __import__("diffguide.cli._runtime", fromlist=["x"]).prepare_runtime
    def prepare(args):
        out = _orig(args)
        gc.collect()  # a collection while the command runs: its callback raises
        return out
    import diffguide.cli
    diffguide.cli.prepare_runtime = prepare
console_main()
"""


@pytest.mark.parametrize("where", ["gc", "atexit"])
def test_ctrl_c_in_a_gc_callback_or_an_exit_handler_is_one_line_and_130(where, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "WHERE": where,
           "TF_CPP_MIN_LOG_LEVEL": "3"}
    out = tmp_path / "machine.toml"
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(out)], env=env, text=True,
                          capture_output=True, timeout=120)
    assert "Traceback" not in proc.stderr and "Exception ignored" not in proc.stderr, proc.stderr
    assert proc.returncode == EXIT_INTERRUPTED, proc.stderr
    assert len(proc.stderr.splitlines()) == 1 and proc.stderr.rstrip().endswith(": interrupted")
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no partial file
