"""Measurement CSV: validation with file:line:field messages, units, merging of runs."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from diffguide.io.measurements import (
    MIN_SCATTER_DOF,
    QUANTITIES,
    merge_readings,
    parse_readings,
    read_measurements,
)
from diffguide.machine.kinematics import ERROR_NAMES

HEADER = "position_mm,point,x_mm,y_mm,quantity,value,unit"


def _write(tmp_path, text, name="m.csv"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_quantities_match_kinematics():
    assert QUANTITIES == ERROR_NAMES


@pytest.mark.parametrize("unit, value, si", [
    ("um/m", 2.0, 2e-6), ("µm/m", 2.0, 2e-6), ("urad", 3.0, 3e-6), ("µrad", 3.0, 3e-6),
    ("mrad", 0.5, 5e-4), ("arcsec", 1.0, math.pi / 648000),
])
def test_angular_units(tmp_path, unit, value, si):
    m = read_measurements(_write(tmp_path, f"{HEADER}\n0,P1,1,2,EBX,{value},{unit}\n"))
    assert m.value[0] == pytest.approx(si, rel=1e-12)
    assert m.points_xy[0] == pytest.approx([1e-3, 2e-3])


@pytest.mark.parametrize("unit, si", [("um", 1e-6), ("µm", 1e-6), ("mm", 1e-3)])
def test_linear_units(tmp_path, unit, si):
    m = read_measurements(_write(tmp_path, f"{HEADER}\n10,P1,0,0,EZX,1.5,{unit}\n"))
    assert m.value[0] == pytest.approx(1.5 * si)
    assert m.position[0] == pytest.approx(0.01)
    assert m.instrument == ("interferometer",)


@pytest.mark.parametrize("row, field, allowed", [
    ("x,P1,0,0,EBX,1,um/m", "position_mm", "finite number"),
    ("nan,P1,0,0,EBX,1,um/m", "position_mm", "finite number"),
    ("0,,0,0,EBX,1,um/m", "point", "non-empty"),
    ("0,P1,0,inf,EBX,1,um/m", "y_mm", "finite"),
    ("0,P1,0,0,EQX,1,um/m", "quantity", "EXX, EYX"),
    ("0,P1,0,0,EBX,1,um", "unit", "um/m"),
    ("0,P1,0,0,EZX,1,urad", "unit", "mm"),
    ("0,P1,0,0,EBX,1e999,um/m", "value", "finite"),
], ids=lambda v: str(v)[:18])
def test_bad_row_names_file_line_field(tmp_path, row, field, allowed):
    p = _write(tmp_path, f"# comment\n{HEADER}\n0,P1,0,0,EBX,1,um/m\n{row}\n")
    with pytest.raises(ValueError) as exc:
        read_measurements(p)
    msg = str(exc.value)
    assert msg.startswith(f"{p}:4: field '{field}'")
    assert allowed in msg


@pytest.mark.parametrize("extra, row, field", [
    (",sigma", "0,P1,0,0,EBX,1,um/m,-1", "sigma"),
    (",sigma", "0,P1,0,0,EBX,1,um/m,1e9", "sigma"),  # beyond the readings' 10 mrad limit
    (",sigma", "0,P1,0,0,EZX,1,mm,10.5", "sigma"),
    (",direction", "0,P1,0,0,EBX,1,um/m,sideways", "direction"),
    (",instrument", "0,P1,0,0,EBX,1,um/m,theodolite", "instrument"),
    (",instrument", "0,P1,0,0,ECX,1,um/m,level", "instrument"),
])
def test_bad_optional_fields(tmp_path, extra, row, field):
    p = _write(tmp_path, f"{HEADER}{extra}\n{row}\n")
    with pytest.raises(ValueError, match=rf"^{p}:2: field '{field}'.*allowed"):
        read_measurements(p)


def test_structural_errors(tmp_path):
    with pytest.raises(ValueError, match=r":1: unknown column 'sigam'"):
        read_measurements(_write(tmp_path, HEADER + ",sigam\n"))
    with pytest.raises(ValueError, match=r":1: missing column\(s\) unit"):
        read_measurements(_write(tmp_path, "position_mm,point,x_mm,y_mm,quantity,value\n"))
    with pytest.raises(ValueError, match=r":2: no data rows"):
        read_measurements(_write(tmp_path, "\n" + HEADER + "\n"))
    with pytest.raises(ValueError, match=r":3: 6 fields"):
        read_measurements(_write(tmp_path, HEADER + "\n0,P1,0,0,EBX,1,um/m\n0,P1,0,0,EBX,1\n"))
    with pytest.raises(ValueError, match=r":3: field 'x_mm'/'y_mm': point 'P1'"):
        read_measurements(_write(tmp_path, HEADER + "\n0,P1,0,0,EBX,1,um/m\n5,P1,9,0,EBX,1,um/m\n"))
    with pytest.raises(ValueError, match="cannot read"):
        read_measurements(tmp_path / "missing.csv")
    p = tmp_path / "bin.csv"
    p.write_bytes(HEADER.encode() + b"\n0,P1,0,0,EBX,\xff,um/m\n")
    with pytest.raises(ValueError, match=r":2: field 'value': not a number, got 'ÿ'"):
        read_measurements(p)  # not UTF-8: read as cp1252, where 0xff is 'ÿ'
    p.write_bytes(HEADER.encode() + b"\n0,P1,0,0,EBX,\x00,um/m\n")
    with pytest.raises(ValueError, match=r":2: the file contains a NUL byte"):
        read_measurements(p)


def _runs_text(values_fwd, values_bwd, sigma=None):
    head = HEADER + ",run,direction" + (",sigma" if sigma else "")
    rows = []
    for run, v in enumerate(values_fwd):
        rows.append(f"0,P1,0,0,EBX,{v},um/m,{run},forward" + (f",{sigma}" if sigma else ""))
    for run, v in enumerate(values_bwd):
        rows.append(f"0,P1,0,0,EBX,{v},um/m,{run},backward" + (f",{sigma}" if sigma else ""))
    return head + "\n" + "\n".join(rows) + "\n"


def test_bidirectional_mean_and_sigma_column(tmp_path):
    # unequal run counts: the mean of the direction means, not of all readings
    m = read_measurements(_write(tmp_path, _runs_text([1, 2, 3], [7], sigma=2.0)))
    assert m.value[0] == pytest.approx(0.5 * (2 + 7) * 1e-6)
    assert m.reversal[0] == pytest.approx((2 - 7) * 1e-6)
    # σ² of the mean of two means: ¼ (σ²/3 + σ²/1)
    assert m.sigma[0] == pytest.approx(0.5 * math.sqrt(4 / 3 + 4) * 1e-6)
    assert m.sigma_source == ("column",)
    assert m.n_readings[0] == 4


def test_default_sigma_by_instrument(tmp_path):
    m = read_measurements(_write(tmp_path, _runs_text([1, 2], [3, 4])))
    assert m.sigma[0] == pytest.approx(4e-6 / 2)  # level, 4 readings
    assert m.sigma_source == ("default",)


def test_sigma_from_pooled_scatter_matches_noise():
    rng = np.random.default_rng(1)
    lines = [HEADER + ",run,direction,instrument"]
    n_pos, runs, sd = 40, 5, 3.0
    for i in range(n_pos):
        for run in range(runs):
            for d in ("forward", "backward"):
                v = 10 * np.sin(i) + (0.5 if d == "forward" else -0.5) + rng.normal(0, sd)
                lines.append(f"{i * 10},P5,0,0,ECX,{v:.6f},um/m,{run},{d},interferometer")
    m = merge_readings(parse_readings("\n".join(lines)))
    assert n_pos * 2 * (runs - 1) >= MIN_SCATTER_DOF
    assert set(m.sigma_source) == {"scatter"}
    per_reading = m.sigma[0] * math.sqrt(2 * runs) * 1e6
    # pooled sd from 320 degrees of freedom: relative standard error 1/sqrt(2*320) = 4 %
    assert per_reading == pytest.approx(sd, rel=0.15)
    assert np.allclose(m.reversal * 1e6, 1.0, atol=4 * sd / math.sqrt(runs / 2))
    assert m.n == n_pos and np.all(m.n_readings == 2 * runs)


def test_row_of_reading_maps_back(tmp_path):
    m = read_measurements(_write(tmp_path, HEADER + "\n0,A,0,0,EBX,1,um/m\n10,A,0,0,EBX,2,um/m\n"
                                 "0,A,0,0,EBX,3,um/m\n0,B,1,1,EAX,4,um/m\n"))
    assert m.point_names == ("A", "B")
    vals = [m.value[k] for k in m.row_of_reading]
    assert vals == pytest.approx([2e-6, 2e-6, 2e-6, 4e-6])


_FIELD = st.one_of(st.sampled_from(["0", "1e3", "-5", "nan", "inf", "", "P1", "EBX", "ECX",
                                    "um/m", "mrad", "um", "forward", "-", "level", "1e999",
                                    '"', "a,b", "\x00"]),
                   st.text(max_size=6))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(header=st.lists(st.sampled_from(["position_mm", "point", "x_mm", "y_mm", "quantity",
                                         "value", "unit", "sigma", "run", "direction",
                                         "instrument", "bogus"]), min_size=0, max_size=12),
       rows=st.lists(st.lists(_FIELD, min_size=0, max_size=12), max_size=4))
def test_fuzz_only_value_errors(header, rows):
    text = ",".join(header) + "\n" + "\n".join(",".join(r) for r in rows)
    try:
        m = merge_readings(parse_readings(text, "fuzz.csv"), "fuzz.csv")
    except ValueError as exc:
        assert str(exc).startswith("fuzz.csv")
    else:
        assert np.all(np.isfinite(m.value)) and np.all(m.sigma > 0)


def test_two_instruments_at_one_point_are_two_channels(tmp_path):
    text = (HEADER + ",instrument\n0,P1,0,0,EBX,1,um/m,level\n0,P1,0,0,EBX,5,um/m,interferometer\n"
            "10,P1,0,0,EBX,2,um/m,level\n10,P1,0,0,EBX,6,um/m,interferometer\n")
    m = read_measurements(_write(tmp_path, text))
    assert m.n == 4 and len(m.channels) == 2
    assert {m.channel_label(c) for c in range(2)} == {"EBX at P1 (level)",
                                                       "EBX at P1 (interferometer)"}
    # each channel's own rows, in its own zero
    chan = m.channel_index()
    for c in range(2):
        inst = m.channels[c][2]
        assert all(m.instrument[i] == inst for i in np.flatnonzero(chan == c))


def test_z_column_and_one_height_per_channel(tmp_path):
    m = read_measurements(_write(tmp_path, HEADER + ",z_mm\n0,P5,0,0,EXX,1,um,120\n"
                                 "10,P5,0,0,EXX,2,um,120\n"))
    assert m.z == pytest.approx([0.12, 0.12])
    with pytest.raises(ValueError, match=r":3: field 'z_mm'.*several heights"):
        read_measurements(_write(tmp_path, HEADER + ",z_mm\n0,P5,0,0,EXX,1,um,120\n"
                                 "0,P5,0,0,EXX,2,um,0\n"))
    with pytest.raises(ValueError, match=r":2: field 'z_mm'.*allowed -2000 to 2000 mm"):
        read_measurements(_write(tmp_path, HEADER + ",z_mm\n0,P5,0,0,EXX,1,um,9000\n"))


def _outlier_text(rng, n_pos, runs, sd, outliers):
    lines = [HEADER + ",run,direction"]
    for i in range(n_pos):
        for run in range(runs):
            for d in ("forward", "backward"):
                v = 5 * np.cos(i / 3) + rng.normal(0, sd)
                if (i, run, d) in outliers:
                    v += 10 * sd
                lines.append(f"{i * 10},P1,0,0,EBX,{v:.6f},um/m,{run},{d}")
    return "\n".join(lines) + "\n"


def test_gross_outliers_are_set_aside_and_clean_data_kept():
    rng = np.random.default_rng(7)
    bad = {(3, 1, "forward"), (17, 4, "backward"), (30, 0, "forward")}
    text = _outlier_text(rng, 36, 5, 4.0, bad)
    m = merge_readings(parse_readings(text, "o.csv"), "o.csv")
    lines = {2 + (i * 5 + run) * 2 + (d == "backward") for i, run, d in bad}
    assert set(m.rejected) == lines
    assert all(m.row_of_reading[k] == -1 for k, r in enumerate(m.readings) if r.line in lines)
    # ten clean data sets of 3600 readings: a 6σ criterion rejects (almost) nothing
    rejected = [len(merge_readings(parse_readings(_outlier_text(rng, 36, 5, 4.0, set())))
                    .rejected) for _ in range(10)]
    assert sum(rejected) <= 1, rejected


def test_leave_one_out_deviation_matches_a_median_per_reading():
    """The order-statistic form equals ``|v_k − median(v without v_k)|`` computed one median at a
    time, for every length and with ties."""
    from diffguide.io.measurements import leave_one_out_deviation

    rng = np.random.default_rng(1)
    for n in range(2, 14):
        for trial in range(50):
            v = rng.integers(0, 4, n).astype(float) if trial % 2 else rng.normal(size=n)
            ref = [abs(v[k] - np.median(np.delete(v, k))) for k in range(n)]
            np.testing.assert_allclose(leave_one_out_deviation(v), ref, rtol=0, atol=1e-15)


def _identical_runs_text(quantity, unit, instrument, values, runs=5, odd=None):
    """Every run and direction of every position reads the same written value — except, with
    ``odd = (position index, text)``, run 1's forward reading there (``odd`` a dict:
    ``{(position index, direction): text}``, run 1's reading at each)."""
    odd = {} if odd is None else odd if isinstance(odd, dict) else {(odd[0], "forward"): odd[1]}
    lines = [HEADER + ",run,direction,instrument"]
    for i, v in enumerate(values):
        for run in range(1, runs + 1):
            for d in ("forward", "backward"):
                w = odd[(i, d)] if run == 1 and (i, d) in odd else v
                lines.append(f"{i * 20},P5,0,0,{quantity},{w},{unit},{run},{d},{instrument}")
    return "\n".join(lines) + "\n"


