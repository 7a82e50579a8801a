"""Compensation exports, each parsed back by a parser written here from the controller's own
documented syntax (not from diffguide's writer), and checked against the errors that went in:
values, units, and signs — a compensation on an axis must cancel the error at the tool whether
that axis carries the tool or the workpiece.

Sources of the parsers (the same as docs/compensation-exports.md): SINUMERIK Extended Functions
K3 (03/2013) 4.4.3; Beckhoff TF5280 "ISG CSV format", "Units of measure", P-VOLC-00007/8;
HEIDENHAIN MANUALplus 620 Technical Manual (01/2012) 6.10.3; FANUC B-63980EN/01 and A-77810E
(parameters 3620-3624).
"""

import csv
import io
import re
from pathlib import Path

import numpy as np
import pytest

from diffguide.cli import main
from diffguide.studies.exports import EXPERIMENTAL, FORMATS, ExportSpec, export_compensation

X = np.linspace(-300.0, 300.0, 13)  # mm, equidistant, includes 0
X0 = 500.0
NAMES = ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX")
# closed-form errors of the model (m, rad), distinct per quantity, zero at x = 0
_S = X / 300.0
MODEL = np.stack([3e-6 * _S, -2e-6 * _S**2, 1.5e-6 * np.sin(3 * _S), 4e-6 * _S,
                  -7e-6 * _S**3, 2.5e-6 * np.sin(2 * _S)], axis=1)
LEAD = 8e-6 * _S + 1e-6 * _S**2  # a lead error of the screw (m), zero at x = 0
ERR = MODEL.copy()
ERR[:, 0] += LEAD  # EXX as a fit predicts it: the model's EXX plus the fitted lead error
SIG = np.abs(ERR) * 0.1 + 0.2e-6
SIDES = [{"Y": "workpiece", "Z": "tool"}, {"Y": "tool", "Z": "workpiece"}]


def residual_at_tool(error, comp, side):
    """What is left of the error between tool and workpiece once the axis on ``side`` has
    moved its part by ``comp`` along its positive direction: the table (workpiece) is off by
    ``error``; a workpiece-side axis moves the workpiece, a tool-side axis the tool."""
    workpiece = error + (comp if side == "workpiece" else 0.0)
    tool = comp if side == "tool" else 0.0
    return tool - workpiece


def _files(fmt, lead=True, **kw):
    return export_compensation(ExportSpec(fmt, **kw), X, ERR, SIG, x0_mm=X0, point="P5",
                               source="test", exx_includes_lead=lead)


# ---------------------------------------------------------------- parsers from the manuals


def parse_csv(text):
    rows = list(csv.DictReader(ln for ln in io.StringIO(text) if not ln.startswith("#")))
    units = ("um",) * 3 + ("urad",) * 3

    def col(name):
        return np.array([float(r[name]) if r[name] else np.nan for r in rows])

    e = np.stack([col(f"{n}_{u}") for n, u in zip(NAMES, units)], axis=1) * 1e-6
    s = np.stack([col(f"{n}_sigma_{u}") for n, u in zip(NAMES, units)], axis=1) * 1e-6
    return col("X_machine_mm"), e, s


def parse_isg_csv(text):
    """ISG CSV (TF5280): '//' starts a line comment, '#' a file break (a new header), the
    header names the argument and the parameters, records are whitespace-separated; parameter
    values in mm and rad, the argument X in mm. Returns {name: column} of the first block."""
    blocks, header = [], None
    for line in text.splitlines():
        line = line.split("//")[0].strip()
        if line.startswith("#"):
            header = None
            continue
        if not line:
            continue
        if header is None:
            header = line.split()
            blocks.append({h: [] for h in header})
            continue
        for h, v in zip(header, line.split(), strict=True):
            blocks[-1][h].append(float(v))
    assert len(blocks) == 1
    return {h: np.array(v) for h, v in blocks[0].items()}


def parse_lis(text):
    """An ISG list file: 'name value' lines, '#' comments."""
    out = {}
    for line in text.splitlines():
        line = line.split("#")[0].strip()
        if line:
            key, value = line.split(None, 1)
            out[key] = value.strip()
    return out


