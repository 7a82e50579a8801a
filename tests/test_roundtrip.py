"""Every file a fit writes reads back into what consumes it, on every position grid and layout
of the battery (tests/battery/cases.py) and on grids chosen to stress the round-off of the
fitted range's ends:

- ``rails.csv`` → the rails reader of ``simulate --rails`` and ``fit --truth``
  (:mod:`diffguide.io.rails_csv`);
- ``fit.csv`` → the measurement reader (``fit --measurements``): the same merged data;
- ``layout.csv`` → ``plan --start`` (:func:`diffguide.io.plan_files.read_placements`);
- ``errors.csv`` of ``simulate`` → a CSV reader, the same numbers.

The writers are exercised on the arrays a fit hands them, without fitting; one real fit (the
bundled data measured over x ∈ [−250, 350] mm, whose fitted range starts at the float
−0.43200000000000005 m) goes end to end through the command line.
"""

import csv
import types
from pathlib import Path

import numpy as np
import pytest
from battery import cases
from battery.cases import CASES

from diffguide.cli import main
from diffguide.guideway.carriage import element_offsets
from diffguide.inverse import RailBasis, visited_range
from diffguide.io.errors_csv import joint_errors_csv
from diffguide.io.fit_files import fit_csv_text, layout_csv_text, profile_grid, rails_csv_text
from diffguide.io.measurements import merge_readings, parse_readings
from diffguide.io.plan_files import read_placements
from diffguide.io.rails_csv import rails_at, read_rails_csv, read_rails_samples, sampled_ranges
from diffguide.machine.errors import error_columns

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"

#: What :func:`visited_range` reads of a machine: the majda2012 carriages (±160 mm, 12 elements
#: at 4 mm pitch) — inputs here, not results.
MACHINE = types.SimpleNamespace(carriage_x=np.array([-0.16, 0.16, -0.16, 0.16]),
                                carriage=types.SimpleNamespace(xi=element_offsets(12, 0.004)))


def _grids() -> dict[str, np.ndarray]:
    """Position grids (m): every battery case's, the measured-range case of the issue
    (−250..350 mm), a non-uniform one, and one with positions off the 1 µm grid."""
    out = {f"{n} positions": np.linspace(-0.35, 0.35, n)
           for n in sorted({make().n_positions for make in CASES.values()})}
    rng = np.random.default_rng(28)
    out["measured -250..350 mm"] = np.linspace(-0.25, 0.35, 61)
    out["non-uniform"] = np.sort(rng.uniform(-0.35, 0.35, 40))
    out["off the micron grid"] = np.linspace(-0.3499996, 0.3300004, 23)
    return out


GRIDS = _grids()
#: Knot spacings (m): the default (the carriage's loaded length), coarse, fine.
SPACINGS = (0.048, 0.096, 0.02)


def _profiles(s):
    """Smooth known profiles ``(2, 2, len(s))`` (m) and σ (m)."""
    k = np.arange(4).reshape(2, 2, 1)
    val = 1e-6 * (np.sin(2 * np.pi * s / (0.3 + 0.1 * k)) + (k - 1.5) * s)
    return val, 1e-7 * (1.0 + k + s**2)


@pytest.mark.parametrize("spacing", SPACINGS)
@pytest.mark.parametrize("grid", list(GRIDS))
def test_rails_csv_reads_back(grid, spacing, tmp_path):
    basis = RailBasis.covering(*visited_range(MACHINE, GRIDS[grid]), spacing)
    s = profile_grid(basis)
    assert s[0] == basis.start and s[-1] == basis.end
    assert np.all(np.diff(s) >= 1e-6 - 1e-12) and np.all(np.diff(s) <= 2e-3 + 1e-6)
    val, sig = _profiles(s)
    path = tmp_path / "rails.csv"
    path.write_text(rails_csv_text(s, val, sig))
    samples = read_rails_samples(path)  # the reader of simulate --rails; refuses a repeated s
    s_written = np.round(s * 1e3, 3) * 1e-3
    for r in (1, 2):
        data = samples[r]
        np.testing.assert_allclose(data[:, 0], s_written, rtol=0, atol=1e-12)
        np.testing.assert_allclose(data[:, 1], val[r - 1, 0], rtol=0, atol=1e-11)
        np.testing.assert_allclose(data[:, 2], val[r - 1, 1], rtol=0, atol=1e-11)
    lo, hi = sampled_ranges(path)[0]
    assert abs(lo - basis.start) <= 5e-7 and abs(hi - basis.end) <= 5e-7
    np.testing.assert_allclose(rails_at(path, s), val, rtol=0, atol=1e-11)  # fit --truth
    rails = read_rails_csv(path)  # the splines simulate --rails builds
    mid = s[len(s) // 2]
    got = np.array([[float(v) for v in rail(mid)] for rail in rails])  # (horizontal, vertical)
    want = _profiles(np.array([mid]))[0][:, :, 0][:, ::-1]
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-9)