def test_identical_runs_are_one_run_with_the_instrument_default():
    # runs identical at every position (copies of one run): their mean is no better than one
    # reading, and they say nothing of the repeatability — σ of one reading is the default
    # (1 µm for a linear interferometer), merged as one forward and one backward reading
    values = [f"{0.1 * k - 3.697:.3f}" for k in range(36)]
    text = _identical_runs_text("EXX", "um", "interferometer", values)
    notes = []
    m = merge_readings(parse_readings(text, "same.csv"), "same.csv", notes)
    assert np.allclose(m.sigma, 1e-6 / math.sqrt(2), rtol=1e-12)
    assert set(m.sigma_source) == {"copies+default"}
    assert len(notes) == 1 and "EXX at P5 (interferometer)" in notes[0]
    assert "identical at every position" in notes[0] and "default 1 µm" in notes[0]
    # a stated σ is one reading's, not divided by the number of copies either
    stated = parse_readings(text.replace("instrument\n", "instrument,sigma\n", 1)
                            .replace("interferometer\n", "interferometer,0.3\n"), "same.csv")
    m = merge_readings(stated)
    assert np.allclose(m.sigma, 0.3e-6 / math.sqrt(2), rtol=1e-12)


def test_copies_of_coarsely_rounded_readings_keep_the_rounding():
    # yaw in 10 µm/m steps (stated), identical runs: one reading's σ is the rounding
    # 10/√12 = 2.89 µm/m, above the interferometer's 2 µm/m default; one reading per direction
    values = [str(10 * (k % 3)) for k in range(36)]
    text = _identical_runs_text("ECX", "um/m", "interferometer", values)
    text = text.replace("instrument\n", "instrument,resolution\n", 1).replace(
        "interferometer\n", "interferometer,10\n")
    m = merge_readings(parse_readings(text))
    assert np.allclose(m.sigma, 10e-6 / math.sqrt(12) / math.sqrt(2), rtol=1e-12)
    assert set(m.sigma_source) == {"copies+default"}