def parse_cec(text):
    """SINUMERIK CEC init program (K3 4.4.3): %_N_NC_CEC_INI, CHANDATA(1), ';' comments,
    $AN_CEC[t,N] (mm) and the table parameters, M17. Returns {t: table} with the positions of
    the basic axis MIN + N*STEP, the values, the axes and the comments."""
    raw = text.splitlines()
    comments = [ln.split(";", 1)[1] for ln in raw if ";" in ln]
    lines = [ln.split(";")[0].strip() for ln in raw]
    lines = [ln for ln in lines if ln]
    assert lines[:2] == ["%_N_NC_CEC_INI", "CHANDATA(1)"] and lines[-1] == "M17"
    values, params = {}, {}
    for ln in lines[2:-1]:
        m = re.fullmatch(r"\$AN_CEC\[(\d+),(\d+)\]=(-?\d+\.?\d*)", ln)
        if m:
            values.setdefault(int(m[1]), {})[int(m[2])] = float(m[3])
            continue
        m = re.fullmatch(r"\$AN_CEC_(INPUT_AXIS|OUTPUT_AXIS|STEP|MIN|MAX|DIRECTION|"
                         r"MULT_BY_TABLE|IS_MODULO)\[(\d+)\]=(.+)", ln)
        assert m, ln
        params[(m[1], int(m[2]))] = m[3]
    tables = {}
    for t, vals in values.items():
        n = len(vals)
        assert sorted(vals) == list(range(n))
        step, lo, hi = (float(params[(k, t)]) for k in ("STEP", "MIN", "MAX"))
        pos = lo + step * np.arange(n)
        assert pos[-1] == pytest.approx(hi, abs=1e-6)  # MAX is the last point's position
        assert (params[("DIRECTION", t)], params[("MULT_BY_TABLE", t)],
                params[("IS_MODULO", t)]) == ("0", "0", "0")
        tables[t] = {"pos": pos, "comp": np.array([vals[i] for i in range(n)]) * 1e-3,
                     "input": params[("INPUT_AXIS", t)], "output": params[("OUTPUT_AXIS", t)]}
    return tables, comments


def parse_tnc_table(text):
    """A TNC table: 'BEGIN NAME.EXT [MM]', the column names, one row per line, '[END]'."""
    lines = text.splitlines()
    m = re.fullmatch(r"BEGIN (\S+)(?: (MM|INCH))?", lines[0])
    assert m and lines[-1] == "[END]"
    cols = lines[1].split()
    rows = [ln.split() for ln in lines[2:-1]]
    assert all(len(r) == len(cols) for r in rows)
    return m[1], {c: [r[i] for r in rows] for i, c in enumerate(cols)}


def parse_fanuc(text, du=1e-3):
    """Pitch error compensation of one axis from parameters 3620 (reference point number),
    3621/3622 (farthest points), 3623 (magnification), 3624 (interval, detection units): point
    n at X_ref + (n - n_ref)*interval, its value the increment from point n-1 to n, zero
    compensation at the reference. Returns (positions mm, absolute compensation m)."""
    p = {int(m[1]): int(m[2]) for m in re.finditer(r"^# (36\d\d) = (-?\d+)", text, re.M)}
    x_ref = float(re.search(r"REFERENCE POINT X = (-?[\d.]+) MM", text)[1])
    data = {int(a): int(c) for a, _, c in
            (ln.split() for ln in text.splitlines() if ln and not ln.startswith("#"))}
    n_ref, lo, hi, mag, interval = p[3620], p[3621], p[3622], p[3623], p[3624]
    assert sorted(data) == list(range(lo, hi + 1)) and lo <= n_ref <= hi
    numbers = np.arange(lo, hi + 1)
    cum = np.cumsum([data[n] for n in numbers])
    absolute = (cum - cum[n_ref - lo]) * mag * du * 1e-3  # m, zero at the reference point
    return x_ref + (numbers - n_ref) * interval * du, absolute


# ---------------------------------------------------------------- the formats


