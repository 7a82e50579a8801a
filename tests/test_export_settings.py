"""The controller settings of the compensation exports (issue 39), from the command line and the
machine file's ``[export]`` table, each checked by a parser written from the controller's
documentation (tests/test_exports.py, and the ISG cross compensation list below), and the
straightness tables' statement of the slope a fit leaves undetermined.

Sources of the cross compensation parser: Beckhoff Information System, TF5200 TwinCAT 3 CNC
Axis compensation: "Cross compensation (kw.crosscomp.*)", "Example of a compensation value
list" (the Z axis' list with X as master), P-COMP-00001..00007 (header, unit 1 = 0.1 µm,
last_index, master_ax_nr, table[i].setpoint / .correction); ``#`` comment lines, ``/* */``
comments, ``:`` the example's elision. FANUC increment systems: Series 30i/31i/32i-A
Connection Manual (Function) B-63943EN-1/02, 1 "Axis control" (IS-B 0.001 mm, IS-C
0.0001 mm on a millimetre machine).
"""

import csv
import re

import numpy as np
import pytest
import test_exports as manual  # the parsers written from the manuals
from test_exports import ERR, SIDES, SIG, X0, X, residual_at_tool

from diffguide.cli import main
from diffguide.io.config import dump_config, load_config
from diffguide.studies.exports import FORMATS, ExportSpec, export_compensation
from diffguide.studies.exports.settings import merged, parse_option, spec_options

NUMBERS = {"X": 4, "Y": 7, "Z": 2}
NOTE = ("STRAIGHTNESS SLOPE NOT DETERMINED: test line", "second line of the note")


def parse_crosscomp(text):
    """An ISG axis compensation list with cross compensation (TF5200): 'name value' lines, '#'
    comment lines, '/* ... */' comments; kopf.achs_nr the list's (slave) axis,
    kw.crosscomp.master_ax_nr the master, unit 1 = 0.1 µm, table[i] for i = 0..last_index.
    Returns the header and the setpoints and corrections in m."""
    kv = {}
    for line in text.splitlines():
        line = re.sub(r"/\*.*?\*/", "", line).strip()
        if not line or line.startswith("#") or line == ":":
            continue
        key, value = line.split(None, 1)
        assert key not in kv, key
        kv[key] = value.strip()
    n = int(kv["kw.crosscomp.last_index"]) + 1
    assert kv["kw.crosscomp.unit"] == "1"  # metric, 0.1 µm
    unit = 1e-7
    setpoint = np.array([float(kv[f"kw.crosscomp.table[{i}].setpoint"]) for i in range(n)])
    correction = np.array([float(kv[f"kw.crosscomp.table[{i}].correction"]) for i in range(n)])
    assert np.all(np.diff(setpoint) > 0)
    if n > 1000:  # more than the default memory (P-COMP-00060, 1001 entries)
        assert int(kv["kw.crosscomp.max_points"]) > n - 1
    return {"slave": int(kv["kopf.achs_nr"]), "name": kv["kopf.log_achs_name"],
            "master": int(kv["kw.crosscomp.master_ax_nr"]),
            "setpoint": setpoint * unit, "correction": correction * unit}


def _files(fmt, **kw):
    return export_compensation(ExportSpec(fmt, **kw), X, ERR, SIG, x0_mm=X0, point="P5",
                               source="test", exx_includes_lead=True, straightness_note=NOTE)


def _comments(text, prefix):
    return [ln for ln in text.splitlines() if ln.lstrip().startswith(prefix)]


# ---------------------------------------------------------------- ISG cross compensation


