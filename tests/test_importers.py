"""Measurement importers: every supported layout of the bundled data gives the canonical file's
merged data; separators, decimal commas, units, directions, machine coordinates, differential
level pairs and extra columns checked against hand-computed values; unknown layouts fail with
one line."""

import math
from pathlib import Path

import numpy as np
import pytest

from diffguide.cli import main
from diffguide.cli.import_ import add_parser
from diffguide.io.importers import detect_layout, import_readings, merged_table, read_any
from diffguide.io.measurements import read_measurements

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "data"
CANONICAL = DATA / "majda2012_measurements.csv"


@pytest.fixture(scope="module")
def canonical():
    return merged_table(read_measurements(CANONICAL))


@pytest.mark.parametrize(
    "name, x0_mm, layout",
    [
        ("majda2012_measurements_wide.csv", None, "wide"),  # x0: the file's x0_mm line (400 mm)
        ("majda2012_measurements_semicolon.csv", 400.0, "long"),
    ],
)
def test_example_layouts_give_the_canonical_merged_data(canonical, name, x0_mm, layout):
    text = (DATA / name).read_text(encoding="utf-8")
    assert detect_layout(text, name) == layout
    notes = []
    got = merged_table(read_any(DATA / name, "auto", x0_mm, notes))
    assert got.shape == canonical.shape
    # positions (mm), point and quantity exactly; values and σ to the printed 0.001 µm/m
    np.testing.assert_allclose(got[:, :3], canonical[:, :3], atol=1e-9)
    np.testing.assert_allclose(got[:, 3:], canonical[:, 3:], atol=5e-4)
    assert any("temperature" in n.lower() for n in notes)