def test_csv_errors_sigma_and_the_lead():
    (text,) = _files("csv").values()
    X_m, e, s = parse_csv(text)
    np.testing.assert_allclose(X_m, X + X0, atol=5e-5)
    np.testing.assert_allclose(e, ERR, atol=5e-12)  # 5 decimals of µm / µrad
    np.testing.assert_allclose(e[:, 0], MODEL[:, 0] + LEAD, atol=5e-12)  # EXX = model + lead
    np.testing.assert_allclose(s, SIG, atol=5e-12)
    assert "# EXX includes the fitted lead error" in text


@pytest.mark.parametrize("side", SIDES)
def test_isg_errors_mm_rad_and_workpiece_axes(side):
    files = _files("isg", axis_side=side, file_name="comp.csv")
    d = parse_isg_csv(files[""])
    assert list(d) == ["X", *NAMES]
    np.testing.assert_allclose(d["X"], X + X0, atol=5e-5)
    np.testing.assert_allclose(np.stack([d[n] for n in NAMES[:3]], 1), ERR[:, :3] * 1e3,
                               atol=5e-10)  # mm
    np.testing.assert_allclose(np.stack([d[n] for n in NAMES[3:]], 1), ERR[:, 3:],
                               atol=5e-13)  # rad
    lis = parse_lis(files[".lis"])
    # the chain runs from the workpiece: X (the table) first, then the workpiece-side axes
    wp = 1 + sum(s == "workpiece" for s in side.values())
    assert int(lis["workpiece_axes"]) == wp
    assert lis["chain"][0] == "X" and set(lis["chain"][1:wp]) == {
        a for a, s in side.items() if s == "workpiece"}
    assert lis["file[0]"] == "comp.csv" and lis["file_format[0]"] == "ISG_CSV"
    assert f"workpiece_axes   {wp}" in files[""]  # stated in the table's own header too


def test_isg_without_sides_says_what_is_missing():
    files = _files("isg")
    assert "workpiece_axes" not in parse_lis(files[".lis"])
    assert "side of Y and/or Z was not given" in files[".lis"]


@pytest.mark.parametrize("side", SIDES)
def test_siemens_cec_cancels_the_error_on_either_side(side):
    files = _files("siemens-cec", axis_side=side)
    tables, comments = parse_cec(files[""])
    by_axis = {t["output"]: t for t in tables.values()}
    assert set(by_axis) == {"(AX2)", "(AX3)"}
    for axis, k in (("Y", 1), ("Z", 2)):
        t = by_axis["(AX2)" if axis == "Y" else "(AX3)"]
        assert t["input"] == "(AX1)"
        np.testing.assert_allclose(t["pos"], X + X0, atol=1e-6)
        left = residual_at_tool(ERR[:, k], t["comp"], side[axis])
        np.testing.assert_allclose(left, 0.0, atol=5e-10)  # 6 decimals of mm
        assert np.max(np.abs(t["comp"])) > 1e-7  # not trivially zero
    text = "\n".join(comments)
    n = len(X)
    for t in tables:
        m = re.search(rf"MD18342 \$MN_MM_CEC_MAX_POINTS\[{t}\] >= (\d+)", text)
        assert m and int(m[1]) >= n
        assert f"SD41300 $SN_CEC_TABLE_ENABLE[{t}] = 1" in text
    assert "MD32710 $MA_CEC_ENABLE" in text and "NEWCONF" in text and "power on" in text
    assert "EXX (pitch) is not in this program" in text


def test_siemens_cec_refuses_without_the_side():
    with pytest.raises(ValueError, match="depends on which side of the kinematic chain"):
        export_compensation("siemens-cec", X, ERR)


