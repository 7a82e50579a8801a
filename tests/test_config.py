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
    import argparse

    from diffguide.cli.fit import fit_settings, structure_priors

    path = tmp_path / "m.toml"
    path.write_text(
        "[table]\nthickness_mm = 60\n[fit]\nthickness_prior_mm = [45, 30, 90]\n"
        'criterion = "gcv"\n'
    )
    cfg = load_config(path)
    assert "thickness_prior_mm = [45.0, 30.0, 90.0]" in dump_config(cfg)
    args = argparse.Namespace(structure=None, criterion=None, thickness_prior_mm=None,
                              preload_prior=None)
    pri = structure_priors(args, cfg)
    assert (pri.thickness.value, pri.thickness.lo, pri.thickness.hi) == pytest.approx(
        (0.045, 0.030, 0.090))
    p0 = cfg["carriage"]["preload_fraction"]  # not in the file: the machine's, [1/4, 2]x
    assert (pri.preload.value, pri.preload.lo, pri.preload.hi) == pytest.approx(
        (p0, p0 / 4, 2 * p0))
    assert fit_settings(args, cfg) == ("estimate", "gcv")
    args.thickness_prior_mm, args.criterion = "50,40,70", "ml"
    pri = structure_priors(args, cfg)
    assert (pri.thickness.value, pri.thickness.lo, pri.thickness.hi) == pytest.approx(
        (0.050, 0.040, 0.070))
    assert fit_settings(args, cfg) == ("estimate", "ml")
    path.write_text('[fit]\nstructure = "fixed"\n')
    assert structure_priors(argparse.Namespace(
        structure=None, criterion=None, thickness_prior_mm=None, preload_prior=None),
        load_config(path)).active() == ()


def test_fit_section_rigid_switch(tmp_path):
    """``[fit] rigid = true`` asks for the rigid-table inversion; ``--rigid``/``--no-rigid``
    override it; the dumped file reads back the same (TOML booleans)."""
    import argparse

    from diffguide.cli.fit import rigid_wanted

    path = tmp_path / "m.toml"
    path.write_text("[fit]\nrigid = true\n")
    cfg = load_config(path)
    assert cfg["fit"]["rigid"] is True
    assert rigid_wanted(argparse.Namespace(rigid=None), cfg)
    assert not rigid_wanted(argparse.Namespace(rigid=False), cfg)
    assert not rigid_wanted(argparse.Namespace(rigid=None), load_config(tmp_path / "m.toml")
                            | {"fit": {"rigid": False}})
    again = tmp_path / "again.toml"
    again.write_text(dump_config(cfg))
    assert "rigid = true" in again.read_text()
    assert load_config(again)["fit"]["rigid"] is True
