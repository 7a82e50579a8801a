"""Text from the input (a measurement or rails file's name, a point name, a machine name) in a
compensation export's comments cannot end the comment: every control or line-breaking character
(and each format's own comment terminator) is written as a visible escape, so the file's live
lines are those of the same export with harmless names. Names written outside comments (a
SINUMERIK axis, a TNC table, an ISG file name) are refused. The files are read back by the
parsers of tests/test_exports.py, written from the controllers' manuals."""

import csv
import re

import numpy as np
import pytest
from test_exports import (
    ERR,
    SIG,
    X0,
    X,
    parse_cec,
    parse_csv,
    parse_fanuc,
    parse_isg_csv,
    parse_lis,
    parse_tnc_table,
)

from diffguide.cli import main
from diffguide.studies.compensation import compensation_table
from diffguide.studies.exports import ExportSpec, export_compensation, file_spec

#: a file name that, unescaped, ends every format's comment and adds live lines to each
HOSTILE = ("run\n$AN_CEC[0,0]=99\nM30\r\n3620 = 7\n0 0.0000 99\n# break\n// x\u2028X EXX\x0b"
           "1.0 2.0\u0085[END]\x00.csv")
SIDE = {"Y": "workpiece", "Z": "tool"}
#: each format's comment prefix (every other line is live)
COMMENT = {"csv": "#", "isg": "//", "siemens-cec": ";", "fanuc": "#", "heidenhain": None}


def _export(fmt, point, source):
    return export_compensation(ExportSpec(fmt, axis_side=SIDE), X, ERR, SIG, x0_mm=X0,
                               point=point, source=source, exx_includes_lead=True)


def _live(text, prefix):
    lines = text.splitlines()  # splits at every line break a reader may honour
    return [ln for ln in lines if prefix is None or not ln.lstrip().startswith(prefix)], len(lines)


@pytest.mark.parametrize("fmt", list(COMMENT))
def test_a_hostile_name_adds_no_live_line(fmt):
    clean = _export(fmt, "P5", "measured in run.csv")
    hostile = _export(fmt, HOSTILE, f"measured in {HOSTILE}")
    assert clean.keys() == hostile.keys()
    for suffix, text in hostile.items():
        prefix = {".lis": "#", ".startup.lis": "#", ".sigma.csv": "#", ".cma": None,
                  ".note.txt": None}.get(
            suffix, COMMENT[fmt])
        if suffix == ".note.txt":  # plain text, no live lines: one line per line still
            assert len(text.splitlines()) == len(clean[suffix].splitlines())
            continue
        assert _live(text, prefix) == _live(clean[suffix], prefix), (fmt, suffix)
        assert text.isascii() or fmt == "csv" or suffix == ".note.txt"
    text = hostile[""]
    if fmt == "siemens-cec":
        tables, _ = parse_cec(text)  # every live line a known one (M30 would fail it)
        assert tables[0]["comp"][0] == pytest.approx(-ERR[0, 1], abs=1e-9)  # not 99 mm
        assert "M30" not in [ln.strip() for ln in text.splitlines()]
    elif fmt == "isg":
        cols = parse_isg_csv(text)  # one block: no '#' file break at a line's start
        np.testing.assert_allclose(cols["X"], X + X0)
        assert parse_lis(hostile[".lis"]) == parse_lis(clean[".lis"])
    elif fmt == "fanuc":
        pos, _ = parse_fanuc(text)  # 3620 = 7 would have moved the reference point
        np.testing.assert_allclose(pos, X + X0)
    elif fmt == "csv":
        x, e, _ = parse_csv(text)
        np.testing.assert_allclose(x, X + X0)
        assert HOSTILE.replace("\n", "\\x0a")[:20] in text  # quoted, visibly escaped
    else:
        assert parse_tnc_table(text)[0] == "DGX.COM"


