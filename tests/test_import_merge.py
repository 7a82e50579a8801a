"""Several measurement files are one data set: merged as their concatenation would be, each
reading keeping its file, conflicts refused naming both files; the input x0 and the export's
machine x0 apart (``fit --x0-mm`` / ``--machine-x0-mm``), both stated in report.json."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from diffguide.cli import main
from diffguide.io.importers import merged_table, read_any

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"


def _rows():
    with open(DATA, encoding="utf-8") as fh:
        return list(csv.DictReader(line for line in fh if not line.startswith("#")))


def _write(path, rows, **change):
    cols = list(rows[0])
    with open(path, "w", encoding="utf-8", newline="") as fh:
        w = csv.DictWriter(fh, cols, lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({**r, **change})
    return path


def _same(a, b):
    assert a.shape == b.shape
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)


@pytest.fixture(scope="module")
def canonical():
    return merged_table(read_any(DATA))


def test_files_split_by_channel_or_by_run_merge_as_their_concatenation(tmp_path, canonical):
    rows = _rows()
    a = _write(tmp_path / "a.csv", [r for r in rows if r["point"] in ("P1", "P2", "P3")])
    b = _write(tmp_path / "b.csv", [r for r in rows if r["point"] not in ("P1", "P2", "P3")])
    got = read_any([a, b])
    _same(merged_table(got), canonical)
    assert {r.source for r in got.readings} == {str(a), str(b)}
    assert all(r.source == str(a) for r in got.readings if r.point == "P1")
    c = _write(tmp_path / "c.csv", [r for r in rows if r["run"] in ("1", "2")])
    d = _write(tmp_path / "d.csv", [r for r in rows if r["run"] not in ("1", "2")])
    _same(merged_table(read_any([d, c])), canonical)


def test_a_run_label_two_files_share_is_two_runs(tmp_path):
    """Files A (runs 1, 2) and B (runs 3, 4 labelled 1, 2 again) merge as runs 1-4 of one file:
    B's runs are relabelled, said in a note — not pooled with A's as repeats of the same run."""
    rows = [r for r in _rows() if r["point"] == "P5"]
    a = _write(tmp_path / "a.csv", [r for r in rows if r["run"] in ("1", "2")])
    b_rows = [{**r, "run": str(int(r["run"]) - 2)} for r in rows if r["run"] in ("3", "4")]
    b = _write(tmp_path / "b.csv", b_rows)
    both = _write(tmp_path / "both.csv", [r for r in rows if r["run"] in ("1", "2", "3", "4")])
    notes = []
    got = read_any([a, b], notes=notes)
    _same(merged_table(got), merged_table(read_any(both)))
    assert any("b.csv: run(s) 1, 2" in n and "relabelled" in n for n in notes)
    assert {r.run for r in got.readings} == {"1", "2", "1@b.csv", "2@b.csv"}


def test_conflicting_files_are_refused_naming_both(tmp_path):
    rows = [r for r in _rows() if r["point"] in ("P1", "P5")]
    a = _write(tmp_path / "a.csv", [r for r in rows if r["quantity"] == "EBX"])
    moved = _write(tmp_path / "moved.csv", [r for r in rows if r["quantity"] != "EBX"],
                   x_mm="455.0")
    with pytest.raises(ValueError, match=r"moved.csv:\d+: point 'P1' is at \(455, 200\) mm "
                                         r"here but at \(450, 200\) mm in .*a.csv:\d+"):
        read_any([a, moved])
    high = [dict(r, z_mm="50") for r in rows if r["quantity"] == "EBX"]
    h = _write(tmp_path / "high.csv", high)
    with pytest.raises(ValueError, match=r"high.csv:\d+: EBX at P1 \(level\) is read at z = 50 "
                                         r"mm here but at z = 0 mm in .*a.csv:\d+"):
        read_any([a, h])
    with pytest.raises(ValueError, match="the same file, given twice as measurement files"):
        read_any([a, a])


def test_middle_x0_is_the_middle_of_all_files(tmp_path):
    rows = [r for r in _rows() if r["point"] == "P5"]
    a = _write(tmp_path / "a.csv", [dict(r, position_mm=float(r["position_mm"]) + 1000)
                                    for r in rows if r["quantity"] == "EBX"])
    b = _write(tmp_path / "b.csv", [dict(r, position_mm=float(r["position_mm"]) + 1000)
                                    for r in rows if r["quantity"] == "ECX"])
    info = {}
    got = read_any([a, b], x0_mm="middle", info=info)
    assert [f["x0_mm"] for f in info["files"]] == [1000.0, 1000.0]
    np.testing.assert_allclose(sorted(set(np.round(got.position * 1e3, 6))),
                               sorted({float(r["position_mm"]) for r in rows}))


def test_fit_of_two_files_equals_the_fit_of_their_concatenation(tmp_path, capsys):
    """One interferometer's pitch and yaw in two files, and in one: the same profiles; the
    report states each file, x0 and the export's machine x0 (here 1000 mm)."""
    rows = [r for r in _rows() if r["point"] == "P5"]
    a = _write(tmp_path / "pitch.csv", [r for r in rows if r["quantity"] == "EBX"])
    b = _write(tmp_path / "yaw.csv", [r for r in rows if r["quantity"] == "ECX"])
    one = _write(tmp_path / "one.csv", rows)
    common = ["--lambda", "0.01", "--structure", "fixed", "--no-plots", "--quiet"]
    assert main(["fit", "--measurements", str(a), "--measurements", str(b), "--out",
                 str(tmp_path / "two"), "--export-compensation", str(tmp_path / "comp.csv"),
                 "--at", "P5", "--machine-x0-mm", "1000", *common]) in (0, 3)
    assert main(["fit", "--measurements", str(one), "--out", str(tmp_path / "one"),
                 *common]) in (0, 3)
    two = np.loadtxt(tmp_path / "two" / "rails.csv", delimiter=",", skiprows=1,
                     comments="#")
    ref = np.loadtxt(tmp_path / "one" / "rails.csv", delimiter=",", skiprows=1, comments="#")
    np.testing.assert_allclose(two, ref, rtol=1e-9, atol=1e-9)
    rep = json.loads((tmp_path / "two" / "report.json").read_text())["measurements"]
    assert [f["file"] for f in rep["files"]] == [str(a), str(b)]
    assert rep["x0_mm"] == 0.0 and rep["machine_x0_mm"] == 1000.0
    comp = [r for r in csv.DictReader(ln for ln in open(tmp_path / "comp.csv")
                                      if not ln.startswith("#"))]
    assert all(abs(float(r["X_machine_mm"]) - float(r["x_mm"]) - 1000.0) < 1e-3 for r in comp)
    fitcsv = (tmp_path / "two" / "fit.csv").read_text()
    assert fitcsv.count("\n") == (tmp_path / "one" / "fit.csv").read_text().count("\n")


