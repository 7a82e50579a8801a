"""Crash-consistent outputs: the output folder swapped in with no gap, the leftovers of killed
runs removed by the next run, every Ctrl-C stopping the run with exit status 130, and output
places checked before the work."""

import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from diffguide._core import atomic
from diffguide.cli import main

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"


def _stage(out: Path, text: str) -> Path:
    tmp = atomic.staging_dir(out)
    (tmp / "report.json").write_text(text)
    return tmp


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


# --- the swap ----------------------------------------------------------------------------------

def test_exchange_swaps_two_folders_here(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    (a / "x").write_text("a"), (b / "x").write_text("b")
    if not atomic.exchange(a, b):
        pytest.skip("renameat2(RENAME_EXCHANGE) is not offered here (the two-rename swap is used)")
    assert (a / "x").read_text() == "b" and (b / "x").read_text() == "a"


def test_replace_dir_never_leaves_the_output_missing(tmp_path):
    """A reader stat()ing out/report.json in a loop never misses it during 200 swaps."""
    out = tmp_path / "out"
    atomic.replace_dir(_stage(out, "0"), out)  # no earlier folder: a plain rename
    misses, reads, stop = [], [0], threading.Event()

    def reader():
        while not stop.is_set():
            try:
                os.stat(out / "report.json")
            except FileNotFoundError:
                misses.append(1)
            reads[0] += 1

    t = threading.Thread(target=reader)
    t.start()
    try:
        for i in range(1, 201):
            atomic.replace_dir(_stage(out, str(i)), out)
    finally:
        stop.set()
        t.join()
    assert reads[0] > 200
    if not atomic.exchange(tmp_path, tmp_path):  # a probe: exchanging a name with itself
        pytest.skip("no atomic exchange here")
    assert not misses, f"out/report.json missing in {len(misses)} of {reads[0]} reads"
    assert (out / "report.json").read_text() == "200"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]  # the earlier folders removed


def test_two_rename_fallback_gives_the_same_result(tmp_path, monkeypatch):
    out = tmp_path / "out"
    atomic.replace_dir(_stage(out, "old"), out)
    monkeypatch.setattr(atomic, "exchange", lambda a, b: False)
    atomic.replace_dir(_stage(out, "new"), out)
    assert (out / "report.json").read_text() == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


@pytest.mark.parametrize("exchange_offered", [True, False])
def test_ctrl_c_during_the_swap_completes_it(tmp_path, monkeypatch, exchange_offered):
    """SIGINT arriving in the middle of the swap: held, then raised once the new folder is in."""
    out = tmp_path / "out"
    atomic.replace_dir(_stage(out, "old"), out)
    real = atomic.exchange

    def exchange_interrupted(a, b):
        signal.raise_signal(signal.SIGINT)  # the Python handler runs at once where not held
        return real(a, b) if exchange_offered else False

    monkeypatch.setattr(atomic, "exchange", exchange_interrupted)
    with pytest.raises(KeyboardInterrupt):
        atomic.replace_dir(_stage(out, "new"), out)
    assert (out / "report.json").read_text() == "new"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


# --- leftovers ---------------------------------------------------------------------------------

def test_leftovers_of_dead_runs_are_removed_and_nothing_else(tmp_path):
    dead, alive = _dead_pid(), os.getppid()
    old_stamp = time.time() - 2 * 86400
    gone = [f".out.{dead}.abcd1234.tmp", f".out.{dead}.x_y9zz00.old", ".out.k3j4h5g6.tmp"]
    kept = [f".out.{alive}.abcd1234.tmp", f".out.{os.getpid()}.abcd1234.tmp",
            ".out.q1w2e3r4.old",  # no pid, fresh: its owner may be running
            f".other.{dead}.abcd1234.tmp", f"out.{dead}.abcd1234.tmp",
            f".out.{dead}.abcd1234.bak", f".out.v2.{dead}.abcd1234.tmp", "out", "notes.txt"]
    for name in gone[:2] + kept:
        (tmp_path / name).mkdir()
        (tmp_path / name / "report.json").write_text("{}")
    (tmp_path / gone[2]).write_text("a probe file")  # a file, not a folder
    os.utime(tmp_path / gone[2], (old_stamp, old_stamp))
    removed = atomic.remove_leftovers(tmp_path / "out")
    assert sorted(p.name for p in removed) == sorted(gone)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(kept)


def test_staging_names_carry_the_pid_and_are_kept_while_it_lives(tmp_path):
    tmp = atomic.staging_dir(tmp_path / "out")
    assert tmp.name.startswith(f".out.{os.getpid()}.") and tmp.name.endswith(".tmp")
    assert atomic.remove_leftovers(tmp_path / "out") == [] and tmp.is_dir()


# --- early refusals ----------------------------------------------------------------------------

def _forbid_run(monkeypatch, command):
    import importlib

    module = importlib.import_module(f"diffguide.cli.{command}")
    monkeypatch.setattr(module, "run", lambda args: pytest.fail("the work started"))