@pytest.mark.parametrize("side", SIDES)
def test_isg_cross_lists_cancel_the_error_on_either_side(side):
    files = _files("isg-cross", axis_side=side, isg_axis_numbers=NUMBERS, file_name="k.lis")
    assert set(files) == {"", ".Y.lis", ".Z.lis", ".sigma.csv"}
    for axis, k in (("Y", 1), ("Z", 2)):
        t = parse_crosscomp(files[f".{axis}.lis"])
        assert (t["slave"], t["name"], t["master"]) == (NUMBERS[axis], axis, NUMBERS["X"])
        np.testing.assert_allclose(t["setpoint"] * 1e3, X + X0, atol=1e-7)  # mm
        left = residual_at_tool(ERR[:, k], t["correction"], side[axis])
        np.testing.assert_allclose(left, 0.0, atol=0.5e-7 + 1e-15)  # rounded to 0.1 µm
        assert np.max(np.abs(t["correction"])) > 1e-6
    overview = files[""]
    assert "k.Y.lis" in overview and "lr_param.crosscomp 1 (P-AXIS-00047)" in overview
    assert "UNCONFIRMED" in overview and "isg_cross_values = compensation" in overview


def test_isg_cross_error_convention_writes_minus_the_compensation():
    comp = parse_crosscomp(_files("isg-cross", axis_side="tool", isg_axis_numbers=NUMBERS)
                           [".Z.lis"])
    err = parse_crosscomp(_files("isg-cross", axis_side="tool", isg_axis_numbers=NUMBERS,
                                 isg_cross_values="error")[".Z.lis"])
    np.testing.assert_array_equal(err["correction"], -comp["correction"])
    np.testing.assert_allclose(err["correction"], ERR[:, 2] * -1, atol=0.5e-7 + 1e-15)


def test_isg_cross_needs_the_axis_numbers_and_the_side():
    with pytest.raises(ValueError, match=r"logical axis number of X, Y, Z is needed.*"
                                         r"--isg-axis-numbers"):
        _files("isg-cross", axis_side="tool")
    with pytest.raises(ValueError, match="logical axis number of Z"):
        _files("isg-cross", axis_side="tool", isg_axis_numbers={"X": 1, "Y": 2})
    with pytest.raises(ValueError, match="depends on which side"):
        _files("isg-cross", isg_axis_numbers=NUMBERS)


def test_isg_cross_of_a_long_table_reserves_its_memory():
    x = np.linspace(-500.0, 500.0, 1201)
    err = np.zeros((len(x), 6))
    err[:, 2] = 1e-6 * np.sin(x / 100.0)
    files = export_compensation(ExportSpec("isg-cross", axis_side="tool",
                                           isg_axis_numbers=NUMBERS), x, err)
    t = parse_crosscomp(files[".Z.lis"])  # checks max_points > last_index
    np.testing.assert_allclose(t["correction"], err[:, 2], atol=0.5e-7 + 1e-15)


# ---------------------------------------------------------------- ISG volumetric .lis


def test_isg_lis_assigns_the_axes_and_the_start_up_bounds_the_records():
    files = _files("isg", axis_side=SIDES[0], isg_axis_numbers=NUMBERS, file_name="vc.csv")
    lis = manual.parse_lis(files[".lis"])
    # P-VOLC-00001..3: the logical axis numbers of the ISO 230 X, Y, Z axes
    assert (lis["x"], lis["y"], lis["z"]) == ("4", "7", "2")
    boot = manual.parse_lis(files[".startup.lis"])
    assert boot["vol_comp[0].file_name"] == "vc.lis"  # P-STUP-00101: the configuration list
    records = len(manual.parse_isg_csv(files[""])["X"])
    assert int(boot["vol_comp[0].max_records"]) == records  # P-STUP-00100, default 0
    bigger = _files("isg", isg_axis_numbers=NUMBERS, max_records=5000)
    assert manual.parse_lis(bigger[".startup.lis"])["vol_comp[0].max_records"] == "5000"
    with pytest.raises(ValueError, match="max_records .*12 is less than the table's 13"):
        _files("isg", max_records=12)


