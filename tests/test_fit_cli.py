"""``diffguide fit`` end to end on the bundled data, scored against the bundled truth; atomic
output."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from diffguide.cli import main

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"
TRUTH = ROOT / "data" / "majda2012_truth.csv"


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("fit") / "result"
    rc = main(["fit", "--preset", "majda2012", "--measurements", str(DATA), "--out", str(out),
               "--truth", str(TRUTH), "--export-compensation", str(out.parent / "comp.txt"),
               "--at", "P1", "--rigid", "--quiet"])
    assert rc == 0
    return out


def test_compensation_table_from_the_fit(out_dir):
    # the fitted model's errors at P1 over the 700 mm stroke, one row per position, with σ
    rows = list(csv.DictReader(ln for ln in (out_dir.parent / "comp.txt").open()
                               if not ln.startswith("#")))
    assert list(rows[0])[:4] == ["X_machine_mm", "x_mm", "EXX_um", "EXX_sigma_um"]
    assert len(rows) == 71
    x = np.array([float(r["x_mm"]) for r in rows])
    assert x[0] == pytest.approx(-350.0) and x[-1] == pytest.approx(350.0)
    ref = int(np.argmin(np.abs(x)))
    for q in ("EYX_um", "EZX_um", "EAX_urad", "EBX_urad", "ECX_urad"):
        assert abs(float(rows[ref][q])) < 1e-9  # errors are relative to x = 0
    # the bundled data hold no EXX: the lead error is unknown, so EXX is left out
    assert all(r["EXX_um"] == "" for r in rows)
    sig = np.array([float(r["EBX_sigma_urad"]) for r in rows])
    assert np.all(sig[np.abs(x) > 100] > 0) and sig[ref] < 1e-6  # zero σ at the reference


def test_bundled_data_is_small_and_documented():
    assert DATA.stat().st_size < 1_000_000 and TRUTH.stat().st_size < 1_000_000
    assert DATA.read_text().startswith("# diffguide synthetic measurement")


def test_outputs_and_columns(out_dir):
    names = {p.name for p in out_dir.iterdir()}
    assert {"rails.csv", "rails_rigid.csv", "fit.csv", "report.json", "profiles.png",
            "curves.png"} <= names
    assert not [p for p in out_dir.parent.iterdir() if p.name.startswith(".")]  # no temp left
    rails = list(csv.DictReader((out_dir / "rails.csv").open()))
    assert list(rails[0]) == ["rail", "s_mm", "vertical_um", "vertical_sigma_um",
                              "horizontal_um", "horizontal_sigma_um"]
    assert {r["rail"] for r in rails} == {"1", "2"}
    assert all(float(r["vertical_sigma_um"]) > 0 for r in rails)
    fit = list(csv.DictReader((out_dir / "fit.csv").open()))
    n_readings = sum(1 for ln in DATA.read_text().splitlines()[1:]
                     if ln.strip() and not ln.startswith(("#", "position_mm")))
    assert len(fit) == n_readings
    for r in fit[:50]:
        assert float(r["value"]) - float(r["fitted"]) == pytest.approx(float(r["residual"]),
                                                                       abs=1e-6)
    assert (out_dir / "profiles.png").read_bytes()[:4] == b"\x89PNG"


def test_report_against_truth(out_dir):
    rep = json.loads((out_dir / "report.json").read_text())
    el, rg = rep["elastic"], rep["rigid_table"]
    assert el["converged"] and 0.7 < el["chi2_per_dof"] < 1.3
    assert rg["chi2_per_dof"] > 2 * el["chi2_per_dof"]
    truth = rep["truth"]
    # independent check of the report's own numbers: rails.csv against the truth file
    t = {(int(r["rail"]), round(float(r["s_mm"]), 3)): r
         for r in csv.DictReader(ln for ln in TRUTH.open() if not ln.startswith("#"))}
    rails = list(csv.DictReader((out_dir / "rails.csv").open()))
    s = np.array([float(r["s_mm"]) for r in rails if r["rail"] == "1"])
    fitted = np.array([[float(r["vertical_um"]) for r in rails if r["rail"] == str(k)]
                       for k in (1, 2)])
    true_v = np.array([[np.interp(x, *zip(*sorted((kk[1], float(v["vertical_um"]))
                                                 for kk, v in t.items() if kk[0] == k)))
                        for x in s] for k in (1, 2)])
    true_v -= true_v.mean(axis=1, keepdims=True)
    sc = s - s.mean()
    true_v -= np.mean([sc @ tv / (sc @ sc) for tv in true_v]) * sc  # common slope
    err = np.sqrt(np.mean((fitted - true_v) ** 2))
    assert err == pytest.approx(np.sqrt(np.mean([truth["rms_error_um"]["elastic"][k] ** 2
                                                 for k in ("rail 1 vertical",
                                                           "rail 2 vertical")])), rel=0.02)
    assert err < 0.15 * np.sqrt(np.mean(true_v**2))
    # the elastic fit beats the rigid-table inversion on the same data, with the structure
    # estimated (by 4x with the structure known: test_inverse.py)
    rms = truth["rms_error_um"]
    assert rms["elastic"]["all"] < 0.8 * rms["rigid_table"]["all"]
    assert truth["coverage_2sigma"]["elastic"] >= 0.9
    th = el["structure"]["thickness"]  # the data were simulated at 50 mm (a finer mesh)
    assert abs(th["value"] - 50.0) <= 2 * th["sigma"] and th["determined_by_data"]
    ident = rep["identifiability"]
    assert {"gauge", "singular_values", "wavelengths", "regularisation"} <= set(ident)
    res = el["resolution"]  # no waviness stated: the report says what the bands leave out
    assert res["rail_waviness_um"] == 0.0 and "not include it" in res["note"]


def test_failed_fit_leaves_no_output(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("position_mm,point,x_mm,y_mm,quantity,value,unit\n0,P1,0,0,EBX,x,um/m\n")
    out = tmp_path / "never"
    assert main(["fit", "--measurements", str(bad), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:2: field 'value'" in err
    assert not out.exists() and list(tmp_path.iterdir()) == [bad]


def test_bad_waviness_is_refused_before_any_work(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["fit", "--measurements", str(DATA), "--out", str(out),
                 "--rail-waviness-um", "-0.1", "--quiet"]) == 2
    assert "--rail-waviness-um must be an RMS in [0, 100]" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("args, message", [
    (["--at", "P9"], "--at must be one of the points P1, P2, P3, P4, P5, got 'P9'"),
    (["--comp-points", "1"], "--comp-points must be in [2, 10000]"),
    (["--tol-um", "-1"], "--tol-um must be a finite number > 0"),
    (["--at-z-mm", "3000"], "--at-z-mm must be in [-500, 2000] mm"),
])
def test_bad_export_options_are_refused_before_any_work(tmp_path, capsys, args, message):
    """Exit 2 means nothing written: the export's options are checked before the fit."""
    out = tmp_path / "o"
    assert main(["fit", "--measurements", str(DATA), "--out", str(out), "--quiet",
                 "--export-compensation", str(tmp_path / "c.txt"), *args]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists() and not (tmp_path / "c.txt").exists()


def test_off_table_point_and_foreign_out_dir(tmp_path, capsys):
    far = tmp_path / "far.csv"
    far.write_text("position_mm,point,x_mm,y_mm,quantity,value,unit\n0,P9,900,0,EBX,1,um/m\n")
    assert main(["fit", "--measurements", str(far), "--out", str(tmp_path / "o")]) == 2
    assert "off the majda2012 table" in capsys.readouterr().err
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("precious")
    assert main(["fit", "--measurements", str(DATA), "--out", str(foreign), "--quiet"]) == 2
    assert "refusing to replace" in capsys.readouterr().err
    assert (foreign / "thesis.tex").read_text() == "precious"


def _subset(tmp_path, keep) -> Path:
    """The bundled readings restricted to rows whose point is in ``keep``."""
    lines = DATA.read_text().splitlines()
    head = [ln for ln in lines if ln.startswith(("#", "position_mm"))]
    rows = [ln for ln in lines if not ln.startswith(("#", "position_mm")) and ln.strip()
            and ln.split(",")[1] in keep]
    path = tmp_path / "subset.csv"
    path.write_text("\n".join(head + rows) + "\n")
    return path


def test_interferometer_only_writes_an_honest_report(tmp_path, capsys):
    """One interferometer at the centre, pitch and yaw only (the commonest real data set) with a
    given λ: a report is written, λ is the given one, no NaN (the JSON has none by
    construction: allow_nan=False), the rails' mean is determined and their difference is not,
    and the console says which wavelengths of which combination the data leave to the prior.
    No rigid-table inversion unless asked for (--rigid / [fit] rigid)."""
    data = _subset(tmp_path, {"P5"})
    out = tmp_path / "o"
    rc = main(["fit", "--measurements", str(data), "--out", str(out), "--lambda", "0.01",
               "--structure", "fixed", "--no-plots"])
    assert rc in (0, 3)
    assert not (out / "rails_rigid.csv").exists()
    rep = json.loads((out / "report.json").read_text())
    assert "rigid_table" not in rep
    assert "fitted_rigid" not in (out / "fit.csv").read_text()
    assert rep["elastic"]["lambda"] == 0.01
    assert rep["elastic"]["chi2_per_dof"] is not None and rep["elastic"]["chi2_per_dof"] > 0
    combos = {c["combination"].split(" (")[0]: c for c in rep["identifiability"]["wavelengths"]}
    assert not combos["vertical difference"]["determined"]
    assert not combos["horizontal difference"]["determined"]
    assert len(list(csv.DictReader((out / "rails.csv").open()))) > 0
    said = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("not determined")]
    assert len(said) == 1
    for name, c in combos.items():
        for lo, hi in c["undetermined_wavelengths_mm"]:
            assert f"{name} " in said[0] and f"{lo:.0f}–{hi:.0f}" in said[0]


