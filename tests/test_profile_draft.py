"""``diffguide import FILE --draft-profile OUT.toml``: a profile drafted from a vendor file's
own layout and metadata. For each of the seven vendor-style tables of
``tests/data/vendor/make_vendor_tables.py`` (laser CSV with a key/value block and 'Run 1 Fwd'
columns, a laser ASCII Targets/Data export, a Latin-1 level pair with ';' and decimal commas,
a tab-separated inch table, an ISO 230-2 summary, a vendor-exchange grid, a 6-DOF table) the
draft is completed with at most 6 user-written lines — the values a user knows and the file
does not say (the machine coordinate of x = 0, a point's name and place, what a German word
means, a sensor mounted reversed) — and then loads to the same merged data as the canonical
long file written independently beside each table."""

import re
import sys
from pathlib import Path

import pytest

from diffguide.cli import main
from diffguide.io.importers import merged_table, read_any
from diffguide.io.profile_draft import draft_profile
from diffguide.io.profiles import ProfileError, load_profile

ROOT = Path(__file__).resolve().parents[1]
VENDOR = ROOT / "tests" / "data" / "vendor"
sys.path.insert(0, str(VENDOR))
import make_vendor_tables  # noqa: E402

#: what the user writes, per table: {key of a REQUIRED line (or the commented 'sign' line):
#: its value} — the facts of the measurement setup that the files do not state
USER = {
    "laser.csv": {"x0_mm": "400.0"},
    "laser_ascii.txt": {"x0_mm": "400.0"},
    "levels_latin1.csv": {"x0_mm": "400.0", '"Neigung längs"': '"EBX"',
                          '"Neigung quer"': '"EAX"', "# sign": "{ EAX = -1 }"},
    "inch_tab.txt": {"x0_mm": "400.0"},
    "iso230_summary.csv": {"x0_mm": "400.0"},
    "grid.exx": {"x0_mm": "400.0", "point": '"P5"', "x_mm": "0.0", "y_mm": "0.0"},
    "sixdof.csv": {"# sign": "{ ECX = -1 }"},
}


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    return make_vendor_tables.write_all(tmp_path_factory.mktemp("vendor"))


def complete(text: str, answers: dict) -> tuple[str, int]:
    """``text`` with the REQUIRED lines (and a commented-out key) answered; the number of lines
    the user wrote."""
    out, written = [], 0
    for line in text.splitlines():
        key = next((k for k in answers if re.match(rf"{re.escape(k)}\s*=", line)), None)
        if key is not None and ("REQUIRED" in line or key.startswith("# ")):
            out.append(f"{key.removeprefix('# ')} = {answers[key]}")
            written += 1
        else:
            out.append(line)
    return "\n".join(out) + "\n", written


@pytest.mark.parametrize("name", list(make_vendor_tables.TABLES))
def test_a_completed_draft_reads_the_vendor_table_as_its_canonical_twin(tables, name, tmp_path):
    table, canonical, _ = tables[name]
    text, todo = draft_profile(table)
    draft = tmp_path / "draft.toml"
    draft.write_text(text, encoding="utf-8")
    if todo:  # the draft is refused until completed, naming what is left
        with pytest.raises(ProfileError, match=r"is still \"\?\" \(a draft profile"):
            load_profile(str(draft))
    filled, written = complete(text, USER[name])
    assert written <= 6 and written == len(USER[name])
    assert text.count("# REQUIRED") == len(todo) and "# REQUIRED" not in filled
    draft.write_text(filled, encoding="utf-8")
    got = merged_table(read_any(table, profile=str(draft)))
    want = merged_table(read_any(canonical))
    assert got.shape == want.shape
    assert got[:, 0] == pytest.approx(want[:, 0], abs=1e-6)  # positions (m): inches to 1 nm
    assert (got[:, 1:3] == want[:, 1:3]).all()                # points, quantities
    assert got[:, 3:] == pytest.approx(want[:, 3:], rel=1e-9, abs=1e-12)


def test_the_draft_says_what_the_file_says(tables):
    text, todo = draft_profile(tables["levels_latin1.csv"][0])
    for line in ('separator = ";"', 'decimal = ","', 'position = "Position (mm)"',
                 'column = "Messwert (µm/m)"', 'unit = "µm/m"', 'run_column = "Lauf"',
                 'reference_column = "Referenz (µm/m)"', '"rück" = "backward"'):
        assert line in text, line
    assert todo == ["x0_mm", "aliases.quantity.Neigung längs", "aliases.quantity.Neigung quer"]
    text, _ = draft_profile(tables["inch_tab.txt"][0])
    assert 'position_unit = "in"' in text and 'separator = "tab"' in text


