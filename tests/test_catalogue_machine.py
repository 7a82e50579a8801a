"""A machine described as its builder knows it — table dimensions, rail and carriage positions,
a catalogue runner block and its preload class, in a machine file of at most 20 lines —
simulates, fits data simulated with it, and plans, from the command line."""

import csv
import json

import numpy as np
import pytest

from diffguide.cli import main

CONFIG = """\
[table]
length_mm = 1200.0
width_mm = 600.0
thickness_mm = 60.0
mesh_nx = 8
mesh_ny = 4

[guideway]
rail_y_mm = [-220.0, 220.0]
carriage_x_mm = [-250.0, 250.0]

[carriage]
block = "HIWIN-HG 35 C"
preload_class = "ZA"

[machine]
stroke_mm = 600.0
"""


@pytest.fixture(scope="module")
def machine_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("catalogue_machine")
    path = d / "machine.toml"
    path.write_text(CONFIG, encoding="utf-8")
    return path


def test_the_file_is_short_and_says_where_the_block_came_from(machine_file, capsys):
    assert len(CONFIG.splitlines()) <= 20
    assert main(["config", "--explain", str(machine_file)]) == 0
    text = capsys.readouterr().out
    assert "capacity_N = 49520.0  # catalogue, published" in text
    assert "carriage_footprint_mm = [80.0, 70.0]  # catalogue, published" in text


def test_simulate_fit_and_plan(machine_file, tmp_path):
    errors = tmp_path / "errors.csv"
    assert main(["simulate", "--config", str(machine_file), "--variant", "3", "--positions",
                 "-300:300:13", "--out", str(errors), "--quiet"]) == 0
    rows = list(csv.DictReader(errors.open(encoding="utf-8")))
    lines = ["position_mm,point,x_mm,y_mm,quantity,value,unit,sigma,run,direction"]
    for r in rows:  # levels at the corners, an interferometer at the centre; ±0.1 µm/m runs
        for q in (("EBX", "ECX") if r["point"] == "P5" else ("EBX", "EAX")):
            for run, d, dv in (("1", "+", 0.1), ("1", "-", -0.1)):
                lines.append(f"{r['position_mm']},{r['point']},{r['x_mm']},{r['y_mm']},{q},"
                             f"{float(r[q + '_urad']) + dv:.4f},urad,0.5,{run},{d}")
    meas = tmp_path / "meas.csv"
    meas.write_text("\n".join(lines) + "\n", encoding="utf-8")
    out = tmp_path / "fit"
    assert main(["fit", "--config", str(machine_file), "--measurements", str(meas), "--out",
                 str(out), "--structure", "fixed", "--no-rigid", "--no-plots", "--quiet"]) == 0
    report = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert report["config"] == str(machine_file)
    # the model explains data its own machine made (the runs' ±0.1 µm/m cancel in the merge)
    assert report["elastic"]["chi2_per_dof"] < 1.0, report["elastic"]
    plan = tmp_path / "plan"
    assert main(["plan", "--config", str(machine_file), "--start", str(out / "layout.csv"),
                 "--levels", "1", "--interferometers", "0", "--grid", "3x3", "--positions", "8",
                 "--structure", "fixed", "--draws", "1", "--no-plots", "--out", str(plan),
                 "--quiet"]) == 0
    rep = json.loads((plan / "report.json").read_text(encoding="utf-8"))
    assert len(rep["steps"]) == 1
    assert np.isfinite(rep["plan"]["worst_profile_sigma_um"])