def test_fit_refuses_a_conflicting_pair_before_any_work(tmp_path, capsys):
    rows = [r for r in _rows() if r["point"] == "P5"]
    a = _write(tmp_path / "a.csv", [r for r in rows if r["quantity"] == "EBX"])
    b = _write(tmp_path / "b.csv", [r for r in rows if r["quantity"] == "ECX"], y_mm="10")
    assert main(["fit", "--measurements", str(a), "--measurements", str(b), "--out",
                 str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "b.csv" in err and "a.csv" in err and "point 'P5'" in err
    assert not (tmp_path / "o").exists()


def test_the_same_file_twice_is_refused_however_it_is_named(tmp_path, monkeypatch, capsys):
    # merged as new data, a file given twice would count every reading twice and narrow the
    # fit's σ by √2: refused by resolved path and by content, naming both
    rows = [r for r in _rows() if r["point"] == "P5"]
    a = _write(tmp_path / "a.csv", rows)
    copy = tmp_path / "copy.csv"
    copy.write_bytes(a.read_bytes())
    link = tmp_path / "link.csv"
    link.symlink_to(a)
    monkeypatch.chdir(tmp_path)
    for other, why in (("./a.csv", "the same file"), (str(tmp_path / "sub" / ".." / "a.csv"),
                                                     "the same file"),
                       (str(link), "the same file"), (str(copy), "the same content")):
        (tmp_path / "sub").mkdir(exist_ok=True)
        with pytest.raises(ValueError) as exc:
            read_any(["a.csv", other])
        msg = str(exc.value)
        assert msg.startswith(f"a.csv and {other}: ") and why in msg, msg
    # the command line: exit 2 before any work, both files named
    assert main(["fit", "--measurements", "a.csv", "--measurements", str(copy), "--out",
                 str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"a.csv and {copy}: the same content" in err
    assert not (tmp_path / "o").exists()