def test_an_unknown_rounding_survives_the_canonical_file():
    from diffguide.io.importers import format_long

    r = parse_readings(HEADER + ",resolution\n0,P1,0,0,EBX,1.25,um/m,0\n")[0]
    assert r.resolution == 0.0
    assert parse_readings(format_long([r]))[0].resolution == 0.0


def _every_other(values, delta):
    """Run 1 off by ``delta`` (written to 3 decimals) at every other position, both ways."""
    return {(i, d): f"{float(values[i]) + delta:.3f}" for i in range(0, len(values), 2)
            for d in ("forward", "backward")}


def test_runs_agreeing_below_the_instrument_floor_get_the_floor():
    # runs that differ by 0.001 µm at half of the positions: a pooled scatter of ~3e-4 µm,
    # below the floor max(rounding 0.001 µm / √12, 0.1 × the 1 µm default) = 0.1 µm per
    # reading; the merged value is the mean of 10 readings
    values = [f"{0.1 * k - 3.697:.3f}" for k in range(36)]
    text = _identical_runs_text("EXX", "um", "interferometer", values,
                                odd=_every_other(values, 0.001))
    notes = []
    m = merge_readings(parse_readings(text, "same.csv"), "same.csv", notes)
    assert np.allclose(m.sigma, 0.1e-6 / math.sqrt(10), rtol=1e-12)
    assert set(m.sigma_source) == {"floor"}
    assert len(notes) == 1 and "EXX at P5 (interferometer)" in notes[0]
    assert "below the floor 0.1 µm" in notes[0]
    # they differ by one written digit (0.001 µm) at most: the note asks whether they are copies
    assert "identical runs?" in notes[0]