def test_undetermined_lines():
    """The console's summary of the identifiability report: the bands per combination, and the
    short-wave note only when no waviness is stated."""
    from diffguide.io.report_text import undetermined_lines

    ident = {"wavelengths": [
        {"combination": "vertical mean ((rail 1 + rail 2)/2)",
         "transfer": [{"wavelength_mm": 92.5, "transfer": 0.1}],
         "undetermined_wavelengths_mm": [[92.5, 190.8], [285.1, 362.9]]},
        {"combination": "horizontal difference (rail 2 − rail 1)",
         "transfer": [{"wavelength_mm": 92.5, "transfer": 0.9}],
         "undetermined_wavelengths_mm": []},
    ]}
    lines = undetermined_lines(ident, 0.0)
    assert lines[0].endswith("wavelengths in mm: vertical mean 92–191, 285–363")
    assert "shorter than 92 mm" in lines[1] and "--rail-waviness-um" in lines[1]
    assert undetermined_lines(ident, 0.2e-6) == lines[:1]
    ident["wavelengths"].pop(0)
    assert undetermined_lines(ident, 0.2e-6) == []


def test_not_converged_is_written_and_flagged(tmp_path, capsys):
    out = tmp_path / "o"
    rc = main(["fit", "--measurements", str(DATA), "--out", str(out), "--max-steps", "0",
               "--structure", "fixed", "--no-rigid", "--no-plots", "--quiet"])
    assert rc == 3
    rep = json.loads((out / "report.json").read_text())
    assert rep["status"]["converged"] is False and rep["status"]["exit_code"] == 3
    assert "stopped after 0 steps" in rep["status"]["message"]
    assert "identifiability" in rep and (out / "rails.csv").exists()
    assert "did not converge" in capsys.readouterr().err