def test_isg_lis_without_axis_numbers_says_what_to_set():
    files = _files("isg", axis_side="tool")
    lis = manual.parse_lis(files[".lis"])
    assert not {"x", "y", "z"} & set(lis)
    text = " ".join(_comments(files[".lis"], "#"))
    assert "logical axis number of X, Y, Z was not given" in text
    assert "--isg-axis-numbers" in text and "P-VOLC-00001/2/3" in text


# ---------------------------------------------------------------- FANUC, SINUMERIK, TNC


def test_fanuc_is_c_detection_unit():
    """An IS-C machine counts in 0.0001 mm: a table in IS-B units would be read 10x too
    small there. The IS-C sheet parses back to -EXX with the IS-C unit."""
    du = parse_option("fanuc_detection_unit", "IS-C")
    assert du == pytest.approx(1e-4)
    files = export_compensation(ExportSpec("fanuc", detection_unit_mm=du), X, ERR,
                                exx_includes_lead=True)
    pos, comp = manual.parse_fanuc(files[""], du=1e-4)
    i_ref = int(np.argmin(np.abs(X)))
    np.testing.assert_allclose(comp, -(ERR[:, 0] - ERR[i_ref, 0]), atol=0.05e-6 + 1e-12)
    assert "detection unit 0.0001 mm (IS-C with CMR 1" in files[""]
    p = {int(m[1]): int(m[2]) for m in re.finditer(r"^# (36\d\d) = (-?\d+)", files[""], re.M)}
    assert p[3624] == round(50.0 / 1e-4)  # the interval, 50 mm in IS-C units


def test_heidenhain_value_convention_is_stated_and_settable():
    default = _files("heidenhain", axis_side="tool")
    flipped = _files("heidenhain", axis_side="tool", heidenhain_values="error")
    _, a = manual.parse_tnc_table(default[""])
    _, b = manual.parse_tnc_table(flipped[""])
    for axis in ("X", "Y", "Z"):
        np.testing.assert_allclose(np.array(b[axis], float), -np.array(a[axis], float))
    assert "heidenhain_values = compensation); UNCONFIRMED" in default[".note.txt"]
    assert "heidenhain_values = error); UNCONFIRMED" in flipped[".note.txt"]
    assert "--heidenhain-values compensation" in flipped[".note.txt"]  # how to go back


@pytest.mark.parametrize("key, text, message", [
    ("cec_axis_names", "X=X1,Y=Y 1", "--cec-axis-names: Y: 'Y 1' is not allowed"),
    ("cec_axis_names", "X=X1,Y=X1", "the axes must be distinct"),
    ("cec_axis_names", "Q=Q1", "--cec-axis-names: {'Q': 'Q1'} is not allowed"),
    ("cec_axis_names", "X=AX1)\nM30", "--cec-axis-names: X: 'AX1)\\nM30' is not allowed"),
    ("fanuc_detection_unit", "IS-F", "--fanuc-detection-unit: 'IS-F' is not allowed; allowed: "
     "IS-A, IS-B, IS-C, IS-D, IS-E or a length in mm"),
    ("fanuc_detection_unit", "0.5", "--fanuc-detection-unit: '0.5' is not allowed"),
    ("isg_axis_numbers", "X=0,Y=1", "--isg-axis-numbers: X: 0 is not allowed; allowed: "
     "X=N,Y=N,Z=N, integers in [1, 65535]"),
    ("isg_axis_numbers", "X=1,Y=1", "the axes must be distinct"),
    ("isg_max_records", "-3", "--isg-max-records: '-3' is not allowed"),
    ("heidenhain_values", "minus", "--heidenhain-values: 'minus' is not allowed; allowed: "
     "compensation or error"),
])
def test_bad_settings_are_refused_naming_the_option(key, text, message):
    with pytest.raises(ValueError) as info:
        parse_option(key, text)
    assert message in str(info.value)


