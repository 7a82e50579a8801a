"""``diffguide fit``'s report.json: the rigid-table blind wavelengths are in mm, and so are
their keys (``blind_wavelengths()`` itself stays in metres with ``_m`` keys)."""

import json
from pathlib import Path

import numpy as np
import pytest

from diffguide.cli import main
from diffguide.inverse import blind_wavelengths
from diffguide.io.config import default_config

DATA = Path(__file__).resolve().parents[1] / "data" / "majda2012_measurements.csv"


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("fit") / "o"
    # the cheapest fit that writes a report: no steps, structure fixed, no rigid fit, no plots
    rc = main(["fit", "--measurements", str(DATA), "--out", str(out), "--max-steps", "0",
               "--structure", "fixed", "--no-rigid", "--no-plots", "--quiet"])
    assert rc == 3  # not converged, but written
    return json.loads((out / "report.json").read_text())["identifiability"]


def test_report_blind_wavelengths_are_mm_under_mm_keys(report):
    from diffguide.machine.majda2012 import majda2012_machine

    got = report["rigid_table_blind_wavelengths_mm"]
    assert set(got) == {
        "carriage_averaging_mm", "carriage_spacing_mm", "pitch_yaw_mean_mm", "roll_difference_mm"
    }
    # the report's wavelength grid ends at twice the rail length, the blind list's cut-off
    two_l = max(t["wavelength_mm"] for c in report["wavelengths"] for t in c["transfer"]) * 1e-3
    ref = blind_wavelengths(majda2012_machine(), two_l)  # metres, '_m' keys
    assert set(ref) == {k.removesuffix("_mm") + "_m" for k in got}
    for key, value in ref.items():
        np.testing.assert_allclose(got[key.removesuffix("_m") + "_mm"], np.asarray(value) * 1e3,
                                   rtol=1e-12)


def test_report_blind_wavelengths_against_the_config_in_mm(report):
    """Closed forms from the machine file's own mm values (majda2012: 12 balls at 4 mm pitch
    per row, carriages at x = ±160 mm): n·p = 48 mm, l = 320 mm, l/k, 2l/(2k+1)."""
    g = default_config()["guideway"]
    l_mm = g["carriage_x_mm"][1] - g["carriage_x_mm"][0]
    got = report["rigid_table_blind_wavelengths_mm"]
    assert got["carriage_spacing_mm"] == pytest.approx(l_mm) == pytest.approx(320.0)
    assert got["carriage_averaging_mm"] == pytest.approx([48.0, 24.0, 16.0])
    assert got["pitch_yaw_mean_mm"][:3] == pytest.approx([l_mm, l_mm / 2, l_mm / 3])
    assert got["roll_difference_mm"][:2] == pytest.approx([2 * l_mm, 2 * l_mm / 3])