def test_help_mentions_units(capsys):
    with pytest.raises(SystemExit):
        main(["fit", "--help"])
    text = capsys.readouterr().out
    assert "--knot-spacing-mm" in text and "µm/m" in text and "--quiet" in text


def test_output_folder_has_the_usual_permissions(tmp_path):
    """The staged folder (made 0700 by mkdtemp) ends with the permissions the umask gives a
    new folder, like one made by ``mkdir``."""
    import os
    from types import SimpleNamespace

    from diffguide.cli._outputs import write_dir

    (tmp_path / "ref").mkdir()
    write_dir(SimpleNamespace(out=tmp_path / "out"), "fit", {"a.txt": "x\n"})
    mode = (tmp_path / "out").stat().st_mode & 0o777
    assert mode == (tmp_path / "ref").stat().st_mode & 0o777, oct(mode)
    assert (tmp_path / "out" / "a.txt").read_text() == "x\n"
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]


def test_layout_csv_is_the_measured_layout_and_plan_takes_it_as_start(out_dir, tmp_path, capsys):
    """layout.csv lists every point and instrument kind of the measurement file (read here
    independently of the fit) in ``diffguide plan``'s plan format, and ``plan --start`` keeps
    it: the plan begins with those placements and adds the budget on top."""
    rows = list(csv.DictReader((out_dir / "layout.csv").open()))
    seen = {}
    for r in csv.DictReader(ln for ln in DATA.open() if not ln.startswith("#")):
        kind = "level" if r["instrument"] == "level" else "interferometer"
        seen.setdefault((kind, r["point"], float(r["x_mm"]), float(r["y_mm"])),
                        set()).add(r["quantity"])
    assert {(r["instrument"], r["point"], float(r["x_mm"]), float(r["y_mm"])): set(
        r["reads"].split("+")) for r in rows} == seen
    plan_out = tmp_path / "plan"
    rc = main(["plan", "--start", str(out_dir / "layout.csv"), "--levels", "1",
               "--interferometers", "0", "--grid", "3x3", "--positions", "8", "--structure",
               "fixed", "--draws", "1", "--mesh", "8x4", "--no-plots", "--out", str(plan_out),
               "--quiet"])
    assert rc == 0, capsys.readouterr().err
    rep = json.loads((plan_out / "report.json").read_text())
    assert [(p["instrument"], p["x_mm"], p["y_mm"]) for p in rep["start"]] == [
        (k, x, y) for (k, _, x, y) in sorted(seen, key=lambda t: t[1])]
    assert len(rep["steps"]) == 1 and rep["steps"][0]["instrument"] == "level"
    # the comparison defaults to the start plan: what the one added level buys
    assert rep["compare"]["placements"] == rep["start"]
    assert rep["plan"]["worst_profile_sigma_um"] <= rep["compare"]["worst_profile_sigma_um"]
    assert rep["steps"][0]["before"] == pytest.approx(rep["compare"]["worst_profile_sigma_um"],
                                                      rel=1e-9)
    bad = tmp_path / "bad.csv"
    bad.write_text("instrument,point,x_mm,y_mm\nlaser,P1,0,0\n")
    assert main(["plan", "--start", str(bad), "--out", str(tmp_path / "no"), "--quiet"]) == 2
    assert "bad.csv:2: field 'instrument'" in capsys.readouterr().err


