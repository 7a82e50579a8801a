"""Profiles (:mod:`diffguide.io.profiles`), encodings and units: seven vendor-style tables load,
unedited, through profiles written from the README's documentation alone, to the same merged
data as their canonical twins; the built-in profiles read their example files; the canonical
layouts read through their profiles equal the canonical parsers (two formulations)."""

import math
import re
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from diffguide.cli import main
from diffguide.io.csvtable import decode
from diffguide.io.importers import merged_table, read_any
from diffguide.io.measurements import ANGULAR_UNITS, LINEAR_UNITS, parse_readings
from diffguide.io.profiles import ProfileError, builtin_profiles, load_profile

ROOT = Path(__file__).resolve().parents[1]
VENDOR = ROOT / "tests" / "data" / "vendor"
EXAMPLES = ROOT / "data" / "examples"
sys.path.insert(0, str(VENDOR))
import make_vendor_tables  # noqa: E402

README = (ROOT / "README.md").read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    return make_vendor_tables.write_all(tmp_path_factory.mktemp("vendor"))


def _same(a, b, tol=1e-9):
    """Merged tables equal: positions to 1 nm (inches printed to 1e-9 in), points and quantities
    exactly, values and σ to ``tol`` µm (µm/m) — the round trip of the vendors' units."""
    assert a.shape == b.shape
    np.testing.assert_allclose(a[:, 0], b[:, 0], atol=1e-6)
    np.testing.assert_array_equal(a[:, 1:3], b[:, 1:3])
    np.testing.assert_allclose(a[:, 3:], b[:, 3:], rtol=tol, atol=tol)


@pytest.mark.parametrize("name", list(make_vendor_tables.TABLES))
def test_vendor_table_loads_through_its_profile_to_the_canonical_data(tables, name):
    table, canonical, profile = tables[name]
    notes, info = [], {}
    got = read_any(table, profile=str(profile), notes=notes, info=info)
    _same(merged_table(got), merged_table(read_any(canonical)))
    assert info["readings"] == len(got.readings) and info["x0_mm"] in (0.0, 400.0)
    assert all(r.source == str(table) for r in got.readings)


def test_the_vendor_tables_are_what_the_issue_describes(tables):
    raw = {n: t.read_bytes() for n, (t, _, _) in tables.items()}
    assert raw["laser.csv"].startswith(b"\xef\xbb\xbf") and b"\r\n" in raw["laser.csv"]
    assert b"Targets:" in raw["laser_ascii.txt"] and b"Data:" in raw["laser_ascii.txt"]
    assert "rück".encode("latin-1") in raw["levels_latin1.csv"]
    with pytest.raises(UnicodeDecodeError):
        raw["levels_latin1.csv"].decode("utf-8")
    assert b"\tDown\t" in raw["inch_tab.txt"] and b"arc-sec" in raw["inch_tab.txt"]
    assert "–".encode("cp1252") in raw["iso230_summary.csv"]
    assert b"[EBX]" in raw["grid.exx"] and b"Gridpoints = {" in raw["grid.exx"]
    assert raw["sixdof.csv"].count(b"(") >= 7  # the target and all six errors


def test_several_vendor_files_are_one_data_set(tables, tmp_path, capsys):
    """Six files with disjoint channels, each through its own profile (``import A B ...
    --profile PA --profile PB ...``), merged equal their canonical twins concatenated (the EXX
    grid repeats run 1 of P5: relabelled, tested in test_import_merge)."""
    names = [n for n in make_vendor_tables.TABLES if n != "grid.exx"]
    out = tmp_path / "all.csv"
    args = ["import", *(str(tables[n][0]) for n in names), "--out", str(out), "-q"]
    for n in names:
        args += ["--profile", str(tables[n][2])]
    assert main(args) == 0
    twins = [tables[n][1].read_text(encoding="utf-8") for n in names]
    both = tmp_path / "all.canonical.csv"
    both.write_text(twins[0] + "".join(t.split("\n", 1)[1] for t in twins[1:]),
                    encoding="utf-8")
    # import writes 6 decimals (1e-6 µm/m): the runs' scatter σ moves by < 1e-6 relative
    _same(merged_table(read_any(out)), merged_table(read_any(both)), tol=1e-6)
    head = out.read_text(encoding="utf-8").split("\n", 2)[:2]
    assert all(n in head[0] for n in names) and "x0 = 400 mm" in head[1]