def _noisy_exx(sigma_um: float, decimals: int, seed: int) -> str:
    """EXX at P5, 36 positions × 5 runs × 2 directions: sin(i) µm plus Gaussian noise of
    ``sigma_um``, written to ``decimals``."""
    rng = np.random.default_rng(seed)
    lines = [HEADER + ",run,direction"]
    for i in range(36):
        for run in range(5):
            for d in ("forward", "backward"):
                v = np.sin(i) + rng.normal(0, sigma_um)
                lines.append(f"{i * 20},P5,0,0,EXX,{v:.{decimals}f},um,{run},{d}")
    return "\n".join(lines)


def test_a_genuine_repeatability_below_the_floor_is_not_called_identical_runs():
    # 0.05 µm of real scatter written to 3 decimals (ranges of ~0.1 µm, 100 written steps):
    # below the 0.1 µm floor of a linear interferometer, so σ of one reading is the floor, but
    # the runs are not identical and the note must not say so
    notes = []
    m = merge_readings(parse_readings(_noisy_exx(0.05, 3, seed=7), "real.csv"), "real.csv",
                       notes)
    assert np.allclose(m.sigma, 0.1e-6 / math.sqrt(10), rtol=1e-12)
    assert set(m.sigma_source) == {"floor"}
    assert len(notes) == 1 and "below the floor 0.1 µm" in notes[0]
    assert "identical runs" not in notes[0]
    assert "repeatability finer than the instrument class" in notes[0]