def test_profile_grid_ends_never_collide_with_the_step():
    """Ends a round-off away from a multiple of the step (either side, at the file's 0.001 mm
    resolution and far below it) are written once."""
    rng = np.random.default_rng(5)
    for _ in range(400):
        lo = -rng.integers(100, 300) * 2e-3 + rng.choice([0, 1e-17, -1e-16, 4e-7, -4e-7,
                                                          6e-7, -6e-7, 1e-9])
        hi = rng.integers(100, 300) * 2e-3 + rng.choice([0, 1e-16, -4e-7, 5e-7, 1.3e-6])
        s = profile_grid(RailBasis.covering(lo, hi, 0.048))
        written = [f"{v * 1e3:.3f}" for v in s]
        assert len(set(written)) == len(written), (lo, hi, written[:3], written[-3:])


def test_rails_csv_text_refuses_s_it_cannot_write_apart():
    s = np.array([0.0, 1e-3, 1.0002e-3, 2e-3])
    val, sig = _profiles(s)
    with pytest.raises(ValueError, match=r"rows 2 and 3 read 1.000 and 1.000 mm"):
        rails_csv_text(s, val, sig)


def _case_measurements(name):
    """A battery case's readings (any values: a random field in place of the truth's errors,
    with the case's noise, drift and outliers), through the input path."""
    case = CASES[name]()
    errors = np.random.default_rng(3).normal(0.0, 3.0, (case.n_positions, len(case.points()), 6))
    return cases.measurements(case, errors)