def test_machine_file_export_table_round_trips_and_refuses_bad_keys(tmp_path):
    good = tmp_path / "m.toml"
    good.write_text('[export]\ncec_axis_names = {X = "X1", Z = "Z1"}\n'
                    'fanuc_detection_unit = "IS-C"\nisg_axis_numbers = {X = 1, Y = 2, Z = 3}\n')
    cfg = load_config(good)
    s = merged(cfg["export"], {"cec_axis_names": parse_option("cec_axis_names", "Y=Y9")})
    assert s["cec_axis_names"] == {"X": "X1", "Y": "Y9", "Z": "Z1"}  # CLI over file over default
    assert s["fanuc_detection_unit"] == pytest.approx(1e-4)
    assert ExportSpec("siemens-cec", **spec_options(s)).axis_names["Z"] == "Z1"
    again = tmp_path / "again.toml"
    again.write_text(dump_config(cfg))
    assert load_config(again)["export"] == cfg["export"]
    # the default file's commented [export] lines, uncommented, are the stated defaults
    text = dump_config(cfg | {"export": {}})
    head, table = text.split("[export]")
    live = [ln[2:].split("  #")[0] for ln in table.splitlines()[1:] if ln.startswith("# ")]
    defaults = tmp_path / "defaults.toml"
    defaults.write_text(head + "[export]\n" + "\n".join(live) + "\n")
    stated = load_config(defaults)["export"]
    for key, value in merged().items():
        if value is not None:
            assert stated[key] == value, key
    for body, message in [
        ("cec_axis_names = {X = \"X1\\nM30\"}", "key 'export.cec_axis_names': X:"),
        ("fanuc_detection_unit = 0.02", "key 'export.fanuc_detection_unit': 0.02 is not allowed"),
        ("isg_max_records = 0", "key 'export.isg_max_records': 0 is not allowed"),
        ("axis_names = {X = \"X1\"}", "key 'export.axis_names' is unknown; allowed: "
         "cec_axis_names"),
    ]:
        bad = tmp_path / "bad.toml"
        bad.write_text(f"[export]\n{body}\n")
        with pytest.raises(ValueError, match=re.escape(f"{bad}: {message}")):
            load_config(bad)


# ---------------------------------------------------------------- the common slope


def test_every_straightness_file_states_the_undetermined_slope():
    for fmt in FORMATS:
        kw = dict(axis_side="tool", isg_axis_numbers=NUMBERS) if fmt != "fanuc" else {}
        files = _files(fmt, **kw)
        for suffix, text in files.items():
            if suffix in (".lis", ".startup.lis", ".cma") or (fmt, suffix) == ("heidenhain", ""):
                continue  # configuration, not values; a TNC table has no comments (.note.txt)
            holds_straightness = fmt != "fanuc"
            assert (NOTE[0] in text) == holds_straightness, (fmt, suffix)
    _, e, _ = manual.parse_csv(_files("csv")[""])  # the note is in comments: the table intact
    np.testing.assert_allclose(e, ERR, atol=5e-12)


def test_the_note_quotes_the_alignment_slopes_with_their_posterior_sigma():
    """A fit with two straightness channels: the note quotes each channel's alignment slope
    with the σ from the last entries of the posterior covariance (the alignment slopes close
    v = (c, q, lead, alignment)), and says which planes carry the undetermined slope."""
    from types import SimpleNamespace

    from diffguide.studies.compensation import common_slope_note

    cov = np.diag([4e-12, 1e-12, 9e-14, 2.5e-13])  # rad² for the two alignment slopes
    fit = SimpleNamespace(fix_slope=(True, False), alignment=np.array([0.52e-6, -1.2e-6]),
                          posterior_cov=cov)
    note = " ".join(common_slope_note(fit, np.linspace(-250.0, 250.0, 11), x0_mm=400.0))
    assert "EZX (vertical plane) carry" in note and "EYX" not in note.split("carry")[0]
    assert "+0.52 +/- 0.3, -1.2 +/- 0.5 um/m" in note  # sqrt(9e-14), sqrt(2.5e-13) rad
    assert "a*(X - 400 mm)" in note and "1 um/m of it is 0.25 um" in note
    assert common_slope_note(SimpleNamespace(fix_slope=(False, False), alignment=np.zeros(0),
                                             posterior_cov=np.zeros((0, 0))), [0.0, 1.0]) == ()