@pytest.mark.parametrize("side", SIDES)
def test_heidenhain_com_and_cma(side):
    files = _files("heidenhain", axis_side=side, table_name="comp")
    assert set(files) == {"", ".cma", ".note.txt", ".sigma.csv"}
    name, com = parse_tnc_table(files[""])
    assert name == "COMP.COM" and list(com) == ["NR", "AXISPOS", "X", "Y", "Z"]
    np.testing.assert_allclose(np.array(com["AXISPOS"], float), X + X0, atol=5e-5)
    cma_name, cma = parse_tnc_table(files[".cma"])
    assert cma_name == "CONFIG.CMA"
    active = [i for i, a in enumerate(cma["ACTIVE"]) if a == "*"]
    # [axis of a .COM column] = F(axis of the .CMA column the .COM is entered in): X
    assert len(active) == 1 and cma["X"][active[0]] == "COMP.COM"
    sides = {"X": "workpiece", **side}  # X carries the table, so the workpiece
    for axis, k in (("X", 0), ("Y", 1), ("Z", 2)):
        comp = np.array(com[axis], float) * 1e-3
        np.testing.assert_allclose(residual_at_tool(ERR[:, k], comp, sides[axis]), 0.0,
                                   atol=5e-11)
    note = files[".note.txt"]
    assert "EXPERIMENTAL" in note and "angles EAX, EBX, ECX are not written" in note
    assert "EXX includes the fitted lead error" in note


def test_heidenhain_pitch_is_model_plus_lead():
    _, com = parse_tnc_table(_files("heidenhain")[""])
    assert list(com) == ["NR", "AXISPOS", "X"]  # no side given: no cross-axis column
    np.testing.assert_allclose(-np.array(com["X"], float) * 1e-3, MODEL[:, 0] + LEAD,
                               atol=5e-11)


@pytest.mark.parametrize("x0, ref", [(X0, None), (0.0, 100.0)])
def test_fanuc_pitch_from_parameters_3620_to_3624(x0, ref):
    files = export_compensation(ExportSpec("fanuc", reference_mm=ref, first_number=20), X, ERR,
                                x0_mm=x0, exx_includes_lead=True)
    pos, comp = parse_fanuc(files[""])
    np.testing.assert_allclose(pos, X + x0, atol=1e-9)
    x_ref = x0 if ref is None else ref
    i_ref = int(np.argmin(np.abs(X + x0 - x_ref)))
    expected = -(ERR[:, 0] - ERR[i_ref, 0])  # -EXX, zero at the reference position
    # 1 µm units; the rounding does not accumulate: each absolute value within half a unit
    np.testing.assert_allclose(comp, expected, atol=0.5e-6 + 1e-12)
    text = files[""]
    assert "EXPERIMENTAL" in text and "straightness (EYX, EZX) not written" in text
    assert "EXX includes the fitted lead error" in text


def test_fanuc_magnification_keeps_values_in_range():
    big = ERR.copy()
    big[:, 0] = 2e-3 * _S  # 2 mm over the stroke: 333 µm per point
    files = export_compensation("fanuc", X, big, exx_includes_lead=False)
    pos, comp = parse_fanuc(files[""])
    values = [int(ln.split()[2]) for ln in files[""].splitlines() if not ln.startswith("#")]
    assert max(abs(v) for v in values) <= 127
    np.testing.assert_allclose(comp, -big[:, 0], atol=0.5e-6 * 3 + 1e-12)
    assert "EXX has no lead error" in files[""]


def test_unknown_lead_leaves_exx_out_and_refuses_pitch():
    reason = "whether it includes the lead error of the drive is unknown"
    with pytest.raises(ValueError, match=reason):
        export_compensation("fanuc", X, ERR)
    csv_text = export_compensation("csv", X, ERR, SIG)[""]
    _, e, s = parse_csv(csv_text)
    assert np.isnan(e[:, 0]).all() and np.isnan(s[:, 0]).all() and reason in csv_text
    np.testing.assert_allclose(e[:, 1:], ERR[:, 1:], atol=5e-12)
    isg_text = export_compensation("isg", X, ERR)[""]
    assert "EXX" not in parse_isg_csv(isg_text) and reason in isg_text
    files = export_compensation("heidenhain", X, ERR, axis_side="tool")
    assert list(parse_tnc_table(files[""])[1]) == ["NR", "AXISPOS", "Y", "Z"]
    assert reason in files[".note.txt"]
    with pytest.raises(ValueError, match="nothing to write"):
        export_compensation("heidenhain", X, ERR)


