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


# ---- positions written in inches (4 decimals) or with other decimals are the same positions ----

def _inch(mm: float) -> float:
    """A position as a file in inches to 4 decimals gives it back, in mm."""
    return round(mm / 25.4, 4) * 25.4


def test_positions_from_an_inch_file_are_the_mm_files_positions(tmp_path):
    """P1's level in mm and P5's interferometer converted from 4-decimal inches (up to 1.27 µm
    off): one grid of positions, the mm file's, and a note saying so (was twice as many)."""
    rows = _rows()
    a = _write(tmp_path / "a.csv", [r for r in rows if r["point"] == "P1"])
    b_rows = [{**r, "position_mm": f"{_inch(float(r['position_mm'])):.6f}"}
              for r in rows if r["point"] == "P5"]
    assert any(float(r["position_mm"]) != float(s["position_mm"])
               for r, s in zip(b_rows, (r for r in rows if r["point"] == "P5")))
    b = _write(tmp_path / "b.csv", b_rows)
    notes: list = []
    meas = read_any([a, b], notes=notes)
    want = np.unique([float(r["position_mm"]) * 1e-3 for r in rows if r["point"] == "P1"])
    np.testing.assert_array_equal(np.unique(meas.position), want)
    assert any("taken as that one" in n and "µm" in n for n in notes), notes


def test_the_stroke_end_takes_a_position_a_micrometre_beyond_and_names_one_further(tmp_path):
    """A position 0.8 µm past the stroke's end (an inch file's rounding) is the end; 10 µm past
    it is refused, the position written to 0.1 µm (was '-350 mm is outside ±350 mm')."""
    from diffguide.cli import build_parser
    from diffguide.jobs.fit import check_inputs as _check_inputs
    from diffguide.io.config import default_config

    cfg = default_config()
    rows = _rows()
    args = build_parser().parse_args(["fit", "--preset", "majda2012", "--measurements",
                                      str(DATA), "--out", str(tmp_path / "out")])
    args.nx = args.ny = None  # the mesh as the command sets it from --mesh (the preset's)
    for end, ok in ((350.0008, True), (350.01, False)):
        path = _write(tmp_path / f"{end}.csv", [
            {**r, "position_mm": str(end if float(r["position_mm"]) == 350 else
                                     r["position_mm"])} for r in rows])
        meas = read_any(path)
        if ok:
            _check_inputs(meas, args, cfg)
        else:
            with pytest.raises(ValueError, match=r"position 350\.0100 mm is outside"):
                _check_inputs(meas, args, cfg)


# ---- one channel read by two files with opposite signs (a reversed sensor) ----

def _split_runs(tmp_path, flip: bool):
    """P1's level, runs 1-3 in one file and 4-5 in another (the second negated if ``flip``)."""
    rows = [r for r in _rows() if r["point"] == "P1"]
    a = _write(tmp_path / "runs123.csv", [r for r in rows if r["run"] in "123"])
    b_rows = [{**r, "value": f"{-float(r['value']) if flip else float(r['value']):.3f}"}
              for r in rows if r["run"] in "45"]
    return a, _write(tmp_path / "runs45.csv", b_rows)


def test_a_reversed_file_is_refused_naming_both(tmp_path):
    """The same runs' data, one file negated: averaged, they cancel (the fit saw near-zero
    pitch and roll at P1, χ²/dof still below 1). Refused, naming both files and the channel;
    the unflipped split merges as the whole file does; accepted on request with a note."""
    a, b = _split_runs(tmp_path, flip=True)
    with pytest.raises(ValueError, match=r"EBX at P1 \(level\) has opposite signs in .*"
                                         r"runs123\.csv and .*runs45\.csv.*"
                                         r"--accept-file-conflicts"):
        read_any([a, b])
    notes: list = []
    read_any([a, b], notes=notes, allow_conflicts=True)
    assert any("opposite signs" in n and "merged anyway" in n for n in notes), notes
    a, b = _split_runs(tmp_path, flip=False)
    notes = []
    read_any([a, b], notes=notes)
    assert not any("opposite signs" in n for n in notes)