@pytest.mark.parametrize("name", list(CASES))
def test_fit_csv_reads_back_as_the_same_measurements(name):
    meas = _case_measurements(name)
    fitted = np.asarray(meas.value) * 0.5 + 1e-7
    fake = types.SimpleNamespace(outliers=np.array([0, 3]), fitted=fitted)
    text = fit_csv_text(meas, {"": fake, "_rigid": fake})
    back = merge_readings(parse_readings(text, "fit.csv"), source="fit.csv")
    for field in ("position", "point", "quantity", "n_readings", "z"):
        np.testing.assert_array_equal(getattr(back, field), getattr(meas, field), err_msg=field)
    np.testing.assert_allclose(back.value, meas.value, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(back.sigma, meas.sigma, rtol=1e-9)
    assert back.point_names == meas.point_names and back.instrument == meas.instrument
    assert len(back.rejected) == len(meas.rejected)
    rows = list(csv.DictReader(text.splitlines()))
    assert len(rows) == len(meas.readings)
    for row in rows:
        if row["fitted"]:
            assert float(row["value"]) - float(row["fitted"]) == pytest.approx(
                float(row["residual"]), rel=1e-8, abs=1e-9)


def test_fit_csv_keeps_a_stated_sigma_a_height_and_a_differential_pair():
    text = "position_mm,point,x_mm,y_mm,quantity,value,reference,unit,sigma,z_mm\n" + "".join(
        f"{x},P1,0,0,EXX,{0.3 * x / 100:.2f},{0.01 * k:.2f},um,0.7,85\n"
        f"{x},P1,0,0,EBX,{np.sin(x / 90):.3f},0,urad,1.5,85\n"
        for k, x in enumerate(range(-300, 301, 50)))
    meas = merge_readings(parse_readings(text, "in.csv"), source="in.csv")
    fake = types.SimpleNamespace(outliers=np.zeros(0, int), fitted=np.asarray(meas.value))
    back = merge_readings(parse_readings(fit_csv_text(meas, {"": fake}), "fit.csv"),
                          source="fit.csv")
    np.testing.assert_allclose(back.value, meas.value, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(back.sigma, meas.sigma, rtol=1e-9)
    np.testing.assert_allclose(back.z, 0.085)
    res = [r.resolution for r in parse_readings(text, "in.csv")]
    np.testing.assert_allclose([r.resolution for r in parse_readings(
        fit_csv_text(meas, {"": fake}), "fit.csv")], res, rtol=1e-9)


def _expected_layout(case) -> set:
    """What layout.csv must list for ``case``'s sensors, from the planner's kinds: a level; an
    interferometer's angular optics; its straightness optics; positioning left out."""
    out = set()
    for _name, x, y, inst, qs in case.sensors:
        for q in qs:
            kind = ("level" if inst == "level" else "interferometer" if q in ("EBX", "ECX",
                    "EAX") else "straightness" if q in ("EYX", "EZX") else None)
            if kind is not None:
                out.add((kind, x, y))
    return out


LAYOUTS = {name: CASES[name]() for name in CASES}
LAYOUTS["planned"] = cases.planned(CASES["baseline"]())


@pytest.mark.parametrize("name", sorted({v.sensors: k for k, v in LAYOUTS.items()}.values()))
def test_layout_csv_reads_back_into_plan(name, tmp_path):
    case = LAYOUTS[name]
    errors = np.zeros((case.n_positions, len(case.points()), 6))
    meas = cases.measurements(case, errors)
    path = tmp_path / "layout.csv"
    path.write_text(layout_csv_text(meas))
    sites: dict = {}
    placements = read_placements(str(path), "--start", (1000.0, 500.0), sites)
    got = {(kind, round(sites[site][0] * 1e3, 6), round(sites[site][1] * 1e3, 6))
           for kind, site in placements}
    assert got == _expected_layout(case)


@pytest.mark.parametrize("grid", list(GRIDS))
def test_errors_csv_reads_back(grid):
    x = GRIDS[grid]
    names, xy = ["P1", "T 2"], np.array([[0.45, 0.2], [-0.1234567, 0.0]])
    err = np.random.default_rng(1).normal(0, 5, (len(x), 2, 6))
    rows = list(csv.DictReader(joint_errors_csv(x, names, xy, err).splitlines()))
    assert list(rows[0]) == ["position_mm", "point", "x_mm", "y_mm", *error_columns()]
    pos = np.array([float(r["position_mm"]) for r in rows]).reshape(len(x), 2)
    np.testing.assert_allclose(pos, np.repeat(x[:, None] * 1e3, 2, 1), rtol=0, atol=5e-4)
    assert len(np.unique(pos[:, 0])) == len(x)  # distinct positions stay distinct
    vals = np.array([[float(r[c]) for c in error_columns()] for r in rows])
    np.testing.assert_allclose(vals, err.reshape(-1, 6), rtol=0, atol=5e-7)


def test_a_real_fit_reads_back_end_to_end(tmp_path, capsys):
    """The bundled data measured over −250..350 mm: the fitted range starts at
    −0.43200000000000005 m, next to the 2 mm multiple −432 mm (the issue's repeated row)."""
    lines = DATA.read_text().splitlines()
    keep = [ln for ln in lines if ln.startswith(("#", "position_mm"))
            or (ln.strip() and float(ln.split(",")[0]) >= -250.0)]
    data = tmp_path / "part.csv"
    data.write_text("\n".join(keep) + "\n")
    out = tmp_path / "fit"
    rc = main(["fit", "--measurements", str(data), "--out", str(out), "--no-plots", "--quiet",
               "--structure", "fixed"])
    assert rc == 0, capsys.readouterr().err
    s = read_rails_samples(out / "rails.csv")[1][:, 0]
    assert s[0] == pytest.approx(-0.432, abs=1e-9)
    errs = tmp_path / "errors.csv"
    rc = main(["simulate", "--rails", str(out / "rails.csv"), "--positions", "-250:350:4",
               "--out", str(errs), "--quiet"])
    assert rc == 0, capsys.readouterr().err
    assert len(errs.read_text().splitlines()) > 4
    meas = merge_readings(parse_readings(data.read_text(), "part.csv"), source="part.csv")
    back = merge_readings(parse_readings((out / "fit.csv").read_text(), "fit.csv"),
                          source="fit.csv")
    np.testing.assert_allclose(back.value, meas.value, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(back.sigma, meas.sigma, rtol=1e-9)
    sites: dict = {}
    placed = read_placements(str(out / "layout.csv"), "--start", (1000.0, 500.0), sites)
    assert {k for k, _ in placed} == {"level", "interferometer"} and len(placed) == 5