def test_bad_options_are_refused():
    with pytest.raises(ValueError, match="--format must be one of"):
        export_compensation("okuma", X, ERR)
    with pytest.raises(ValueError, match="equidistant"):
        export_compensation("siemens-cec", X**3 / 1e4, ERR, axis_side="tool")
    with pytest.raises(ValueError, match="X carries the table"):
        export_compensation("siemens-cec", X, ERR, axis_side={"X": "tool"})
    with pytest.raises(ValueError, match="Y or Z = tool or workpiece"):
        export_compensation("siemens-cec", X, ERR, axis_side={"Z": "spindle"})
    with pytest.raises(ValueError, match="reference position X = 123 mm must be one of"):
        export_compensation(ExportSpec("fanuc", reference_mm=123.0), X, ERR,
                            exx_includes_lead=True)


@pytest.mark.parametrize("command", ["fit", "simulate"])
def test_help_marks_experimental_formats(command, capsys):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for fmt in FORMATS:
        assert fmt in text
    for fmt in EXPERIMENTAL:
        assert f"{fmt} (EXPERIMENTAL" in text
    assert "--axis-side" in text


def test_simulated_machine_to_cec_and_heidenhain(tmp_path):
    """A simulated machine's joint errors at P5 (its own CSV) against the exports of the same
    run: the tables cancel them with Z on the tool side and Y on the workpiece side."""
    out, comp = tmp_path / "e.csv", tmp_path / "comp.mpf"
    common = ["simulate", "--variant", "2", "--mesh", "10x5", "--positions", "-300:300:5",
              "--out", str(out), "--x0-mm", "400", "--axis-side", "Y=workpiece,Z=tool",
              "--quiet", "--export-compensation"]
    assert main([*common, str(comp), "--format", "siemens-cec"]) == 0
    rows = [r for r in csv.DictReader(out.open()) if r["point"] == "P5"]
    e = {n: np.array([float(r[f"{n}_um"]) for r in rows]) * 1e-6 for n in ("EXX", "EYX", "EZX")}
    tables, _ = parse_cec(comp.read_text())
    by_axis = {t["output"]: t for t in tables.values()}
    np.testing.assert_allclose(by_axis["(AX2)"]["pos"], [100, 250, 400, 550, 700], atol=1e-6)
    for axis, name, side in (("(AX2)", "EYX", "workpiece"), ("(AX3)", "EZX", "tool")):
        left = residual_at_tool(e[name], by_axis[axis]["comp"], side)
        np.testing.assert_allclose(left, 0.0, atol=1e-9)  # CSV µm to 6 decimals, CEC mm to 6
    assert np.max(np.abs(e["EZX"])) > 1e-8
    com = tmp_path / "tnc.txt"
    assert main([*common, str(com), "--format", "heidenhain"]) == 0
    _, table = parse_tnc_table(com.read_text())
    # a simulation has no lead error, so its pitch column is the model's EXX alone
    np.testing.assert_allclose(-np.array(table["X"], float) * 1e-3, e["EXX"], atol=1e-9)
    assert "EXX has no lead error" in (tmp_path / "tnc.note.txt").read_text()
    no_side = [a for a in common if a not in ("--axis-side", "Y=workpiece,Z=tool")]
    comp.unlink()
    assert main([*no_side, str(comp), "--format", "siemens-cec"]) == 2  # refused before work
    assert not comp.exists()


@pytest.mark.parametrize("args, message", [
    (["--format", "siemens-cec"], "--format siemens-cec needs --axis-side"),
    (["--format", "isg", "--axis-side", "Q=tool"], "axis_side: Q='tool' is not allowed"),
    (["--format", "isg-cross", "--axis-side", "tool"], "logical axis number of X, Y, Z is "
     "needed"),
    (["--format", "fanuc", "--fanuc-detection-unit", "IS-Q"],
     "--fanuc-detection-unit: 'IS-Q' is not allowed; allowed: IS-A, IS-B, IS-C"),
])
def test_fit_refuses_export_options_before_any_work(tmp_path, capsys, args, message):
    data = Path(__file__).resolve().parents[1] / "data" / "majda2012_measurements.csv"
    out = tmp_path / "o"
    assert main(["fit", "--measurements", str(data), "--out", str(out), "--quiet",
                 "--export-compensation", str(tmp_path / "c.txt"), *args]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists() and not (tmp_path / "c.txt").exists()
