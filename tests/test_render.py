"""The figures' process (diffguide.plotting.render): the same files as drawn here, failures
reported, and drawing here when no process runs."""

import numpy as np
import pytest

from diffguide.plotting.render import FigureJob, FigureWorker, save_jobs


def _channels():
    x = np.linspace(-300.0, 300.0, 13)
    return [(f"E{q}X at P{k}", "µm/m", x, np.sin(x / 100 + k), 0.1 + 0 * x,
             np.sin(x / 100 + k) + 0.01, None) for k, q in enumerate("ABC")]


def _jobs():
    s = np.linspace(-0.4, 0.4, 50)
    val = np.stack([np.stack([np.sin(8 * s + r + p) for p in range(2)]) for r in range(2)]) * 1e-6
    return [
        ("curves.png", FigureJob("diffguide.plotting.fit:curves_figure", (_channels(),))),
        ("profiles.png", FigureJob("diffguide.plotting.fit:profiles_figure",
                                   (s, {"elastic": (val, 0.1e-6 + 0 * val)}))),
    ]


def test_worker_writes_the_same_files_as_drawing_here(tmp_path):
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    save_jobs(here, _jobs(), dpi=60)
    with FigureWorker().start() as worker:
        assert worker.running
        worker.submit(there, _jobs(), dpi=60)
        worker.wait()
        worker.submit(there, _jobs()[:1], dpi=60)  # a second batch to the same process
        worker.wait()
    for name in ("curves.png", "profiles.png"):
        a, b = (here / name).read_bytes(), (there / name).read_bytes()
        assert a[:8] == b"\x89PNG\r\n\x1a\n"
        assert a == b, name  # Agg draws the same pixels in any process


def test_a_failing_figure_raises_with_the_workers_traceback(tmp_path):
    bad = [("x.png", FigureJob("diffguide.plotting.fit:curves_figure", ([("only label",)],)))]
    with FigureWorker().start() as worker:
        worker.submit(tmp_path, bad)
        with pytest.raises(RuntimeError, match="(?s)drawing the figures failed.*ValueError"):
            worker.wait()
        assert not worker.running  # stopped after a failure; later jobs are drawn here
        worker.submit(tmp_path, _jobs()[:1], dpi=40)
        worker.wait()
    assert (tmp_path / "curves.png").exists()


def test_without_a_process_the_jobs_are_drawn_here(tmp_path):
    worker = FigureWorker()  # never started
    worker.submit(tmp_path, _jobs(), dpi=40)
    assert not (tmp_path / "curves.png").exists()  # drawn when waited for
    worker.wait()
    assert (tmp_path / "curves.png").exists() and (tmp_path / "profiles.png").exists()


def test_a_job_names_a_plotting_function():
    with pytest.raises(ValueError, match="diffguide.plotting"):
        FigureJob("os:system", ("true",))


def test_a_dead_worker_leaves_its_jobs_to_be_drawn_here(tmp_path):
    worker = FigureWorker().start()
    worker._proc.kill()  # dies before (or while) it draws
    worker._proc.wait()
    worker.submit(tmp_path, _jobs(), dpi=40)
    worker.wait()
    worker.close()
    assert (tmp_path / "curves.png").exists() and (tmp_path / "profiles.png").exists()


def test_a_worker_that_dies_after_the_jobs_were_sent_still_gives_the_files(tmp_path):
    worker = FigureWorker().start()
    worker.submit(tmp_path, _jobs(), dpi=40)
    worker._proc.kill()  # most likely still importing matplotlib
    worker.wait()
    worker.close()
    assert (tmp_path / "curves.png").exists() and (tmp_path / "profiles.png").exists()


def test_a_file_error_in_the_worker_is_raised_as_the_same_oserror(tmp_path):
    """A missing folder (or a full disk) is the user's error, not a bug: the worker's
    ``FileNotFoundError`` comes back as such, as when drawn here."""
    missing = tmp_path / "gone"
    with pytest.raises(FileNotFoundError):
        save_jobs(missing, _jobs()[:1], dpi=40)
    with FigureWorker().start() as worker:
        worker.submit(missing, _jobs()[:1], dpi=40)
        with pytest.raises(FileNotFoundError) as info:
            worker.wait()
    assert any("figures' process" in note for note in info.value.__notes__)


def test_a_job_that_does_not_pickle_is_drawn_here(tmp_path):
    """A job the pipe cannot carry (here a lambda in its arguments) falls back to this process,
    where it meets the same error as it would without a worker."""
    job = FigureJob("diffguide.plotting.fit:curves_figure", (_channels(),), {"bad": lambda: 0})
    with FigureWorker().start() as worker:
        worker.submit(tmp_path, [("x.png", job)])
        assert not worker.running
        with pytest.raises(TypeError, match="bad"):
            worker.wait()


def test_close_stops_an_idle_worker_at_once():
    """Nothing sent: the worker is killed, not waited for (it may still import matplotlib)."""
    worker = FigureWorker().start()
    proc = worker._proc
    worker.close()
    assert proc.returncode is not None and proc.returncode != 0