@pytest.mark.parametrize("n_odd", [1, 7])
def test_copies_with_a_few_readings_changed_are_still_copies(n_odd):
    # copies of one run with one (or 7 of 72 groups) reading edited: no repeatability in them,
    # the information of one run — merged exactly as exact copies are (σ of one reading the
    # 1 µm default, one reading per direction), not as 10 readings at the 0.1 µm floor (10×
    # the σ, 100× less weight than before this rule)
    values = [f"{0.1 * k - 3.697:.3f}" for k in range(36)]
    odd = {(i, "forward"): f"{float(values[i]) + 0.25:.3f}" for i in range(0, 5 * n_odd, 5)}
    text = _identical_runs_text("EXX", "um", "interferometer", values, odd=odd)
    notes = []
    m = merge_readings(parse_readings(text, "edited.csv"), "edited.csv", notes)
    exact = merge_readings(parse_readings(_identical_runs_text("EXX", "um", "interferometer",
                                                               values)))
    np.testing.assert_allclose(m.sigma, exact.sigma, rtol=1e-12)
    assert set(m.sigma_source) == {"copies+default"}
    assert len(notes) == 1 and f"identical at {72 - n_odd} of the 72" in notes[0]
    # the edited readings still count in the merged values (mean of the copies)
    changed = np.unique([i for i, _ in odd])
    assert np.all(np.abs(m.value - exact.value)[changed] > 0)


def _coarse_odd(values):
    """Whole arcseconds: run 1 one 1″ step off at every fourth position, both ways (18 of the
    72 groups: below the 80 % that make copies)."""
    return {(i, d): str(int(values[i]) + 1) for i in range(0, len(values), 4)
            for d in ("forward", "backward")}


