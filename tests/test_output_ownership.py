"""Output folders: a command replaces only a folder it wrote itself (its marker), never the
working folder or a parent of it, never a folder holding anything else; output files are never
folders. Every refusal comes before the work, with exit status 2 and nothing written."""

import importlib
import os
from pathlib import Path
from types import SimpleNamespace

import pytest

from diffguide._core import atomic
from diffguide.cli import main
from diffguide.cli._outputs import output_folder, write_dir
from diffguide.io import outdir

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"


def _forbid_run(monkeypatch, command):
    module = importlib.import_module(f"diffguide.cli.{command}")
    monkeypatch.setattr(module, "run", lambda args: pytest.fail("the work started"))


def _argv(command, out):
    if command == "fit":
        return ["fit", "--preset", "majda2012", "--measurements", str(DATA), "--out", str(out),
                "-q"]
    return ["plan", "--out", str(out), "-q"]


def _project(folder: Path) -> dict:
    """A user's project folder that happens to hold a report.json: its files and content."""
    (folder / "src").mkdir(parents=True)
    (folder / "src" / "a.c").write_text("k\n")
    (folder / "report.json").write_text("{}\n")
    return _snapshot(folder)


def _snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): (p.read_text() if p.is_file() else None)
            for p in sorted(folder.rglob("*"))}


@pytest.mark.parametrize("command", ["fit", "plan"])
def test_out_dot_in_a_project_folder_is_refused_before_the_work(tmp_path, monkeypatch, capsys,
                                                                command):
    """The issue's reproduction: ``--out .`` in a folder with src/ and a report.json."""
    before = _project(tmp_path)
    monkeypatch.chdir(tmp_path)
    _forbid_run(monkeypatch, command)
    assert main(_argv(command, ".")) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err and str(tmp_path) in err
    assert "working folder" in err
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("command", ["fit", "plan"])
def test_parent_of_the_working_folder_is_refused(tmp_path, monkeypatch, capsys, command):
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    _forbid_run(monkeypatch, command)
    assert main(_argv(command, "..")) == 2
    assert "parent of the working folder" in capsys.readouterr().err
    assert main(_argv(command, "/")) == 2
    assert "--out /" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["fit", "plan"])