def _documented_fields():
    section = README[README.index("## File formats"):README.index("## Python API")]
    return section, set(re.findall(r"`([a-z0-9_]+)", section)) | set(
        re.findall(r"^([a-z0-9_]+) =", section, flags=re.M)) | set(
        re.findall(r"# ([a-z0-9_, ]+)", section))


def test_vendor_profiles_use_only_keys_the_readme_documents():
    section, words = _documented_fields()
    text = " ".join(words) + section
    fields = re.search(r"give every field of a reading — (.*?) —", section, flags=re.S)[1]
    for path in VENDOR.glob("*.toml"):
        prof = tomllib.loads(path.read_text(encoding="utf-8"))
        keys = set(prof)
        for sub in ("table", "targets", "blocks"):
            keys |= set(prof.get(sub, {})) | ({f"[{sub}]"} if sub in prof else set())
        for level in (prof.get("reading", {}), *prof.get("values", [])):
            for k in level:
                base = re.sub(r"_(column|meta)$", "", k)
                assert f"`{base}`" in fields or k in ("column", "match"), (path.name, k)
        for k in keys - {"reading", "values", "aliases"}:
            assert k.strip("[]") in text, (path.name, k)
        for f in prof.get("aliases", {}):
            assert f in fields or f"`{f}`" in section, (path.name, f)


@pytest.mark.parametrize("name, x0", [("majda2012_measurements.csv", None),
                                      ("majda2012_measurements_wide.csv", None),
                                      ("majda2012_measurements_semicolon.csv", 400.0)])
def test_canonical_profiles_equal_the_canonical_parsers(name, x0):
    path = ROOT / "data" / name
    profile = "wide" if "wide" in name else "long"
    _same(merged_table(read_any(path, x0_mm=x0, profile=profile)),
          merged_table(read_any(path, x0_mm=x0)))


def test_builtin_profiles_read_their_examples():
    assert {"exx", "iso230-2-summary", "6dof", "long", "wide"} <= set(builtin_profiles())
    exx = load_profile("exx")
    exx["reading"].update(point="P5", x_mm=0.0, y_mm=0.0)
    for example, profile in (("exx_grid.exx", exx), ("iso230-2-summary.csv",
                                                     "iso230-2-summary"),
                             ("6dof.csv", "6dof")):
        path = EXAMPLES / example
        got = merged_table(read_any(path, profile=profile))
        _same(got, merged_table(read_any(path.with_name(path.name + ".canonical.csv"))))


def test_shipped_profiles_are_package_data():
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert "builtin_profiles/*.toml" in text
    assert all(tomllib.loads(t) for t in builtin_profiles().values())


@pytest.mark.parametrize("encoding, bom", [("utf-8", b""), ("utf-8", b"\xef\xbb\xbf"),
                                           ("utf-16-le", b"\xff\xfe"),
                                           ("utf-16-be", b"\xfe\xff"),
                                           ("utf-16-le", b""), ("cp1252", b"")])
def test_encodings_are_detected(encoding, bom):
    text = "position_mm,point\n0,Pä µm/m – x\n"
    if encoding == "cp1252":
        got, used = decode(text.encode("cp1252"), "f")
        assert (got, used) == (text, "cp1252")
        return
    got, used = decode(bom + text.encode(encoding), "f")
    assert got == text and used.startswith(encoding[:5])


def test_stated_encoding_wins_and_a_wrong_one_is_named():
    data = "a;ö\n".encode("latin-1")
    assert decode(data, "f", "latin-1") == ("a;ö\n", "latin-1")
    with pytest.raises(ValueError, match=r"f:1: not utf-8 text"):
        decode(data, "f", "utf-8")
    with pytest.raises(ValueError, match="unknown encoding 'klingon'"):
        decode(data, "f", "klingon")