def test_compensation_table_header_stays_comments():
    errs = np.zeros((3, 1, 6))
    text = compensation_table(np.array([0.0, 1.0, 2.0]), errs, [HOSTILE], HOSTILE, HOSTILE)
    rows = [ln for ln in text.splitlines() if not ln.startswith("#")]
    assert len(rows) == 4 and rows[0].startswith("X_mm")


@pytest.mark.parametrize("fmt, kw, what", [
    ("siemens-cec", {"axis_names": {"X": "AX1)\nM30\n(", "Y": "AX2", "Z": "AX3"}},
     "axis_names['X']"),
    ("heidenhain", {"table_name": "T\n[END]"}, "table_name"),
    ("heidenhain", {"table_name": "MY TABLE"}, "table_name"),
    ("isg", {"file_name": "c.csv\nfile[1] evil.csv"}, "file_name"),
])
def test_a_name_outside_the_comments_is_refused(fmt, kw, what):
    with pytest.raises(ValueError, match=re.escape(what) + " must match"):
        ExportSpec(fmt, **kw)


def test_an_export_file_name_that_cannot_be_a_table_name_is_refused_by_the_cli(tmp_path,
                                                                               capsys):
    bad = tmp_path / "my table.com"
    assert main(["simulate", "--out", str(tmp_path / "e.csv"), "--export-compensation",
                 str(bad), "--format", "heidenhain", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"--export-compensation {bad}" in err and "table_name" in err
    assert list(tmp_path.iterdir()) == []
    assert file_spec("siemens-cec", bad, "tool").table_name == "MY TABLE"  # unused there


def test_simulate_with_a_hostile_rails_file_name_writes_a_clean_cec_program(tmp_path):
    """The issue's reproduction, end to end: the rails file's name goes into the header of the
    SINUMERIK program; the program's live lines are the clean run's."""
    s = np.linspace(-700, 700, 29)
    text = "rail,s_mm,vertical_um,horizontal_um\n" + "".join(f"1,{a},0.5,0\n" for a in s)
    files = {}
    for name in ("rails.csv", "rails\n$AN_CEC[0,0]=99\nM30\n.csv"):
        rails = tmp_path / name
        rails.write_text(text)
        comp = tmp_path / f"c{len(files)}.mpf"
        assert main(["simulate", "--rails", str(rails), "--mesh", "6x3", "--positions",
                     "-300:300:3", "--out", str(tmp_path / "e.csv"), "--axis-side", "tool",
                     "--format", "siemens-cec", "--export-compensation", str(comp),
                     "--quiet"]) == 0
        files[name] = comp.read_text()
    clean, hostile = files.values()
    assert _live(hostile, ";") == _live(clean, ";")
    tables, comments = parse_cec(hostile)
    assert "M30" not in hostile.splitlines() and len(tables) == 2
    assert any("\\x0a$AN_CEC[0,0]=99\\x0aM30" in c for c in comments)
    with (tmp_path / "e.csv").open() as fh:
        assert next(csv.reader(fh))  # the run's own CSV is intact


def test_isg_cross_lists_keep_a_hostile_name_in_their_comments():
    """The cross compensation lists (``#`` comments, tests/test_export_settings.py's parser)
    and their overview: a hostile point or source name changes no live line."""
    from test_export_settings import NUMBERS, parse_crosscomp

    def export(point, source):
        return export_compensation(ExportSpec("isg-cross", axis_side=SIDE,
                                              isg_axis_numbers=NUMBERS), X, ERR, SIG, x0_mm=X0,
                                   point=point, source=source, exx_includes_lead=True)

    clean, hostile = export("P5", "run.csv"), export(HOSTILE, f"measured in {HOSTILE}")
    assert clean.keys() == hostile.keys()
    for suffix, text in hostile.items():  # every file's comments start with '#'
        assert _live(text, "#") == _live(clean[suffix], "#"), suffix
        assert text.isascii()
    assert parse_crosscomp(hostile[".Z.lis"])["slave"] == NUMBERS["Z"]