def test_a_reversed_file_is_refused_by_fit_before_the_work(tmp_path, capsys):
    a, b = _split_runs(tmp_path, flip=True)
    out = tmp_path / "out"
    rc = main(["fit", "--preset", "majda2012", "--measurements", str(a), "--measurements",
               str(b), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2 and "opposite signs" in err and "runs45.csv" in err and not out.exists()


def test_files_of_pure_noise_are_not_called_reversed():
    """Two files of independent noise on one channel (36 common positions): over 400 pairs
    the conflict test fires at most at its stated rate (t > 4 on the regression slope: one-
    sided p ≈ 0.0001 at 34 degrees of freedom; allowed here: 2 of 400)."""
    from diffguide.inverse.data import Reading
    from diffguide.inverse.merge import file_conflicts

    rng = np.random.default_rng(7)
    x = np.linspace(-0.35, 0.35, 36)
    fired = 0
    for _ in range(400):
        rows = [Reading(line=i, position=float(p), point="P1", xy=(0.45, 0.2), quantity="EBX",
                        value=float(rng.normal(0, 4e-6)), unit="rad", sigma=None, run="1",
                        direction="forward", instrument="level", source=src)
                for src in ("a.csv", "b.csv") for i, p in enumerate(x)]
        fired += bool(file_conflicts(rows))
    assert fired <= 2


def test_each_files_chi2_against_the_fit_of_all(tmp_path):
    """Two files of one level channel, one run each way, stated σ s: file A reads v + δ, file
    B v − δ. Against the merged value v (the fit of both, here exact), file A's own value is
    off by δ with σ² = ¼(s² + s²) (the mean of one forward and one backward reading), so
    χ²_A = χ²_B = N · 2δ²/s² over its N rows; with the fit's ν its share N · ν / N_used."""
    import dataclasses

    from diffguide.inverse.file_chi2 import file_chi2
    from diffguide.io.measurements import merge_readings, parse_readings

    s, delta, n = 2.0, 0.7, 12
    head = "position_mm,point,x_mm,y_mm,quantity,value,unit,run,direction,sigma\n"
    readings = []
    for name, d in (("a.csv", delta), ("b.csv", -delta)):
        text = head + "".join(f"{20 * i},P1,0,0,EBX,{np.sin(i) + d:.3f},um/m,1,{w},{s}\n"
                              for i in range(n) for w in ("forward", "backward"))
        readings += [dataclasses.replace(r, source=name, run=name)
                     for r in parse_readings(text, name)]
    m = merge_readings(readings)
    rows = file_chi2(m, m.value, dof=10.0)
    assert [r["file"] for r in rows] == ["a.csv", "b.csv"]
    for r in rows:
        assert r["rows"] == n and r["readings"] == 2 * n
        assert r["chi2"] == pytest.approx(n * 2 * delta**2 / s**2, rel=1e-9)
        assert r["dof"] == pytest.approx(10.0)
    # a row left out as an outlier is not counted; one file: no rows
    assert file_chi2(m, m.value, outliers=[0])[0]["rows"] == n - 1
    assert file_chi2(merge_readings(readings[: 2 * n]), m.value[:n]) == []


@pytest.mark.slow  # a whole fit: 67 s of CPU on two busy cores (file_chi2's closed form above)
def test_fit_accepting_a_reversed_file_reports_each_files_chi2(tmp_path):
    """The bundled data with P1's runs 4-5 in a second file, negated, merged on request
    (--accept-file-conflicts): report.json gives each file's χ² against the fit of both, and
    the reversed file is the one the model explains worse per degree of freedom."""
    rows = _rows()
    moved = [r for r in rows if r["point"] == "P1" and r["run"] in "45"]
    a = _write(tmp_path / "main.csv", [r for r in rows if r not in moved])
    b = _write(tmp_path / "reversed.csv",
               [{**r, "value": f"{-float(r['value']):.3f}"} for r in moved])
    out = tmp_path / "out"
    assert main(["fit", "--preset", "majda2012", "--measurements", str(a), "--measurements",
                 str(b), "--accept-file-conflicts", "--mesh", "6x3", "--max-steps", "3",
                 "--no-plots", "--out", str(out), "--quiet"]) == 0
    files = {Path(f["file"]).name: f for f in
             json.loads((out / "report.json").read_text())["elastic"]["files"]}
    assert set(files) == {"main.csv", "reversed.csv"}
    assert files["reversed.csv"]["readings"] == len(moved)
    assert sum(f["rows"] for f in files.values()) > files["main.csv"]["rows"]
    assert files["reversed.csv"]["chi2_per_dof"] > 3 * files["main.csv"]["chi2_per_dof"]