def test_cli_writes_the_draft_with_the_machines_points_and_never_over_a_file(tables, tmp_path,
                                                                              capsys):
    table = str(tables["grid.exx"][0])
    out = tmp_path / "grid.toml"
    assert main(["import", table, "--draft-profile", str(out), "--preset", "majda2012"]) == 0
    said = capsys.readouterr().out
    assert "4 line(s) marked REQUIRED" in said and "reading.point" in said
    text = out.read_text(encoding="utf-8")
    assert "#     P5 = 0, 0" in text and "#     P1 = 450, 200" in text
    out.write_text("# completed by hand\n", encoding="utf-8")
    assert main(["import", table, "--draft-profile", str(out)]) == 2
    assert "the file exists" in capsys.readouterr().err
    assert out.read_text(encoding="utf-8") == "# completed by hand\n"
    assert main(["import", table, "--draft-profile", str(out), "--overwrite-draft"]) == 0
    assert "Gridpoints" in out.read_text(encoding="utf-8")
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left


def _wyler(folder):
    """A Wyler-style level table in UTF-16: a title, metadata lines (instrument S/N, date, temperature
    with a decimal comma, operator, machine S/N, the point and its place), ';' and decimal
    commas, 'Pos. [mm]', 'Dir.' with arrows, pitch in mm/m; machine coordinates 0 … 600 mm."""
    lines = ["WYLER AG - BlueLEVEL measurement", "Instrument S/N: 470-1234",
             "Date: 2026-11-02 09:14", "Temperature: 20,4 °C", "Operator: J. Kowalski",
             "Machine S/N: VMC-0815", "Measuring point: P1", "X [mm]: 450", "Y [mm]: 200", "",
             "Pos. [mm];Run;Dir.;Pitch [mm/m]"]
    canon = [make_vendor_tables.CANONICAL_HEADER]
    for run in (1, 2):
        for arrow, d in (("↑", "forward"), ("↓", "backward")):
            for k in range(13):
                v = round(0.004 * ((k * 7 + run * 3 + len(d)) % 11 - 5), 5)  # mm/m
                lines.append(f"{50 * k},0;{run};{arrow};{v:.5f}".replace(".", ","))
                canon.append(f"{50 * k - 300},P1,450,200,EBX,{v * 1000:.2f},um/m,,{run},{d},"
                             "level")
    table = folder / "wyler.csv"
    table.write_bytes(("\r\n".join(lines) + "\r\n").encode("utf-16"))  # with a BOM
    (folder / "wyler.csv.canonical.csv").write_text("\n".join(canon) + "\n")
    return table, folder / "wyler.csv.canonical.csv"


def _xl80(folder):
    """A Renishaw-XL-80-like linear export: a key/value block, columns 'Run 1 ↑ (µm)' …,
    an environment column; positions from 0 to 700 mm."""
    lines = ["Renishaw LaserXL linear measurement,", "Serial number,XL80-98765",
             "Date,07/12/2026", "Measurement,Linear", "Location,P5", "X position,0",
             "Y position,0", "",
             "Target (mm),Run 1 ↑ (µm),Run 1 ↓ (µm),Run 2 ↑ (µm),Run 2 ↓ (µm),Air temp (°C)"]
    canon = [make_vendor_tables.CANONICAL_HEADER]
    for k in range(15):
        vals = {(r, d): round(0.8 * (k - 7) + 0.1 * r - (0.3 if d == "backward" else 0), 3)
                for r in (1, 2) for d in ("forward", "backward")}
        lines.append(f"{50 * k}," + ",".join(f"{vals[(r, d)]:.3f}" for r in (1, 2)
                                             for d in ("forward", "backward")) + ",20.1")
        canon += [f"{50 * k - 350},P5,0,0,EXX,{vals[(r, d)]:.3f},um,,{r},{d},interferometer"
                  for r in (1, 2) for d in ("forward", "backward")]
    table = folder / "xl80.csv"
    table.write_text("\n".join(lines) + "\n", encoding="utf-8")
    (folder / "xl80.csv.canonical.csv").write_text("\n".join(canon) + "\n")
    return table, folder / "xl80.csv.canonical.csv"


@pytest.mark.parametrize("make, answers", [(_wyler, {"x0_mm": "300.0"}),
                                           (_xl80, {"x0_mm": "350.0"})])
def test_more_vendor_layouts_draft_to_one_line(make, answers, tmp_path):
    table, canonical = make(tmp_path)
    text, todo = draft_profile(table)
    assert todo == ["x0_mm"], text
    filled, written = complete(text, answers)
    draft = tmp_path / "draft.toml"
    draft.write_text(filled, encoding="utf-8")
    got = read_any(table, profile=str(draft))
    assert merged_table(got) == pytest.approx(merged_table(read_any(canonical)), rel=1e-9,
                                              abs=1e-12)
    assert {r.instrument for r in got.readings} == {r.instrument for r in
                                                     read_any(canonical).readings}
