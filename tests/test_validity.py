"""Plausibility at the model's edges: the audit's reproducers each end in a warning (stderr and
report.json's ``validity``) or a correct result; the bundled job raises none."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from diffguide.cli import main
from diffguide.inverse.validity import chi2_bounds, chi2_check
from diffguide.inverse.weight import _Spectrum, choose_weight, detectable_weight

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"
FAST = ["--mesh", "6x3", "--structure", "fixed", "--no-plots", "--quiet"]


def _rows():
    lines = [ln for ln in DATA.read_text().splitlines() if not ln.startswith("#")]
    return lines[0], list(csv.reader(lines[1:]))


def _write_measurements(path, value_of):
    header, rows = _rows()
    h = header.split(",")
    iv = h.index("value")
    with open(path, "w") as f:
        f.write(header + "\n")
        for k, r in enumerate(rows):
            r[iv] = f"{value_of(k, dict(zip(h, r))):.4f}"
            f.write(",".join(r) + "\n")


def _write_rails(path, s_mm, vertical_um):
    with open(path, "w") as f:
        f.write("rail,s_mm,vertical_um,horizontal_um\n")
        for rail in (1, 2):
            for s, v in zip(s_mm, vertical_um):
                f.write(f"{rail},{s:g},{v if rail == 1 else 0.0:.4f},0\n")


def _codes(err: str) -> str:
    return "\n".join(ln for ln in err.splitlines() if "warning:" in ln)


# ---- the weight: σ never narrowed by data that carry no information ----

def _toy(seed=0, n=60, m=12):
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(n, m))
    D = np.diff(np.eye(m), 2, axis=0)
    Omega = D.T @ D + 1e-3 * np.eye(m)
    return J, Omega, rng


def _posterior_sd(J, Omega, lam):
    return np.sqrt(np.diag(np.linalg.inv(J.T @ J + lam * Omega)))


def test_null_data_give_the_sigma_of_pure_noise_not_a_collapsed_prior():
    # null data (y = 0) against an independent reference: the same layout on pure noise at the
    # stated σ (whitened: N(0, 1)); both carry no signal, so their σ must agree
    J, Omega, rng = _toy()
    null = choose_weight(J, np.zeros(len(J)), Omega, len(J))
    noise = [choose_weight(J, rng.normal(size=len(J)), Omega, len(J)) for _ in range(20)]
    sd_null = _posterior_sd(J, Omega, null.lam)
    sd_noise = np.median([_posterior_sd(J, Omega, c.lam) for c in noise], axis=0)
    assert np.all(sd_null > 0.3 * sd_noise)
    # the prior's rails at that λ still show in the data at the stated σ (E‖Jθ‖² ≥ 1)
    assert np.trace(J @ np.linalg.solve(null.lam * Omega, J.T)) >= 1 - 1e-9


def test_data_with_signal_are_not_capped():
    J, Omega, rng = _toy(1)
    theta = np.linalg.solve(np.linalg.cholesky(Omega).T, rng.normal(size=J.shape[1])) * 30
    c = choose_weight(J, J @ theta + rng.normal(size=len(J)), Omega, len(J))
    assert c.lam < 1e-2 * detectable_weight(_Spectrum(J, J @ theta, Omega))


# ---- χ²/dof against its distribution ----

@pytest.mark.parametrize("dof", [20.0, 318.5, 5000.0])
def test_chi2_bounds_match_the_chi2_distribution(dof):
    lo, hi = chi2_bounds(dof)
    ref = stats.chi2.ppf([0.0005, 0.9995], dof) / dof
    assert lo == pytest.approx(ref[0], rel=0.02) and hi == pytest.approx(ref[1], rel=0.02)
    assert not chi2_check(0.969, 318.5)  # the bundled fit
    assert chi2_check(20.9, dof)[0].code == "chi2_high"
    assert chi2_check(0.0, dof)[0].code == "chi2_low"


# ---- the audit's fit reproducers ----

@pytest.fixture(scope="module")
def null_fit(tmp_path_factory):
    d = tmp_path_factory.mktemp("null")
    _write_measurements(d / "null.csv", lambda k, r: 9999.0)
    return d


def test_null_data_warn_and_keep_their_sigma(null_fit, capsys):
    # a stuck instrument (every reading 9999) with a tight tolerance: the straightness'
    # interval is the prior's, a few nm wide; the verdict is "not decidable", never "pass"
    out = null_fit / "out"
    assert main(["fit", "--measurements", str(null_fit / "null.csv"), "--out", str(out),
                 "--tolerance-um", "0.2", *FAST]) == 0
    err = _codes(capsys.readouterr().err)
    assert "carry no information" in err and "χ²/dof" in err
    rep = json.loads((out / "report.json").read_text())
    assert {"null_data", "chi2_low"} <= {w["code"] for w in rep["validity"]}
    for r in rep["straightness"]["rails"]:
        assert r["interval_95_um"][1] < 0.2
        assert r["verdict"] == "not decidable" and not r["informative"]
        assert "no information" in r["verdict_reason"]
    assert "verdict: not decidable" in (out / "report.html").read_text(encoding="utf-8")
    rows = list(csv.DictReader((out / "rails.csv").open()))
    sig = np.array([float(r["vertical_sigma_um"]) for r in rows if abs(float(r["s_mm"])) > 200])
    assert sig.min() > 1e-3  # not the collapsed 4e-5 µm of a prior shrunk to zero


def test_pitch_proportional_to_position_warns(tmp_path, capsys):
    # pitch = 20 µrad per mm of travel: 7 mrad at the stroke's end
    _write_measurements(tmp_path / "p.csv", lambda k, r: 20 * float(r["position_mm"])
                        if r["quantity"] == "EBX" else 0.0)
    assert main(["fit", "--measurements", str(tmp_path / "p.csv"), "--out",
                 str(tmp_path / "out"), *FAST]) in (0, 3)
    err = _codes(capsys.readouterr().err)
    rep = json.loads((tmp_path / "out" / "report.json").read_text())
    codes = {w["code"] for w in rep["validity"]}
    assert "rotation_beyond_small_angle" in codes and "small-rotation" in err


# ---- the audit's simulate reproducers ----

def _simulate(tmp_path, rails, capsys):
    rc = main(["simulate", "--rails", str(rails), "--mesh", "6x3", "--positions",
               "-350:350:5", "--out", str(tmp_path / "sim.csv"), "--quiet"])
    return rc, _codes(capsys.readouterr().err)


def test_rails_sampled_over_40_mm_warn_of_extrapolation(tmp_path, capsys):
    s = np.linspace(-40, 40, 9)
    _write_rails(tmp_path / "r.csv", s, 25 * (s * 1e-3 + (s * 1e-3) ** 2))
    rc, err = _simulate(tmp_path, tmp_path / "r.csv", capsys)
    assert rc == 0 and "rail 1 is sampled over [-40, 40] mm" in err


def test_alternating_rails_warn_of_the_contact_range(tmp_path, capsys):
    s = np.arange(-800, 801, 20.0)
    _write_rails(tmp_path / "r.csv", s, 9999.0 * (-1.0) ** np.arange(len(s)))
    rc, err = _simulate(tmp_path, tmp_path / "r.csv", capsys)
    assert rc == 0
    assert "small-deflection range" in err and "small-rotation" in err


def test_plausible_rails_raise_no_warning(tmp_path, capsys):
    s = np.linspace(-600, 600, 121)
    _write_rails(tmp_path / "r.csv", s, 25 * (s * 1e-3 + (s * 1e-3) ** 2))
    rc, err = _simulate(tmp_path, tmp_path / "r.csv", capsys)
    assert rc == 0 and err == ""


def test_rail_range_reports_the_departure_written_out_in_numpy():
    """The batched rail check's figure equals the departure of the rail under every carriage
    from its least-squares line, evaluated here sample by sample in NumPy from the sine."""
    from diffguide.guideway.rails import SinusoidalRail, StraightRail
    from diffguide.machine.majda2012 import majda2012_machine
    from diffguide.machine.validity import rail_range

    machine = majda2012_machine(nx=4, ny=2)
    amp, wl = 80e-6, 0.031
    rails = (SinusoidalRail(amp, wl), StraightRail())
    x = np.array([-0.2, 0.0, 0.13])
    xi = np.asarray(machine.carriage.xi, float)
    worst = 0.0
    for v in x:
        for k, r in enumerate(machine.carriage_rail):
            if r != 0:
                continue
            e = amp * np.sin(2 * np.pi * (v + float(machine.carriage_x[k]) + xi) / wl)
            line = np.polyval(np.polyfit(xi, e, 1), xi)
            worst = max(worst, float(np.max(np.abs(e - line))))
    (w,) = rail_range(machine, rails, x)
    assert w.code == "rail_beyond_contact_range"
    assert f"{worst * 1e6:.4g} µm" in w.message

    def sample(r, s):  # the host evaluation the fit's report passes (the same rails)
        e = amp * np.sin(2 * np.pi * s / wl) if r == 0 else np.zeros_like(s)
        return np.zeros_like(s), e
    (w_host,) = rail_range(machine, rails, x, sample=sample)
    assert w_host.message == w.message