def test_non_empty_folder_without_marker_is_refused(tmp_path, monkeypatch, capsys, command):
    out = tmp_path / "results"
    before = _project(out)
    _forbid_run(monkeypatch, command)
    assert main(_argv(command, out)) == 2
    err = capsys.readouterr().err
    assert f"--out {out}" in err and outdir.MARKER in err and "refusing" in err
    assert _snapshot(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results"]  # nothing staged


def _earlier_output(out: Path, command="fit", files=("report.json", "rails.csv")) -> None:
    write_dir(SimpleNamespace(out=out), command, {name: f"old {name}\n" for name in files})


def test_another_commands_output_is_refused(tmp_path, monkeypatch, capsys):
    out = tmp_path / "o"
    _earlier_output(out, "fit")
    _forbid_run(monkeypatch, "plan")
    assert main(_argv("plan", out)) == 2
    assert "'diffguide fit'" in capsys.readouterr().err
    assert (out / "rails.csv").read_text() == "old rails.csv\n"


@pytest.mark.parametrize("extra", ["notes.txt", "sub/"])
def test_an_earlier_output_with_user_files_added_is_refused(tmp_path, monkeypatch, capsys,
                                                            extra):
    out = tmp_path / "o"
    _earlier_output(out)
    if extra.endswith("/"):
        (out / extra).mkdir()
    else:
        (out / extra).write_text("mine\n")
    _forbid_run(monkeypatch, "fit")
    assert main(_argv("fit", out)) == 2
    err = capsys.readouterr().err
    assert extra.rstrip("/") in err and "did not write" in err
    assert (out / "report.json").read_text() == "old report.json\n"


def test_a_forged_marker_listing_other_names_does_not_cover_them(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    (out / "thesis.tex").write_text("precious")
    (out / outdir.MARKER).write_text('{"command": "fit", "files": ["../x"]}')
    with pytest.raises(ValueError, match="no .diffguide-output.json"):
        outdir.check_output_dir(out, "fit")


def test_an_earlier_output_is_replaced_and_its_marker_lists_the_new_files(tmp_path):
    out = tmp_path / "o"
    _earlier_output(out, files=("report.json", "rails.csv", "old_only.png"))
    write_dir(SimpleNamespace(out=out), "fit", {"report.json": "new\n", "fit.csv": "new\n"})
    assert sorted(p.name for p in out.iterdir()) == [outdir.MARKER, "fit.csv", "report.json"]
    marker = outdir.read_marker(out)
    assert marker["command"] == "fit" and marker["files"] == ["fit.csv", "report.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]  # no staging, no previous


def test_an_existing_empty_folder_is_used(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    write_dir(SimpleNamespace(out=out), "plan", {"plan.csv": "x\n"})
    assert outdir.read_marker(out)["files"] == ["plan.csv"]


def test_files_added_during_the_work_stop_the_replacement(tmp_path, monkeypatch):
    """Checked again just before the swap: a file the user put into the folder while the
    command ran stops it (exit 2 from the command line), and the folder stays as it was."""
    out = tmp_path / "o"
    _earlier_output(out)
    with pytest.raises(ValueError, match="new.txt"):
        with output_folder(SimpleNamespace(out=out), "fit") as staged:
            staged.write({"report.json": "new\n"})
            (out / "new.txt").write_text("added meanwhile\n")
            staged.commit()
    assert (out / "report.json").read_text() == "old report.json\n"
    assert (out / "new.txt").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]


def test_a_file_slipped_in_at_the_swap_is_kept(tmp_path, monkeypatch):
    """The last moment (after the last check, before the swap): the previous folder's listed
    files are removed, an unlisted one kept beside it, with a warning."""
    out = tmp_path / "o"
    _earlier_output(out)
    real = outdir.check_output_dir

    def check_then_add(path, command, flag="--out"):
        result = real(path, command, flag)
        (Path(path) / "late.txt").write_text("late\n")
        return result

    staged = output_folder(SimpleNamespace(out=out), "fit")
    staged.write({"report.json": "new\n"})
    monkeypatch.setattr(outdir, "check_output_dir", check_then_add)
    with pytest.warns(UserWarning, match="kept"):
        staged.commit()
    kept = tmp_path / f"o.kept-{os.getpid()}"
    assert [p.name for p in kept.iterdir()] == ["late.txt"]
    assert (out / "report.json").read_text() == "new\n"


@pytest.mark.parametrize("command,argv", [
    ("predict", ["predict", "--fit", "F", "--point", "Q:0,0", "--out"]),
    ("design", ["design", "--vary", "x", "--out"]),
    ("design", ["design", "--vary", "x", "--json"]),
    ("tolerance", ["tolerance", "--limit", "1", "--out"]),
    ("simulate", ["simulate", "--out"]),
    ("montecarlo", ["montecarlo", "--out"]),
])
def test_an_output_file_that_is_a_folder_is_refused_before_the_work(tmp_path, monkeypatch,
                                                                    capsys, command, argv):
    folder = tmp_path / "folder"
    folder.mkdir()
    _forbid_run(monkeypatch, command)
    assert main([*argv, str(folder)]) == 2
    err = capsys.readouterr().err
    assert f"{argv[-1]} {folder}" in err and "is a folder" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder"]
    assert list(folder.iterdir()) == []


@pytest.mark.parametrize("path", ["/", ".", "sub/"])
def test_an_output_file_named_like_a_folder_is_refused(tmp_path, monkeypatch, capsys, path):
    monkeypatch.chdir(tmp_path)
    _forbid_run(monkeypatch, "tolerance")
    assert main(["tolerance", "--limit", "1", "--out", path]) == 2
    assert "is a folder" in capsys.readouterr().err


def test_atomic_write_to_a_folder_leaves_no_temporary_file(tmp_path):
    with pytest.raises(IsADirectoryError):
        atomic.atomic_write(tmp_path, lambda tmp: Path(tmp).write_text("x"))
    assert list(tmp_path.iterdir()) == [] and not list(tmp_path.parent.glob(f".{tmp_path.name}*"))


def test_an_export_inside_the_fit_folder_is_refused_before_the_work(tmp_path, monkeypatch,
                                                                   capsys):
    """It would be a file the folder's marker does not list: the next fit would refuse."""
    _forbid_run(monkeypatch, "fit")
    out = tmp_path / "res"
    assert main([*_argv("fit", out), "--export-compensation", str(out / "comp.mpf")]) == 2
    err = capsys.readouterr().err
    assert f"--export-compensation {out / 'comp.mpf'}: inside the output folder --out" in err
    assert list(tmp_path.iterdir()) == []