def _write(tmp_path, text, name="m.csv"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_long_semicolon_decimal_comma_units_directions(tmp_path):
    text = (
        "# export\n"
        "position_mm;point;x_mm;y_mm;quantity;value;unit;direction;temp_C\n"
        "1000,5;A;10;-20,5;EXX;250;nm;positive;20,1\n"
        "1000,5;A;10;-20,5;EXX;350;nm;negative;20,1\n"
        "1000,5;A;10;-20,5;EZX;0,0001;in;+;20,1\n"
        "1000,5;A;10;-20,5;EBX;0,012;mm/m;-;20,1\n"
        "1000,5;A;10;-20,5;EAX;0,5;arcmin;fwd;20,1\n"
        "1000,5;A;10;-20,5;ECX;0,001;deg;up;20,1\n"
    )
    notes = []
    rs = import_readings(_write(tmp_path, text), x0_mm=1000.0, notes=notes)
    assert [n for n in notes if "temp_C ignored" in n]  # as written
    assert math.isclose(rs[0].position, 0.5e-3)  # 1000.5 mm - x0
    assert rs[0].xy == (10e-3, -20.5e-3)
    assert (rs[0].value, rs[0].direction) == (pytest.approx(250e-9), "forward")
    assert (rs[1].value, rs[1].direction) == (pytest.approx(350e-9), "backward")
    assert rs[2].value == pytest.approx(2.54e-6)  # 0.0001 in = 2.54 µm
    assert rs[3].value == pytest.approx(12e-6) and rs[3].direction == "backward"
    assert rs[4].value == pytest.approx(0.5 / 60 * math.pi / 180)
    assert rs[5].value == pytest.approx(0.001 * math.pi / 180)
    m = read_any(_write(tmp_path, text), x0_mm=1000.0)
    exx = m.value[m.quantity == 0][0]
    assert exx == pytest.approx(300e-9)  # mean of the forward and backward readings


def test_tab_separated_and_unit_spellings(tmp_path):
    text = "position_mm\tpoint\tx_mm\ty_mm\tquantity\tvalue\tunit\n0\tA\t0\t0\tEBX\t1,5\tUM/M\n"
    (r,) = import_readings(_write(tmp_path, text))
    assert r.value == pytest.approx(1.5e-6)


WIDE = """# laser report
point;P9
x_mm;100
y_mm;-50
quantity;EBX
unit;µm/m
instrument;level
target_mm;run1_fwd;run1_fwd_ref;run1_bwd;run1_bwd_ref;run2_fwd;run2_fwd_ref;run2_bwd;run2_bwd_ref;T
100;5;1;6;1;7;2;8;2;20
300;1;0,5;2,5;0,5;3;1;4;1;20
"""


def test_wide_differential_pair_and_default_x0(tmp_path):
    notes = []
    m = read_any(_write(tmp_path, WIDE), x0_mm="middle", notes=notes)
    assert m.point_names == ("P9",)
    np.testing.assert_allclose(m.points_xy, [[0.1, -0.05]])
    # x0 = middle of 100 and 300 mm
    np.testing.assert_allclose(np.sort(m.position), [-0.1, 0.1])
    i = np.argsort(m.position)
    # measuring - reference: at 100 mm fwd 4, 5; bwd 5, 6 -> mean(4.5, 5.5) = 5.0
    #                        at 300 mm fwd 0.5, 2; bwd 2, 3 -> mean(1.25, 2.5) = 1.875
    np.testing.assert_allclose(m.value[i] * 1e6, [5.0, 1.875])
    np.testing.assert_allclose(m.reversal[i] * 1e6, [4.5 - 5.5, 1.25 - 2.5])
    assert any("'T'" in n or " T " in n or "T ignored" in n for n in notes)
    m2 = read_any(_write(tmp_path, WIDE))  # the default x0 is 0 in every layout
    np.testing.assert_allclose(np.sort(m2.position), [0.1, 0.3])
    m3 = read_any(_write(tmp_path, "x0_mm;250\n" + WIDE))  # the file's own x0
    np.testing.assert_allclose(np.sort(m3.position), [-0.15, 0.05])


def test_wide_resolution_line_survives_import(tmp_path):
    # a level showing whole arcseconds; the canonical file (6 decimals of µm/m) keeps the step
    from diffguide.io.importers import format_long, import_readings
    from diffguide.io.measurements import parse_readings

    text = ("point;P1\nx_mm;0\ny_mm;0\nquantity;EBX\nunit;arcsec\nresolution;0.5\n"
            "target_mm;run1_fwd;run1_bwd\n0;1.5;2\n100;-1;0.5\n")
    readings = import_readings(_write(tmp_path, text), "wide")
    step = 0.5 * math.pi / 648000  # rad
    assert [r.resolution for r in readings] == pytest.approx([step / math.sqrt(12)] * 4)
    again = parse_readings(format_long(readings))
    assert [r.resolution for r in again] == pytest.approx([step / math.sqrt(12)] * 4, rel=1e-5)


@pytest.mark.parametrize(
    "text, line, expected",
    [
        ("hello,world\n1,2\n", 1, "unknown layout: expected a long header"),
        (
            "# c\npoint;P1\nquantity;EBX\nunit;um/m\ntarget_mm;run1\n0;1\n",
            5,
            "without metadata line(s) x_mm, y_mm",
        ),
        (
            "point;P1\nx_mm;0\ny_mm;0\nquantity;EBX\nunit;um/m\ntarget_mm;speed\n",
            6,
            "without run columns",
        ),
        (
            "point;P1\nx_mm;0\ny_mm;0\nquantity;EBX\nunit;um/m\ntarget_mm;run1_fwd\n0;abc\n",
            7,
            "column 'run1_fwd': not a number",
        ),
        (
            "point;P1\nx_mm;0\ny_mm;0\nquantity;EBX\nunit;um/m\ntarget_mm;run1_fwd_ref\n0;1\n",
            6,
            "without its measuring column",
        ),
        ("position_mm;point;x_mm;y_mm;quantity;value;unit;sigam\n", 1, "did you mean 'sigma'"),
    ],
)
def test_unknown_layouts_fail_with_one_line(tmp_path, text, line, expected):
    p = _write(tmp_path, text)
    with pytest.raises(ValueError) as err:
        read_any(p)
    msg = str(err.value)
    assert msg.startswith(f"{p}:{line}: ") and expected in msg and "\n" not in msg


def test_import_command_writes_the_canonical_file(tmp_path, canonical, capsys):
    import argparse

    sub = argparse.ArgumentParser().add_subparsers()
    add_parser(sub)  # registered as 'import' (cli/__init__.py lists the commands)
    out = tmp_path / "canon.csv"
    args = sub.choices["import"].parse_args(
        [str(DATA / "majda2012_measurements_wide.csv"), "--out", str(out)]
    )
    assert args.func(args) == 0
    assert "temperature_C ignored" in capsys.readouterr().err
    got = merged_table(read_measurements(out))
    np.testing.assert_allclose(got[:, :3], canonical[:, :3], atol=1e-9)
    np.testing.assert_allclose(got[:, 3:], canonical[:, 3:], atol=5e-4)


def test_fit_refuses_an_unknown_layout(tmp_path):
    bad = _write(tmp_path, "hello;world\n")
    assert main(["fit", "--measurements", str(bad), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert not (tmp_path / "o").exists()


def test_one_csv_reader_for_every_file(tmp_path):
    """The rules of diffguide.io.csvtable: the bundled truth file (a '#' comment first) reads;
    ';' with decimal commas, an extra column (noted) and a typo (refused) behave as for the
    measurements."""
    from diffguide.io.csvtable import number, read_table

    cols = ("rail", "s_mm", "vertical_um", "horizontal_um")
    rows = read_table(DATA / "majda2012_truth.csv", cols)
    assert rows[0][0] == 3 and rows[0][1]["rail"] == "1"  # line numbers of the file
    notes = []
    p = _write(tmp_path, "# c\nRail;s_mm;vertical_um;horizontal_um;T_C\n1;-2,5;0,75;1;20,5\n")
    ((line, row),) = read_table(p, cols, notes=notes)
    assert line == 3 and number(row, "s_mm", str(p), line, "mm") == -2.5
    assert number(row, "vertical_um", str(p), line, "µm") == 0.75 and "T_C ignored" in notes[0]
    with pytest.raises(ValueError, match=r":1: unknown column 'vertical_mu', did you mean"):
        read_table(_write(tmp_path, "rail,s_mm,vertical_mu,horizontal_um\n"), cols)
    with pytest.raises(ValueError, match=r":2: field 's_mm': not a finite number"):
        number({"s_mm": "x"}, "s_mm", "f.csv", 2, "mm")


@pytest.mark.parametrize(
    "cells, column",
    [("0;12", "run1_fwd"), ("0;0,5;-11", "run1_fwd_ref")],  # mm/m: ±10 mm/m allowed
)
def test_wide_implausible_reading_names_its_column(tmp_path, cells, column):
    ref = ";run1_fwd_ref" if cells.count(";") == 2 else ""
    text = f"point;P1\nx_mm;0\ny_mm;0\nquantity;EBX\nunit;mm/m\ntarget_mm;run1_fwd{ref}\n{cells}\n"
    p = _write(tmp_path, text)
    with pytest.raises(ValueError) as err:
        read_any(p)
    msg = str(err.value)
    assert msg.startswith(f"{p}:7: column '{column}': not a plausible reading")
    assert "(allowed -10 to 10 mm/m" in msg


def test_wide_repeated_target_row_is_noted(tmp_path):
    text = ("point;P1\nx_mm;0\ny_mm;0\nquantity;EBX\nunit;µm/m\ntarget_mm;run1_fwd;run1_bwd\n"
            "0;1;2\n10;3;4\n10;5;6\n")
    notes = []
    m = read_any(_write(tmp_path, text), x0_mm=0.0, notes=notes)
    (note,) = [n for n in notes if "repeat" in n]
    assert "2 reading(s) repeat" in note and "line(s) 9 (as 8): merged" in note
    # target 10 mm: forward (3 + 5)/2, backward (4 + 6)/2
    assert m.value[np.argmax(m.position)] == pytest.approx(4.5e-6)