def _fit_argv(out):
    return ["fit", "--measurements", str(DATA), "--mesh", "6x3", "--out", str(out), "-q"]


@pytest.mark.parametrize("where", ["under_a_file", "proc"])
def test_unwritable_output_folder_is_refused_before_any_work(tmp_path, capsys, monkeypatch,
                                                             where):
    """For root as well: a folder under a file, or in /proc, cannot be created by anyone."""
    if where == "under_a_file":
        (tmp_path / "a_file").write_text("x")
        out, folder = tmp_path / "a_file" / "sub" / "out", tmp_path / "a_file"
    else:
        if not Path("/proc/self").is_dir():
            pytest.skip("no /proc")
        out, folder = Path("/proc/diffguide_out"), Path("/proc")
    _forbid_run(monkeypatch, "fit")
    assert main(_fit_argv(out)) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err and str(folder) in err


def test_full_output_disk_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    free = 3 * 2**20
    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda p: usage._replace(free=free))
    _forbid_run(monkeypatch, "plan")
    assert main(["plan", "--out", str(tmp_path / "plan")]) == 2
    err = capsys.readouterr().err
    assert "MB free" in err and str(tmp_path) in err
    _forbid_run(monkeypatch, "simulate")
    assert main(["simulate", "--out", str(tmp_path / "e.csv")]) == 2
    assert "MB free" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # the probe removed, nothing written


def test_file_output_under_a_file_is_refused(tmp_path, capsys, monkeypatch):
    (tmp_path / "f").write_text("x")
    _forbid_run(monkeypatch, "simulate")
    assert main(["simulate", "--out", str(tmp_path / "e.csv"),
                 "--plot", str(tmp_path / "f" / "p.png")]) == 2
    assert "--plot" in capsys.readouterr().err


# --- Ctrl-C ------------------------------------------------------------------------------------

def _swallowed_sigint():
    """A SIGINT whose KeyboardInterrupt is lost (as in a garbage-collection callback)."""
    try:
        signal.raise_signal(signal.SIGINT)
    except KeyboardInterrupt:
        pass


@pytest.mark.parametrize("when", ["before_commit", "after_commit"])
def test_a_swallowed_ctrl_c_still_exits_130_without_committing(tmp_path, capsys, monkeypatch,
                                                               when):
    from diffguide.cli import _outputs, fit
    from diffguide.io import outdir

    out = tmp_path / "out"
    out.mkdir()
    (out / "report.json").write_text('"previous"')
    (out / outdir.MARKER).write_text(outdir.marker_text("fit", ["report.json"]))

    def run(args):
        with _outputs.output_folder(args, "fit") as staged:
            staged.write({"report.json": '"new"'})
            if when == "before_commit":
                _swallowed_sigint()
            staged.commit()
        if when == "after_commit":
            _swallowed_sigint()
        return 0

    monkeypatch.setattr(fit, "run", run)
    assert main(_fit_argv(out)) == 130
    assert capsys.readouterr().err == "diffguide fit: interrupted\n"
    expected = '"previous"' if when == "before_commit" else '"new"'
    assert (out / "report.json").read_text() == expected
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back


# --- the real command, killed and interrupted at random ----------------------------------------

def _soak_module():
    spec = importlib.util.spec_from_file_location("kill_soak", ROOT / "bench" / "kill_soak.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_random_kills_and_ctrl_cs_during_fit_leave_a_complete_result(tmp_path):
    """8 SIGKILLs and 8 SIGINTs at random times during ``diffguide fit`` (coarse mesh):
    ``out/`` always a complete result, every SIGINT exit 130, no leftovers after the next run
    (bench/kill_soak.py runs 100 + 100)."""
    soak = _soak_module()
    out = tmp_path / "out"
    tally = soak.soak(out, kills=8, interrupts=8, seed=int(os.environ.get("KILL_SEED", "1")),
                      log=lambda *a: None)
    assert not tally["failures"], "\n".join(tally["failures"])
    assert tally["killed"] + tally["interrupted"] >= 12, tally  # most runs were really stopped
    assert tally["exit_130"] == tally["interrupted"]
    assert json.loads((out / "report.json").read_text())


def test_an_interrupt_recorded_before_a_nested_install_is_kept():
    """The ``diffguide`` command installs the recording handler and then ``main`` installs it
    again: a Ctrl-C between the two whose exception was lost must still count."""
    from diffguide.cli import _interrupt

    outer = _interrupt.install()
    try:
        with pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGINT)  # recorded; the exception "lost" (caught here)
        inner = _interrupt.install()  # main()'s own install
        assert inner is _interrupt._handler
        assert _interrupt.interrupted()
        _interrupt.restore(inner)
    finally:
        _interrupt.restore(outer)
    assert signal.getsignal(signal.SIGINT) is outer
    _interrupt.install()  # a fresh command (the handler not installed): the record is cleared
    try:
        assert not _interrupt.interrupted()
    finally:
        _interrupt.restore(outer)
