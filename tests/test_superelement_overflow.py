"""An imported reduced matrix with an entry that is not a stiffness (1e300: finite, but its
squares overflow) is refused where it is read, naming the file and the entry; the rigid-body
check fails on a NaN instead of passing it (a NaN comparison is false)."""

import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from test_superelement_readers import _dmig_small_cards, spring_3d, two_element_beam

from diffguide.cli import main
from diffguide.fe.superelement import MAX_ENTRY, ReducedMatrix, check_rigid_modes
from diffguide.io.superelement import read_dmig

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "data" / "examples" / "superelement"


def test_a_dmig_entry_of_1e300_is_refused_naming_file_and_entry(tmp_path):
    K = spring_3d(np.array([0.0, 0.6, 0.8]))
    K[2, 2] = 1e300
    dofs = [(11, 1), (11, 2), (11, 3), (12, 1), (12, 2), (12, 3)]
    p = tmp_path / "k.pch"
    p.write_text(_dmig_small_cards("KAAX", K, dofs))
    with pytest.raises(ValueError, match=r"k\.pch: K\[2,2\] \(node 11 DOF 3 and node 11 DOF 3"
                                         r"\) = 1e\+300: every entry must be finite"):
        read_dmig(p)


@pytest.mark.parametrize("value", [np.nan, np.inf, -1e300, 2 * MAX_ENTRY])
def test_reduced_matrix_refuses_non_finite_and_huge_entries(value):
    rm, _ = two_element_beam(0.0)
    K = np.array(rm.K)
    K[3, 7] = K[7, 3] = value
    with pytest.raises(ValueError, match=r"beam: K\[4,8\] \(node 1 DOF 4 and node 2 DOF 2\)"):
        ReducedMatrix(K=K, dofs=rm.dofs, f=rm.f, source="beam")
    f = np.array(rm.f)
    f[5] = value
    with pytest.raises(ValueError, match=r"beam: f\[6\] \(node 1 DOF 6\)"):
        ReducedMatrix(K=rm.K, dofs=rm.dofs, f=f, source="beam")


def test_scaling_to_si_that_overflows_is_refused():
    rm, _ = two_element_beam(0.0)
    K = np.array(rm.K) / np.abs(rm.K).max() * 1e28  # fine in the file's unit ...
    big = ReducedMatrix(K=K, dofs=rm.dofs, f=rm.f, source="beam")
    with pytest.raises(ValueError, match="at most 1e\\+30"):
        big.scaled(1e-6)  # ... a thousand times too large in SI


@pytest.mark.parametrize("value", [np.nan, 1e300])
def test_rigid_body_check_fails_on_nan_and_overflow(value):
    """Built past the constructor's check (a duck-typed matrix), the rigid-body check itself
    must not let a NaN ratio through."""
    rm, coords = two_element_beam(0.0)
    assert check_rigid_modes(rm, coords) < 1e-9  # a free beam passes
    K = np.array(rm.K)
    K[0, 0] = value
    fake = SimpleNamespace(K=K, dofs=rm.dofs, f=rm.f, source="beam")
    with pytest.raises(ValueError, match="rigid motions free"):
        check_rigid_modes(fake, coords)
    fake.K = np.zeros_like(K)
    with pytest.raises(ValueError, match="rigid motions free"):
        check_rigid_modes(fake, coords)


def test_simulate_refuses_an_imported_table_with_an_entry_of_1e300(tmp_path, capsys):
    """The issue's reproduction: the ribbed example's reactions file with one RF of 1e300;
    ``simulate`` used to pass the rigid-body check (NaN) and go on."""
    for p in EXAMPLE.glob("ribbed*"):
        shutil.copy(p, tmp_path / p.name)
    dat = tmp_path / "ribbed.dat"
    dat.write_text(dat.read_text().replace("-1.193929E+08", "1.0E+300", 1))
    cfg = (ROOT / "tests" / "data" / "calculix" / "ribbed_imported.toml").read_text()
    lines = ['file = "ribbed.toml"' if ln.startswith("file =") else ln
             for ln in cfg.splitlines()]
    (tmp_path / "machine.toml").write_text("\n".join(lines) + "\n")
    out = tmp_path / "e.csv"
    assert main(["simulate", "--config", str(tmp_path / "machine.toml"), "--positions",
                 "-300:300:3", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert str(dat) in err and "node 21619 DOF 1" in err and "5e+299" in err
    assert not out.exists()