def test_runs_written_coarsely_get_the_rounding_floor():
    # whole arcseconds, run 1 one 1″ off at a quarter of the positions: a rounding step of
    # 1″ = π/648000 rad, uniform: σ = step/√12 (GUM F.2.2.1), above 0.1 × the level's 4 µm/m
    # default and above the pooled scatter (18 1″ deviations in 288 degrees of freedom: 0.22″)
    values = [str(k % 7 - 3) for k in range(36)]
    m = merge_readings(parse_readings(
        _identical_runs_text("EBX", "arcsec", "level", values, odd=_coarse_odd(values))))
    step = math.pi / 648000
    assert step / math.sqrt(12) > 0.4e-6
    assert np.allclose(m.sigma, step / math.sqrt(12) / math.sqrt(10), rtol=1e-12)
    assert set(m.sigma_source) == {"floor"}


def test_import_keeps_the_rounding_floor_of_coarse_readings():
    # the whole-arcsecond file above, converted to the canonical 6-decimal µm/m file: the
    # written digits would say 1e-6 µm/m; the resolution column keeps the 1″ step
    from diffguide.io.importers import format_long

    values = [str(k % 7 - 3) for k in range(36)]
    original = parse_readings(_identical_runs_text("EBX", "arcsec", "level", values,
                                                   odd=_coarse_odd(values)))
    text = format_long(original)
    assert text.splitlines()[0].endswith(",z_mm,resolution")
    again = parse_readings(text)
    assert [r.resolution for r in again] == pytest.approx([r.resolution for r in original],
                                                          rel=1e-5)
    step = math.pi / 648000
    m = merge_readings(again)
    assert np.allclose(m.sigma, step / math.sqrt(12) / math.sqrt(10), rtol=1e-5)
    assert set(m.sigma_source) == {"floor"}


def test_a_stated_resolution_replaces_the_written_digits():
    # 2 µm/m steps on a display, exported with 3 decimals; a pair rounds both of its readings
    r = parse_readings(HEADER + ",resolution\n0,P1,0,0,EBX,1.250,um/m,2\n")[0]
    assert r.resolution == pytest.approx(2e-6 / math.sqrt(12))
    r = parse_readings(HEADER + ",reference,resolution\n0,P1,0,0,EBX,1.250,um/m,0.5,2\n")[0]
    assert r.resolution == pytest.approx(math.sqrt(2) * 2e-6 / math.sqrt(12))
    r = parse_readings(HEADER + ",resolution\n0,P1,0,0,EBX,1.250,um/m,\n")[0]
    assert r.resolution == pytest.approx(1e-3 * 1e-6 / math.sqrt(12))


@pytest.mark.parametrize("raw", ["-1", "x", "20000"])
def test_a_bad_resolution_names_the_line_and_the_field(raw):
    with pytest.raises(ValueError, match=r"f\.csv:2: field 'resolution'"):
        parse_readings(HEADER + f",resolution\n0,P1,0,0,EBX,1.25,um/m,{raw}\n", "f.csv")


def test_a_real_scatter_above_the_floor_is_kept():
    # 0.3 µm scatter of a linear interferometer: above its 0.1 µm floor, used as it is
    notes = []
    m = merge_readings(parse_readings(_noisy_exx(0.3, 4, seed=3)), notes=notes)
    assert set(m.sigma_source) == {"scatter"} and not notes
    assert m.sigma[0] * math.sqrt(10) * 1e6 == pytest.approx(0.3, rel=0.15)


@pytest.mark.parametrize("raw, step", [("1.250", 1e-3), ("12", 1.0), ("-3.", 1.0), ("-.5", 0.1),
                                       ("1.5e-3", 1e-4), ("2E2", 100.0), ("+0.00", 1e-2),
                                       ("nan", 0.0), ("1_0", 0.0)])
def test_written_step(raw, step):
    from diffguide.io.measurements import written_step

    assert written_step(raw) == pytest.approx(step, rel=1e-12)


def test_differential_pair_rounding_adds_in_quadrature():
    r = parse_readings(HEADER + ",reference\n0,P1,0,0,EBX,1.25,um/m,0.5\n")[0]
    assert r.resolution == pytest.approx(math.hypot(0.01, 0.1) / math.sqrt(12) * 1e-6)