@pytest.mark.parametrize("unit, factor, quantity", [
    ("rad", 1.0, "EBX"), ("arc-sec", math.pi / 648000, "EBX"), ('"', math.pi / 648000, "EBX"),
    ("arcsec", math.pi / 648000, "ECX"), ("in", 0.0254, "EYX"), ("µin", 0.0254e-6, "EZX"),
    ("uin", 0.0254e-6, "EXX"), ("inches", 0.0254, "EXX")])
def test_new_units_convert_by_their_definitions(unit, factor, quantity):
    value = 2e-3 / factor * (1e-3 if unit in ("rad",) else 1.0)  # within the plausible limit
    text = ("position_mm,point,x_mm,y_mm,quantity,value,unit\n"
            f'0,P1,0,0,{quantity},{value!r},"{unit.replace(chr(34), chr(34) * 2)}"\n')
    (r,) = parse_readings(text)
    assert math.isclose(r.value, value * factor, rel_tol=1e-12)
    assert r.unit in (LINEAR_UNITS if quantity in ("EXX", "EYX", "EZX") else ANGULAR_UNITS)


def test_profile_mistakes_are_named(tmp_path, tables):
    bad = tmp_path / "bad.toml"
    bad.write_text('nmae = "x"\n[table]\nposition = 1\n[[values]]\ncolumn = 2\n')
    with pytest.raises(ProfileError, match="unknown key 'nmae'"):
        load_profile(str(bad))
    bad.write_text('[table]\nposition = "Target (mm)"\nstart = "^Target"\n[[values]]\n'
                   'column = "Run 9 Fwd"\n')
    with pytest.raises(ValueError, match=r"laser.csv:12: values\[1\].column: no column named "
                                         r"'Run 9 Fwd' in the header \(Target \(mm\), Run 1"):
        read_any(tables["laser.csv"][0], profile=str(bad))
    prof = load_profile(str(tables["laser.csv"][2]))
    del prof["aliases"]["direction"]
    prof["values"][0]["match"] = r"Run (?P<run>\d+) (?P<direction>\w+)"
    text = tables["laser.csv"][0].read_bytes().replace(b" Rev", b" Retour")
    (tmp_path / "l.csv").write_bytes(text)
    with pytest.raises(ValueError, match=r"l.csv:13: direction 'Retour' is not a known word"):
        read_any(tmp_path / "l.csv", profile=prof)
    with pytest.raises(ProfileError, match="cannot read the profile.*built-in profiles: 6dof"):
        load_profile(str(tmp_path / "missing.toml"))


