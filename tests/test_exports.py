"""Compensation exports: each file is parsed back by a small parser written from the format's
description (diffguide.studies.exports) and compared with the errors that went in — values to
the printed precision, units and sign (compensation = −error where the controller adds it)."""

import csv
import io
import math
import re

import numpy as np
import pytest

from diffguide.studies.exports import export_compensation

X = np.linspace(-300.0, 300.0, 13)  # mm, equidistant, includes 0
X0 = 500.0
# made-up errors with distinct magnitudes per quantity (m, rad), zero at x = 0
_S = X / 300.0
ERR = np.stack(
    [
        3e-6 * _S,
        -2e-6 * _S**2,
        1.5e-6 * np.sin(3 * _S),
        4e-6 * _S,
        -7e-6 * _S**3,
        2.5e-6 * np.sin(2 * _S),
    ],
    axis=1,
)
SIG = np.abs(ERR) * 0.1 + 0.2e-6


def _files(fmt):
    return export_compensation(fmt, X, ERR, SIG, x0_mm=X0, point="P5", source="test")


def parse_csv(text):
    rows = list(csv.DictReader(line for line in io.StringIO(text) if not line.startswith("#")))
    X_m = np.array([float(r["X_machine_mm"]) for r in rows])
    e = np.array(
        [
            [
                float(r[f"{n}_{u}"])
                for n, u in zip(
                    ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX"), ("um",) * 3 + ("urad",) * 3
                )
            ]
            for r in rows
        ]
    )
    s = np.array(
        [
            [
                float(r[f"{n}_sigma_{u}"])
                for n, u in zip(
                    ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX"), ("um",) * 3 + ("urad",) * 3
                )
            ]
            for r in rows
        ]
    )
    return X_m, e * 1e-6, s * 1e-6


def parse_isg(text):
    """ISG CSV: '//' comments, '#' a file break (none expected), a header naming argument and
    parameters, whitespace-separated records. Units mm and rad."""
    header, rows = None, []
    for line in text.splitlines():
        line = line.split("//")[0].strip()
        assert not line.startswith("#")
        if not line:
            continue
        if header is None:
            header = line.split()
            continue
        rows.append([float(v) for v in line.split()])
    assert header == ["X", "EXX", "EYX", "EZX", "EAX", "EBX", "ECX"]
    a = np.array(rows)
    return a[:, 0], np.concatenate([a[:, 1:4] * 1e-3, a[:, 4:7]], axis=1)


def parse_cec(text):
    """Siemens CEC: $AN_CEC[t,i]=v (mm), STEP/MIN/MAX per table, ';' comments."""
    lines = [ln.split(";")[0].strip() for ln in text.splitlines()]
    lines = [ln for ln in lines if ln]
    assert lines[0] == "%_N_NC_CEC_INI" and lines[1] == "CHANDATA(1)" and lines[-1] == "M17"
    values, meta = {}, {}
    for ln in lines[2:-1]:
        m = re.fullmatch(r"\$AN_CEC\[(\d+),(\d+)\]=(-?[\d.]+)", ln)
        if m:
            values.setdefault(int(m[1]), {})[int(m[2])] = float(m[3])
            continue
        m = re.fullmatch(r"\$AN_CEC_(\w+)\[(\d+)\]=(.+)", ln)
        assert m, ln
        meta[(m[1], int(m[2]))] = m[3]
    out = {}
    for t, vals in values.items():
        n = len(vals)
        xs = float(meta[("MIN", t)]) + float(meta[("STEP", t)]) * np.arange(n)
        assert math.isclose(xs[-1], float(meta[("MAX", t)]), abs_tol=1e-6)
        assert meta[("INPUT_AXIS", t)] == "(AX1)"
        out[meta[("OUTPUT_AXIS", t)]] = (xs, np.array([vals[i] for i in range(n)]) * 1e-3)
    return out


def parse_heidenhain(text):
    lines = text.splitlines()
    assert re.fullmatch(r"BEGIN \S+\.COM MM", lines[0]) and lines[-1] == "[END]"
    cols = lines[1].split()
    rows = np.array([[float(v) for v in ln.split()] for ln in lines[2:-1]])
    d = dict(zip(cols, rows.T))
    comp = np.stack(
        [
            d["EXX"] * 1e-3,
            d["EYX"] * 1e-3,
            d["EZX"] * 1e-3,
            np.radians(d["EAX"]),
            np.radians(d["EBX"]),
            np.radians(d["ECX"]),
        ],
        axis=1,
    )
    return d["X"], comp