#: EXX at P5 (µm) over the stroke, -350 ... 350 mm every 20 mm: noise-free readings of the
#: bundled machine (made by the adversarial test of the σ floor, /tmp/advtest/with_exx.csv)
_EXX_P5 = [-3.697, -3.393, -3.075, -2.761, -2.468, -2.212, -2.002, -1.839, -1.716, -1.623, -1.542,
           -1.455, -1.343, -1.192, -0.996, -0.752, -0.469, -0.160, 0.160, 0.469, 0.752, 0.996,
           1.192, 1.343, 1.455, 1.542, 1.623, 1.716, 1.839, 2.002, 2.212, 2.468, 2.761, 3.075,
           3.393, 3.697]


def test_fit_with_an_identical_runs_channel_has_chi2_of_order_one(tmp_path):
    """The bundled data plus an EXX channel whose five runs are identical: before the floor the
    channel's σ was ~1e-22 m and the fit returned χ²/dof 7e9 and rails 14 µm off the truth; the
    runs are now merged as one run with the instrument's default σ."""
    import json
    from pathlib import Path

    from diffguide.cli import main

    root = Path(__file__).resolve().parents[1]
    text = (root / "data" / "majda2012_measurements.csv").read_text(encoding="utf-8")
    rows = [f"{-350 + 20 * i:.1f},P5,0.0,0.0,EXX,{v:.3f},um,{run},{d},interferometer"
            for i, v in enumerate(_EXX_P5) for run in range(1, 6) for d in ("forward", "backward")]
    data = _write(tmp_path, text.rstrip("\n") + "\n" + "\n".join(rows) + "\n")
    out = tmp_path / "out"
    assert main(["fit", "--measurements", str(data), "--out", str(out), "--no-plots",
                 "--truth", str(root / "data" / "majda2012_truth.csv"), "--quiet"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert "copies+default" in report["measurements"]["sigma_sources"]
    assert 0.5 < report["elastic"]["chi2_per_dof"] < 2.0
    # as good as the bundled data alone (0.2 µm; the README's table)
    assert report["truth"]["rms_error_um"]["elastic"]["all"] < 0.4


@pytest.mark.parametrize("extra, row, field, allowed", [
    ("", "0,P1,0,0,EBX,10001,um/m", "value", "-10000 to 10000 um/m"),
    ("", "0,P1,0,0,EBX,-10.5,mrad", "value", "-10 to 10 mrad"),
    # 10 mrad = 2062.65 arcsec
    ("", "0,P1,0,0,EAX,2063,arcsec", "value", "-2062.65 to 2062.65 arcsec"),
    ("", "0,P5,0,0,EXX,-10.001,mm", "value", "-10 to 10 mm"),
    ("", "0,P5,0,0,EYX,1e6,um", "value", "-10000 to 10000 um"),
    (",reference", "0,P1,0,0,EBX,1,um/m,-2e4", "reference", "-10000 to 10000 um/m"),
], ids=lambda v: str(v)[:24])
def test_implausible_values_are_refused(tmp_path, extra, row, field, allowed):
    p = _write(tmp_path, f"{HEADER}{extra}\n{row}\n")
    with pytest.raises(ValueError) as exc:
        read_measurements(p)
    msg = str(exc.value)
    assert msg.startswith(f"{p}:2: field '{field}': not a plausible reading")
    assert f"(allowed {allowed}" in msg and "\n" not in msg


def test_values_at_the_plausibility_limit_are_read():
    m = merge_readings(parse_readings(HEADER + "\n0,P1,0,0,EBX,10,mrad\n0,P5,0,0,EZX,-10000,um\n"))
    assert sorted(m.value) == pytest.approx([-1e-2, 1e-2])
    # a stated σ at the same limit is read (one reading: the merged σ is the stated one)
    m = merge_readings(parse_readings(HEADER + ",sigma\n0,P1,0,0,EBX,1,um/m,10000\n"))
    assert m.sigma == pytest.approx([1e-2])


def test_one_huge_value_among_normal_ones_is_refused_not_set_aside():
    # 36 positions x 10 readings of a level; one reading 1e6 µm/m (a unit or export slip) — the
    # outlier rule would set it aside; it is refused, naming its line
    text = _outlier_text(np.random.default_rng(2), 36, 5, 4.0, set()).splitlines()
    fields = text[123].split(",")
    fields[5] = "1e6"
    text[123] = ",".join(fields)
    with pytest.raises(ValueError, match=r"^big\.csv:124: field 'value': not a plausible reading"):
        parse_readings("\n".join(text) + "\n", "big.csv")


def test_repeated_readings_are_merged_with_a_note():
    # lines 2-4: three runs at one position; line 5 repeats line 3 (run 2 forward); line 6 is
    # another direction of that run (no repeat); line 7 repeats line 2, 0.0004 mm apart (the
    # 1 µm grid the merge groups positions on)
    text = (HEADER + ",run,direction\n"
            "0,P1,0,0,EBX,1,um/m,1,forward\n0,P1,0,0,EBX,2,um/m,2,forward\n"
            "0,P1,0,0,EBX,3,um/m,3,forward\n0,P1,0,0,EBX,5,um/m,2,forward\n"
            "0,P1,0,0,EBX,4,um/m,2,backward\n0.0004,P1,0,0,EBX,7,um/m,1,+\n")
    notes = []
    m = merge_readings(parse_readings(text, "d.csv", notes=notes))
    assert len(notes) == 1
    assert notes[0].startswith("d.csv: 2 reading(s) repeat")
    assert "line(s) 5 (as 3), 7 (as 2): merged" in notes[0]
    # merged as further readings: forward mean (1+2+3+5+7)/5 = 3.6, backward 4
    assert m.value[0] == pytest.approx(0.5 * (3.6 + 4) * 1e-6)
    assert m.n_readings[0] == 6


def test_repeat_note_names_the_first_ten_lines():
    rows = [f"{k * 10},P1,0,0,EBX,1,um/m" for k in range(12)]
    notes = []
    parse_readings(HEADER + "\n" + "\n".join(rows + rows) + "\n", "d.csv", notes=notes)
    assert notes[0].startswith("d.csv: 12 reading(s) repeat")
    # header line 1, the first copy on lines 2-13, the second on 14-25
    assert "14 (as 2), 15 (as 3)" in notes[0] and "23 (as 11) ...: merged" in notes[0]
    assert "24 (as 12)" not in notes[0]


@pytest.mark.parametrize("rows, line, what", [
    # an empty cell in a paired channel: not a reference of 0
    (["0,P1,0,0,EBX,5,um/m,1", "10,P1,0,0,EBX,5,um/m,", "20,P1,0,0,EBX,5,um/m,1"], 3,
     "empty, but line 2 of the same channel has one"),
    (["0,P1,0,0,EBX,5,um/m,", "10,P1,0,0,EBX,5,um/m,2"], 3,
     "a reference reading, but line 2 of the same channel has none"),
], ids=["empty", "late"])
def test_reference_on_every_row_of_a_channel_or_none(tmp_path, rows, line, what):
    p = _write(tmp_path, HEADER + ",reference\n" + "\n".join(rows) + "\n")
    with pytest.raises(ValueError) as exc:
        read_measurements(p)
    msg = str(exc.value)
    assert msg.startswith(f"{p}:{line}: field 'reference': {what} (EBX at P1, level; allowed")


def test_reference_column_with_unpaired_channels():
    # levels paired, the interferometer's cells empty (as the bundled semicolon example)
    m = merge_readings(parse_readings(
        HEADER + ",reference,instrument\n0,P1,0,0,EBX,5,um/m,1.5,level\n"
        "0,P5,0,0,EBX,2,um/m,,interferometer\n10,P1,0,0,EBX,6,um/m,1,level\n"
        "10,P5,0,0,EBX,3,um/m,,interferometer\n"))
    got = {(m.point_names[p], round(x * 1e3)): v * 1e6
           for p, x, v in zip(m.point, m.position, m.value)}
    assert got == pytest.approx({("P1", 0): 3.5, ("P1", 10): 5.0, ("P5", 0): 2.0, ("P5", 10): 3.0})


def test_ignored_and_unknown_columns_are_named_as_written(tmp_path):
    notes = []
    read_measurements(_write(tmp_path, HEADER + ",Temp_C\n0,P1,0,0,EBX,1,um/m,20.1\n"), notes=notes)
    assert notes and "column(s) Temp_C ignored" in notes[0]
    with pytest.raises(ValueError, match=r":1: unknown column 'Sigam', did you mean 'sigma'"):
        read_measurements(_write(tmp_path, HEADER + ",Sigam\n"))