def test_bundled_job_raises_no_validity_warning(out_dir):
    # no false alarm: the bundled data sit well inside the model's validity
    assert json.loads((out_dir / "report.json").read_text())["validity"] == []


def test_fanuc_without_exx_readings_is_refused_before_the_fit(tmp_path, capsys):
    """The bundled data hold no EXX: the fit would have no lead error, and a FANUC pitch
    table needs it. Refused before the fit (it was after it, the output folder written)."""
    out, comp = tmp_path / "out", tmp_path / "comp.txt"
    rc = main(["fit", "--preset", "majda2012", "--measurements", str(DATA), "--out", str(out),
               "--export-compensation", str(comp), "--format", "fanuc", "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2 and "--format fanuc" in err and "no EXX" in err
    assert not out.exists() and not comp.exists()


def test_the_straightness_table_states_the_slope_the_fit_leaves_undetermined(out_dir):
    """Issue 39: EYX/EZX carry the common slope of both rails in their plane, which no
    reading determines and the fit fixes at zero; the table's header says so, outside σ, with
    its size per µm/m and what to do (the alignment slopes it quotes where the data have
    straightness channels: tests/test_export_settings.py)."""
    text = (out_dir.parent / "comp.txt").read_text()
    head = " ".join(ln for ln in text.splitlines() if ln.startswith("#"))
    assert "STRAIGHTNESS SLOPE NOT DETERMINED" in head and "NOT in the sigma" in head
    assert "measure the slope of the X motion against a straightness reference" in head
    report = json.loads((out_dir / "report.json").read_text())
    assert any("common" in m and "slope" in m for m in report["elastic"]["gauge"])
    # the bundled data hold angles only: no straightness channel, no alignment slope to quote
    assert report["elastic"]["alignment_slopes_um_per_m"] == {}
    assert "alignment slopes" not in head
    # 1 µm/m over the ±350 mm stroke: 0.35 µm at the ends
    assert "1 um/m of it is 0.35 um at the table's ends" in head