def parse_fanuc(text, du=1e-3):
    sections = {}
    ref = {}
    for ln in text.splitlines():
        m = re.search(r"REFERENCE NO\. (\d+)", ln)
        if m:
            ref[int(m[1]) // 10000] = int(m[1])
        m = re.fullmatch(r"N(\d+) P(-?\d+)", ln)
        if m:
            sections.setdefault(int(m[1]) // 10000, {})[int(m[1])] = int(m[2])
    out = {}
    for base, vals in sections.items():
        nums = sorted(vals)
        cum = np.cumsum([vals[n] for n in nums])
        out[base] = (cum - cum[nums.index(ref[base])]) * du * 1e-3  # m
    return out


def test_csv_errors_and_sigma():
    (text,) = _files("csv").values()
    X_m, e, s = parse_csv(text)
    np.testing.assert_allclose(X_m, X + X0, atol=5e-5)
    np.testing.assert_allclose(e, ERR, atol=5e-12)  # 5 decimals of µm / µrad
    np.testing.assert_allclose(s, SIG, atol=5e-12)


def test_isg_errors_in_mm_and_rad():
    files = _files("isg")
    X_m, e = parse_isg(files[""])
    np.testing.assert_allclose(X_m, X + X0, atol=5e-5)
    np.testing.assert_allclose(e, ERR, atol=5e-13)  # errors, not negated
    _, _, s = parse_csv(_sigma_as_csv(files[".sigma.csv"]))
    np.testing.assert_allclose(s, SIG, atol=5e-12)


def _sigma_as_csv(text):
    """The companion has only σ columns: give parse_csv zero error columns."""
    rows = list(csv.DictReader(ln for ln in io.StringIO(text) if not ln.startswith("#")))
    names = [
        f"{n}_{u}"
        for n, u in zip(("EXX", "EYX", "EZX", "EAX", "EBX", "ECX"), ("um",) * 3 + ("urad",) * 3)
    ]
    out = io.StringIO()
    w = csv.DictWriter(out, ["X_machine_mm"] + names + [n.replace("_u", "_sigma_u") for n in names])
    w.writeheader()
    for r in rows:
        w.writerow(
            {
                "X_machine_mm": r["X_machine_mm"],
                **{n: 0 for n in names},
                **{n.replace("_u", "_sigma_u"): r[n.replace("_u", "_sigma_u")] for n in names},
            }
        )
    return out.getvalue()


def test_siemens_cec_negated_in_mm():
    files = _files("siemens-cec")
    tables = parse_cec(files[""])
    for axis, k in (("(AX2)", 1), ("(AX3)", 2)):
        xs, comp = tables[axis]
        np.testing.assert_allclose(xs, X + X0, atol=1e-6)
        np.testing.assert_allclose(comp, -ERR[:, k], atol=5e-10 + 1e-15)  # -error, 1 nm
    assert ".sigma.csv" in files


def test_heidenhain_negated_mm_and_degrees():
    files = _files("heidenhain")
    assert set(files) == {"", ".note.txt", ".sigma.csv"}  # never the table's own name
    assert "compensation = -error" in files[".note.txt"]
    X_m, comp = parse_heidenhain(files[""])
    np.testing.assert_allclose(X_m, X + X0, atol=5e-5)
    np.testing.assert_allclose(comp[:, :3], -ERR[:, :3], atol=5e-11 + 1e-15)
    np.testing.assert_allclose(comp[:, 3:], -ERR[:, 3:], atol=np.radians(5e-11) + 1e-15)


def test_fanuc_incremental_detection_units_from_the_reference():
    files = _files("fanuc")
    sections = parse_fanuc(files[""])
    for base, k in ((1, 0), (2, 1), (3, 2)):
        # absolute compensation (−error) to the detection unit (1 µm): rounding only
        np.testing.assert_allclose(sections[base], -ERR[:, k], atol=0.5e-6 + 1e-12)
    assert "REFERENCE POINT X = 500.0000 MM" in files[""]


def test_unknown_format_and_uneven_steps_refused():
    with pytest.raises(ValueError, match="--format must be one of"):
        export_compensation("okuma", X, ERR)
    with pytest.raises(ValueError, match="equidistant"):
        export_compensation("siemens-cec", X**3 / 1e4, ERR)