def test_import_explain_says_what_was_read(tables, capsys, tmp_path):
    table, _, profile = tables["levels_latin1.csv"]
    out = tmp_path / "o.csv"
    assert main(["import", str(table), "--profile", str(profile), "--explain",
                 "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "encoding: latin-1; separator: ';'; decimal mark: ','" in said
    assert "column 'Messwert (µm/m)' -> EBX [µm/m] at P1, EAX [µm/m] at P1, sign -1" in said
    assert "x0 = 400 mm (the profile)" in said and "positions: column 'Position (mm)'" in said
    _same(merged_table(read_any(out)), merged_table(read_any(tables["levels_latin1.csv"][1])),
          tol=1e-6)
    exx, _, _ = tables["grid.exx"]
    assert main(["import", str(exx), "--profile", "exx", "--profile-set", "point=P5",
                 "--explain"]) == 0
    captured = capsys.readouterr()
    assert "column 'column 2' -> EBX [rad] at P5, ECX [rad] at P5" in captured.out
    assert "section(s) skipped by blocks.skip: [C0B], [EXY]" in captured.err


def test_sign_per_channel(tables):
    """``sign = { "P1:EAX" = -1 }`` turns the reversed level's readings back as
    ``{ EAX = -1 }`` does; the same sign on another point's channel leaves them negated."""
    table, canonical, profile = tables["levels_latin1.csv"]
    ref = merged_table(read_any(canonical))
    prof = load_profile(str(profile))
    prof["reading"]["sign"] = {"P1:EAX": -1, "default": 1}
    _same(merged_table(read_any(table, profile=prof)), ref)
    prof["reading"]["sign"] = {"P2:EAX": -1}
    got = merged_table(read_any(table, profile=prof))
    eax = got[:, 2] == 3  # QUANTITIES.index("EAX")
    np.testing.assert_allclose(got[eax, 3], -ref[eax, 3], atol=1e-9)
    np.testing.assert_allclose(got[~eax, 3], ref[~eax, 3], atol=1e-9)


def _reheader(src, dst, old: str, new: str, move=None):
    """``src`` with its table header ``old`` replaced by ``new`` (and, with ``move``, each data
    row's columns reordered as the header was)."""
    lines = src.read_text(encoding=_enc(src)).splitlines()
    out = []
    for line in lines:
        if line.startswith(old):
            out.append(new)
        elif move and out and out[-1:] and new in out and line.strip():
            cells = line.split(",")
            out.append(",".join(cells[i] for i in move))
        else:
            out.append(line)
    dst.write_text("\n".join(out) + "\n", encoding=_enc(src))
    return dst


def _enc(path):
    return "cp1252" if "iso230" in path.name else "utf-8"


def test_builtin_profiles_read_the_common_header_variants(tmp_path):
    """ISO 230-2's 'Pi (mm)' target column, and a 6-DOF table whose header starts with its run
    and direction columns ('Run,Direction,Position (mm),...'): read as the examples are."""
    iso = EXAMPLES / "iso230-2-summary.csv"
    want = merged_table(read_any(iso.with_name(iso.name + ".canonical.csv")))
    head = "Target (mm);"
    variant = _reheader(iso, tmp_path / "pi.csv", head, "Pi (mm);Mean fwd;Mean bwd;s fwd;"
                        "s bwd;R fwd;R bwd;B")
    _same(merged_table(read_any(variant, profile="iso230-2-summary")), want)
    six = EXAMPLES / "6dof.csv"
    want = merged_table(read_any(six.with_name(six.name + ".canonical.csv")))
    cols = ("Target (mm),Run,Direction,Linear (µm),Horizontal straightness (µm),"
            "Vertical straightness (µm),Roll (µrad),Pitch (µrad),Yaw (µrad)").split(",")
    order = [1, 2, 0, 3, 4, 5, 6, 7, 8]
    header = ",".join(cols[i] for i in order).replace("Target (mm)", "Position (mm)")
    variant = _reheader(six, tmp_path / "run_first.csv", "Target (mm),", header, move=order)
    assert (tmp_path / "run_first.csv").read_text().count("Run,Direction,Position (mm)") == 1
    _same(merged_table(read_any(variant, profile="6dof")), want)


def test_profile_settings_bind_to_their_profile():
    """``--profile-set point=P5`` meant for the exx file landed on every file (a Wyler roll at
    P1 read as P5, no note): with several profiles a setting names its profile, and reaches
    only the files read through it; unqualified, it is refused naming the choice."""
    import argparse

    from diffguide.jobs.inputs import load_profile_args

    def profiles(names, sets):
        return load_profile_args(argparse.Namespace(profile=names, profile_set=sets),
                                 ["a", "b", "c"][:len(names)])

    one = profiles(["exx"], ["point=P5", "x_mm=0"])
    assert one[0]["reading"]["point"] == "P5" and one[0]["reading"]["x_mm"] == 0.0
    a, b = profiles(["6dof", "exx"], ["exx:point=P5", "6dof:x_mm=450"])
    assert b["reading"]["point"] == "P5" and "point" not in a["reading"]  # 6dof: point_meta
    assert a["reading"]["x_mm"] == 450.0 and b["reading"].get("x_mm") != 450.0
    a, b = profiles(["auto", "exx"], ["point=P5"])  # one profile: no doubt which
    assert a is None and b["reading"]["point"] == "P5"
    with pytest.raises(ValueError, match=r"2 profiles \(6dof, exx\); say which one.*"
                                         r"--profile-set exx:point=P5"):
        profiles(["6dof", "exx"], ["point=P5"])
    with pytest.raises(ValueError, match="'wyler' is not one of the --profile options"):
        profiles(["6dof", "exx"], ["wyler:point=P5"])
