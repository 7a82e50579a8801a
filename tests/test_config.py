"""Machine configuration files: round trip, building, and one-line errors for bad input."""

import numpy as np
import pytest

from diffguide.cli import main
from diffguide.io.config import default_config, dump_config, load_config, spec_from_config
from diffguide.machine.build import build_machine
from diffguide.machine.kinematics import joint_errors
from diffguide.machine.majda2012 import majda2012_machine, paper_variant


def test_dump_load_round_trip(tmp_path):
    path = tmp_path / "m.toml"
    assert main(["config", "--preset", "majda2012", "--out", str(path)]) == 0
    assert load_config(path) == default_config()


def test_config_machine_equals_preset_machine(tmp_path):
    cfg = default_config()
    cfg["table"]["mesh_nx"], cfg["table"]["mesh_ny"] = 10, 5
    path = tmp_path / "m.toml"
    path.write_text(dump_config(cfg))
    pos = np.linspace(-0.3, 0.3, 5)
    a = joint_errors(
        build_machine(spec_from_config(load_config(path))), paper_variant(1), pos
    ).errors
    b = joint_errors(majda2012_machine(nx=10, ny=5), paper_variant(1), pos).errors
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-18)


def test_a_thicker_table_in_the_file_changes_the_result(tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(
        "[table]\nthickness_mm = 80\nmesh_nx = 10\nmesh_ny = 5\n"
        '[[ribs]]\naxis = "x"\nposition_mm = 0\nwidth_mm = 20\ndepth_mm = 40\n'
    )
    cfg = load_config(path)
    assert cfg["table"]["thickness_mm"] == 80.0 and cfg["carriage"]["capacity_N"] == 22800.0
    assert len(cfg["ribs"]) == 1
    pos = np.linspace(-0.3, 0.3, 5)
    thick = np.ptp(
        joint_errors(build_machine(spec_from_config(cfg)), paper_variant(1), pos).user_units()[
            :, 0, 3
        ]
    )
    thin = np.ptp(
        joint_errors(majda2012_machine(nx=10, ny=5), paper_variant(1), pos).user_units()[:, 0, 3]
    )
    assert thick < thin  # a stiffer table spreads the roll less between the corners


BAD = [
    ("[table\nlength_mm = 1", "malformed TOML"),
    ("[tabel]\nlength_mm = 1000", "[tabel]: unknown section"),
    ("[table]\nlenght_mm = 1000", "key 'table.lenght_mm' is unknown"),
    ("[table]\nthickness_mm = -5", "key 'table.thickness_mm': -5 outside the allowed range"),
    ('[table]\nthickness_mm = "thick"', "key 'table.thickness_mm': value must be a number"),
    ("[table]\nmesh_nx = 2.5", "key 'table.mesh_nx': must be an integer"),
    ('[carriage]\nlaw = "magic"', "key 'carriage.law': 'magic' is not allowed"),
    ("[carriage]\npreload_fraction = 1.5", "key 'carriage.preload_fraction': 1.5 outside"),
    ("[carriage]\ngroove_conformity = 0.9", "key 'carriage.groove_conformity'"),
    ("[guideway]\nrail_y_mm = [-170]", "key 'guideway.rail_y_mm': must be a list of two numbers"),
    ("[guideway]\nrail_y_mm = [-240, 240]", "puts a carriage footprint off the table"),
    ("[guideway]\ncarriage_x_mm = [-10, 10]", "the carriages overlap"),
    ("[guideway]\ncarriage_x_mm = [-100, -40]", "the carriages overlap"),  # touching: 60 mm
    ("[guideway]\nrail_y_mm = [-10, 10]", "the two rails' carriages overlap"),
    # the nut's footprint off the table (default table 1000 × 500 mm, nut flange 50 × 50 mm)
    ("[screw]\nnut_xy_mm = [2000.0, 0.0]", "key 'screw.nut_xy_mm': (2000, 0) mm puts the nut"),
    ("[screw]\nnut_xy_mm = [0.0, 240.0]\nnut_footprint_mm = [200.0, 200.0]", "|y| <= 150 mm"),
    ("[screw]\nnut_xy_mm = [476.0, 0.0]", "allowed |x| <= 475 mm"),
    ("[screw]\nnut_footprint_mm = [50.0, 600.0]", "key 'screw.nut_footprint_mm'"),
    # on a carriage (C at (160, 170) mm, 60 × 48 mm): touching shares mesh nodes
    ("[screw]\nnut_xy_mm = [160.0, 170.0]", "on the carriage at (160, 170) mm"),
    ("[screw]\nnut_xy_mm = [105.0, 170.0]", "footprints must not touch"),
    ("[points]\nP9 = [900, 0]", "key 'points.P9'"),
    ("[screw]\nfree_length_at_ref_mm = 100", "must exceed half the stroke"),
    ('[[ribs]]\naxis = "z"', "key 'ribs[1].axis'"),
    ("[table]\nE_GPa = nan", "must be finite"),
    ("[fit]\nthickness_prior_mm = [50, 60, 100]", "key 'fit.thickness_prior_mm': needs"),
    ("[fit]\npreload_prior = [0.08, 0.02]", "key 'fit.preload_prior': must be a list of three"),
    ('[fit]\nstructure = "guess"', "key 'fit.structure': 'guess' is not allowed"),
    ("[fit]\nlambda = 3", "key 'fit.lambda' is unknown"),
    ("[fit]\nrigid = 1", "key 'fit.rigid': must be true or false"),
    ("[fit]\nrail_waviness_um = -0.5", "key 'fit.rail_waviness_um': -0.5 outside"),
]


@pytest.mark.parametrize("text, message", BAD, ids=[m for _, m in BAD])
def test_bad_config_gives_one_line_error_naming_file_and_key(tmp_path, capsys, text, message):
    path = tmp_path / "machine.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match="machine.toml") as info:
        load_config(path)
    assert message in str(info.value)
    # and through the CLI: exit 2, one line, no traceback, nothing written
    out = tmp_path / "out.csv"
    assert main(["simulate", "--config", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and not out.exists()


@pytest.mark.parametrize(
    "xy, footprint",
    [
        ((0.0, 150.0), (200.0, 200.0)),  # y edge on the table's: 150 + 100 = 250 = 500 / 2
        ((-475.0, -225.0), (50.0, 50.0)),  # corner: 475 + 25 = 500, 225 + 25 = 250
        ((104.0, 170.0), (50.0, 50.0)),  # 1 mm clear of the carriage at (160, 170): 56 > 55
    ],
)
def test_nut_at_the_edge_of_the_allowed_region_is_valid(tmp_path, xy, footprint):
    path = tmp_path / "m.toml"
    path.write_text(f"[screw]\nnut_xy_mm = {list(xy)}\nnut_footprint_mm = {list(footprint)}\n")
    assert load_config(path)["screw"]["nut_xy_mm"] == xy


def test_nut_on_the_table_edge_builds_and_simulates(tmp_path):
    """The edge case the validation lets through also passes the finite-element patch checks
    (one that it refuses fails there with 'outside the table' or 'overlaps another patch')."""
    from diffguide.machine.build import table_from_spec

    cfg = default_config()
    cfg["table"]["mesh_nx"], cfg["table"]["mesh_ny"] = 10, 5
    cfg["screw"]["nut_xy_mm"], cfg["screw"]["nut_footprint_mm"] = (0.0, 150.0), (200.0, 200.0)
    path = tmp_path / "m.toml"
    path.write_text(dump_config(cfg))
    model = table_from_spec(spec_from_config(load_config(path)), nut=True)
    nut = model.patches[-1]
    assert (nut.y + nut.half_y, nut.half_x) == pytest.approx((0.25, 0.1))  # m, on the edge
    out = tmp_path / "x.csv"
    rc = main(["simulate", "--config", str(path), "--variant", "1", "--positions",
               "-300:300:3", "--out", str(out), "--quiet"])
    assert rc == 0 and out.exists()


def test_stiffness_names_the_config_file_not_the_preset(tmp_path, capsys, monkeypatch):
    """`stiffness --config F` says F in its console line and plot title, not 'majda2012'."""
    import diffguide.plotting.guideway as pg

    titles, plot = [], pg.plot_static_characteristic

    def recording(curves, title="", **kw):
        titles.append(title)
        return plot(curves, title=title, **kw)

    monkeypatch.setattr(pg, "plot_static_characteristic", recording)
    path = tmp_path / "mine.toml"
    path.write_text('[carriage]\narrangement = "O"\n')
    args = ["stiffness", "--config", str(path), "--steps", "3", "--max-load", "2000"]
    assert main([*args, "--out", str(tmp_path / "s.csv"), "--plot", str(tmp_path / "s.png")]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{path}: preload approach") and "majda2012" not in out
    assert titles == [f"{path}: static characteristic"]
    # without --config the preset still names it
    assert main(["stiffness", "--preset", "roller25", "--steps", "3", "--max-load", "2000",
                 "--out", str(tmp_path / "r.csv")]) == 0
    assert capsys.readouterr().out.startswith("roller25: preload approach")


def test_binary_and_missing_config_files(tmp_path):
    path = tmp_path / "machine.toml"
    path.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(ValueError, match="not a UTF-8 text file"):
        load_config(path)
    with pytest.raises(OSError, match="cannot read config file"):
        load_config(tmp_path / "missing.toml")


def test_every_command_has_help_with_units(capsys):
    from diffguide.cli import _COMMANDS

    for command in _COMMANDS:
        with pytest.raises(SystemExit) as info:
            main([command, "--help"])
        assert info.value.code == 0
        text = capsys.readouterr().out
        assert "usage: diffguide " + command in text
        assert any(u in text for u in ("mm", "µm", "N", "µrad")), command


def test_fit_section_sets_the_structural_priors(tmp_path):
    """``[fit]`` priors reach the fit; a flag overrides the file; without either, the machine's
    own values with the documented ranges."""
    from diffguide.inverse.settings import fit_modes, structure_priors

    path = tmp_path / "m.toml"
    path.write_text(
        "[table]\nthickness_mm = 60\n[fit]\nthickness_prior_mm = [45, 30, 90]\n"
        'criterion = "gcv"\n'
    )
    cfg = load_config(path)
    assert "thickness_prior_mm = [45.0, 30.0, 90.0]" in dump_config(cfg)
    pri = structure_priors(cfg)
    assert (pri.thickness.value, pri.thickness.lo, pri.thickness.hi) == pytest.approx(
        (0.045, 0.030, 0.090))
    p0 = cfg["carriage"]["preload_fraction"]  # not in the file: the machine's, [1/4, 2]x
    assert (pri.preload.value, pri.preload.lo, pri.preload.hi) == pytest.approx(
        (p0, p0 / 4, 2 * p0))
    assert fit_modes(cfg) == ("estimate", "gcv")
    pri = structure_priors(cfg, thickness_prior_mm="50,40,70")
    assert (pri.thickness.value, pri.thickness.lo, pri.thickness.hi) == pytest.approx(
        (0.050, 0.040, 0.070))
    assert fit_modes(cfg, criterion="ml") == ("estimate", "ml")
    path.write_text('[fit]\nstructure = "fixed"\n')
    assert structure_priors(load_config(path)).active() == ()


def test_fit_section_rigid_switch(tmp_path):
    """``[fit] rigid = true`` asks for the rigid-table inversion; ``--rigid``/``--no-rigid``
    override it; the dumped file reads back the same (TOML booleans)."""
    from diffguide.inverse.settings import rigid_wanted

    path = tmp_path / "m.toml"
    path.write_text("[fit]\nrigid = true\n")
    cfg = load_config(path)
    assert cfg["fit"]["rigid"] is True
    assert rigid_wanted(cfg, None)
    assert not rigid_wanted(cfg, False)
    assert not rigid_wanted(load_config(tmp_path / "m.toml") | {"fit": {"rigid": False}})
    again = tmp_path / "again.toml"
    again.write_text(dump_config(cfg))
    assert "rigid = true" in again.read_text()
    assert load_config(again)["fit"]["rigid"] is True


def test_explain_names_each_values_source_and_reads_back(tmp_path, capsys):
    """``config --explain``: a key the file gives is 'file', a catalogue block's published C
    'catalogue, published', its calibrated conformity 'catalogue, calibrated', the rest
    'default'; the text (sources are comments) is a machine file that resolves to the same
    machine."""
    import tomllib

    from diffguide.io.config import validate_config

    path = tmp_path / "m.toml"
    path.write_text('[table]\nthickness_mm = 60.0\n[carriage]\nblock = "HIWIN-HG 25 C"\n'
                    'preload_class = "ZA"\n', encoding="utf-8")
    assert main(["config", "--explain", str(path)]) == 0
    text = capsys.readouterr().out
    lines = {ln.split(" = ")[0]: ln for ln in text.splitlines() if " = " in ln}
    assert lines["thickness_mm"].endswith("# file")
    assert lines["length_mm"].endswith("# default")
    assert "# catalogue, published: C = 26480 N" in lines["capacity_N"]
    assert "# catalogue, calibrated: radial rigidity" in lines["groove_conformity"]
    again = validate_config(tomllib.loads(text), "explained")
    want = load_config(path)
    def body(cfg):  # every value to 12 digits, without the catalogue's header comment
        return [ln for ln in dump_config(cfg).splitlines() if not ln.startswith("# carriage:")]

    assert body(again) == body(want)


@pytest.mark.parametrize("name", ['P "1"', "P.1", "a b", "ü", "back\\slash", "x=y", "#1"])
def test_explain_and_dump_quote_point_names(tmp_path, capsys, name):
    """A point name that is not a bare TOML key (quotes, a dot, a space, ...) is written as a
    quoted key: ``config --explain`` and :func:`dump_config` read back through tomllib to the
    same points."""
    import json
    import tomllib

    path = tmp_path / "m.toml"
    # json.dumps writes a TOML basic string (the same escapes) for these names
    path.write_text(f"[points]\n{json.dumps(name)} = [100.0, -50.0]\nQ = [0.0, 0.0]\n",
                    encoding="utf-8")
    want = load_config(path)["points"]
    assert set(want) == {name, "Q"}
    assert main(["config", "--explain", str(path)]) == 0
    explained = tomllib.loads(capsys.readouterr().out)
    assert explained["points"] == {k: list(v) for k, v in want.items()}
    dumped = tomllib.loads(dump_config(load_config(path)))
    assert dumped["points"] == {k: list(v) for k, v in want.items()}