# ---------------------------------------------------------------- end to end


def test_simulate_takes_the_settings_from_the_machine_file_and_the_command_line(tmp_path):
    """The issue's reproduction: CEC axis names were fixed at AX1-AX3. Here the machine file
    names Y and Z, the command line X; a FANUC IS-C sheet and an ISG cross list come from
    the same run's options."""
    cfg = tmp_path / "m.toml"
    cfg.write_text('[export]\ncec_axis_names = {X = "X9", Y = "Y1", Z = "Z1"}\n'
                   "isg_axis_numbers = {X = 1, Y = 2, Z = 3}\n")
    out = tmp_path / "e.csv"
    common = ["simulate", "--config", str(cfg), "--variant", "2", "--mesh", "6x3",
              "--positions", "-300:300:5", "--out", str(out), "--machine-x0-mm", "400",
              "--axis-side", "Y=workpiece,Z=tool", "--quiet", "--export-compensation"]
    cec = tmp_path / "c.mpf"
    assert main([*common, str(cec), "--format", "siemens-cec", "--cec-axis-names",
                 "X=MX"]) == 0
    tables, _ = manual.parse_cec(cec.read_text())
    assert {(t["input"], t["output"]) for t in tables.values()} == {("(MX)", "(Y1)"),
                                                                    ("(MX)", "(Z1)")}
    rows = [r for r in csv.DictReader(out.open()) if r["point"] == "P5"]
    e = {n: np.array([float(r[f"{n}_um"]) for r in rows]) * 1e-6 for n in ("EXX", "EZX")}
    fan = tmp_path / "f.txt"
    assert main([*common, str(fan), "--format", "fanuc", "--fanuc-detection-unit",
                 "IS-C"]) == 0
    pos, comp = manual.parse_fanuc(fan.read_text(), du=1e-4)
    np.testing.assert_allclose(pos, [100, 250, 400, 550, 700], atol=1e-9)
    np.testing.assert_allclose(comp, -(e["EXX"] - e["EXX"][2]), atol=0.05e-6 + 1e-11)
    cross = tmp_path / "k.txt"
    assert main([*common, str(cross), "--format", "isg-cross"]) == 0
    t = parse_crosscomp((tmp_path / "k.Z.lis").read_text())
    assert (t["slave"], t["master"]) == (3, 1)
    np.testing.assert_allclose(t["correction"], e["EZX"], atol=0.5e-7 + 1e-11)  # Z: tool side


@pytest.mark.parametrize("args, message", [
    (["--format", "isg-cross", "--axis-side", "tool"], "--isg-axis-numbers"),
    (["--format", "isg-cross", "--isg-axis-numbers", "X=1,Y=2,Z=3"],
     "--format isg-cross needs --axis-side"),
    (["--format", "siemens-cec", "--axis-side", "tool", "--cec-axis-names", "X=A B"],
     "--cec-axis-names: X: 'A B' is not allowed"),
    (["--format", "isg", "--isg-max-records", "3"], "is less than the table's 5 records"),
])
def test_simulate_refuses_bad_settings_before_any_work(tmp_path, capsys, args, message):
    out = tmp_path / "e.csv"
    assert main(["simulate", "--positions", "-300:300:5", "--out", str(out), "--quiet",
                 "--export-compensation", str(tmp_path / "c.txt"), *args]) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_cli_formats_are_the_exporters():
    from diffguide.cli._export_options import FORMATS as CLI_FORMATS

    assert CLI_FORMATS == FORMATS
