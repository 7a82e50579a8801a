"""Compensation export: the table format, and warnings exactly where the table deforms."""

import numpy as np
import pytest

from diffguide.cli import main
from diffguide.machine.kinematics import joint_errors
from diffguide.machine.majda2012 import majda2012_machine, paper_variant
from diffguide.studies.compensation import compensation_table, location_warnings, non_rigid_part

X = np.linspace(-0.35, 0.35, 15)


@pytest.fixture(scope="module")
def machine():
    return majda2012_machine(nx=10, ny=5)


def test_rigid_table_has_no_non_rigid_part(machine):
    je = joint_errors(machine.with_rigid_table(), paper_variant(3), X)
    e = je.user_units()
    for j in range(5):
        assert np.max(np.abs(non_rigid_part(e, np.asarray(je.points_xy), j))) < 1e-9
    assert location_warnings(e, je.point_names, np.asarray(je.points_xy), "P1") == []


def test_elastic_table_warns_about_roll_at_the_corners(machine):
    je = joint_errors(machine, paper_variant(2), X)
    w = location_warnings(
        je.user_units(), je.point_names, np.asarray(je.points_xy), "P5", tol_um=2.0, tol_urad=5.0
    )
    assert any(m.startswith("EAX at P1") for m in w)
    # a tolerance above every departure silences it
    assert (
        location_warnings(
            je.user_units(),
            je.point_names,
            np.asarray(je.points_xy),
            "P5",
            tol_um=1e3,
            tol_urad=1e3,
        )
        == []
    )


def test_table_text_parses_back(machine):
    je = joint_errors(machine, paper_variant(1), X)
    e = je.user_units()
    text = compensation_table(X * 1e3, e, je.point_names, "P2", "test")
    rows = [line.split() for line in text.splitlines() if not line.startswith("#")]
    assert rows[0] == ["X_mm", "EXX_um", "EYX_um", "EZX_um", "EAX_urad", "EBX_urad", "ECX_urad"]
    values = np.array(rows[1:], dtype=float)
    np.testing.assert_allclose(values[:, 0], X * 1e3, atol=1e-3)
    np.testing.assert_allclose(values[:, 1:], e[:, 1], atol=1e-4)
    with pytest.raises(ValueError, match="--at must be one of"):
        compensation_table(X * 1e3, e, je.point_names, "P9")


def test_simulate_exports_compensation(tmp_path, capsys):
    comp = tmp_path / "comp.txt"
    rc = main(
        [
            "simulate",
            "--variant",
            "2",
            "--mesh",
            "10x5",
            "--positions",
            "-300:300:5",
            "--out",
            str(tmp_path / "e.csv"),
            "--export-compensation",
            str(comp),
            "--at",
            "P5",
            "--quiet",
        ]
    )
    assert rc == 0 and comp.exists()
    assert "warning: EAX at P1" in capsys.readouterr().err
    assert (
        main(
            [
                "simulate",
                "--mesh",
                "10x5",
                "--positions",
                "-300:300:5",
                "--out",
                str(tmp_path / "f.csv"),
                "--export-compensation",
                str(comp),
                "--at",
                "Q",
            ]
        )
        == 2
    )
