"""Sizes that would run the machine out of memory are refused before anything of that size is
allocated, with a message naming the option or file, the value and the allowed range (exit 2):
positions, prediction rows, Monte Carlo samples, an imported matrix's DOF, a fit's mesh."""

import json

import numpy as np
import pytest

from diffguide._core.limits import MAX_POSITIONS, MAX_REDUCED_DOFS, MAX_SAMPLES
from diffguide.cli import main
from diffguide.io.superelement import read_dmig, read_user_element_matrix


def _err(capsys) -> str:
    """The one error line (no traceback); the hand-written posterior files below are of
    format 1 (no checksum), whose reader's warning line is set aside."""
    lines = [ln for ln in capsys.readouterr().err.splitlines()
             if "written by an older diffguide (format 1" not in ln]
    assert len(lines) == 1, lines
    return lines[0] + "\n"


def test_simulate_refuses_a_million_positions(tmp_path, capsys):
    out = tmp_path / "e.csv"
    assert main(["simulate", "--positions", "-350:350:1000000", "--out", str(out)]) == 2
    err = _err(capsys)
    assert "--positions -350:350:1000000" in err and f"2..{MAX_POSITIONS}" in err
    assert "1000000" in err and not out.exists()


def test_montecarlo_refuses_its_former_maximum(tmp_path, capsys):
    assert main(["montecarlo", "--samples", "10000000", "--out", str(tmp_path / "m.csv")]) == 2
    err = _err(capsys)
    assert "--samples" in err and f"1..{MAX_SAMPLES}" in err and "10000000" in err


def test_montecarlo_refuses_rails_that_do_not_fit_in_memory(tmp_path, capsys):
    """--corr-mm 1: 4 800 spline coefficients per rail and plane, 150 kB of rails a sample."""
    assert main(["montecarlo", "--samples", "1000000", "--corr-mm", "1", "--mesh", "6x3",
                 "--out", str(tmp_path / "m.csv"), "-q"]) == 2
    err = _err(capsys)
    assert "--samples 1000000 with --corr-mm 1" in err and "allowed up to" in err
    assert not (tmp_path / "m.csv").exists()


# --- predict, from a small hand-written posterior.json -----------------------------------------

def _posterior(folder, nx=6, ny=3, n=8):
    n_v = 4 * n
    data = {
        "format": "diffguide fit posterior 1", "units": "SI",
        "knots": {"start_m": -0.6, "spacing_m": 1.2 / (n - 3), "n": n},
        "coeffs_m": np.zeros((2, 2, n)).tolist(), "cov": (np.eye(n_v) * 1e-12).tolist(),
        "structure": {}, "lead_m": [], "lead_knots": [], "position_range_m": [-0.3, 0.3],
        "rigid": False, "x_ref_m": 0.0, "points_m": {"P1": [0.1, 0.1]},
        "machine": {"preset": "majda2012", "config": None, "nx": nx, "ny": ny}, "x0_mm": 0.0,
    }
    folder.mkdir(exist_ok=True)
    (folder / "posterior.json").write_text(json.dumps(data))
    return folder


def _predict(fit, *extra):
    return ["predict", "--fit", str(fit), "--point", "Q:0,0", *extra]


def test_predict_refuses_1e8_positions_before_any_allocation(tmp_path, capsys):
    fit, out = _posterior(tmp_path / "fit"), tmp_path / "p.csv"
    assert main(_predict(fit, "--positions-mm=-100:100:100000000", "--out", str(out))) == 2
    err = _err(capsys)
    assert "--positions-mm -100:100:100000000" in err and f"2..{MAX_POSITIONS}" in err
    assert not out.exists()


def test_predict_refuses_positions_times_points_beyond_its_memory(tmp_path, capsys):
    fit = _posterior(tmp_path / "fit")
    points = [a for k in range(8) for a in ("--point", f"Q{k}:{k * 10},0")]
    assert main(["predict", "--fit", str(fit), *points, "--positions-mm=-100:100:100000",
                 "--out", str(tmp_path / "p.csv")]) == 2
    err = _err(capsys)
    assert "--positions-mm -100:100:100000: 100000 positions x 9 points" in err
    assert "allowed: positions x points up to" in err


def test_predict_refuses_a_positions_file_that_is_too_long(tmp_path, capsys):
    fit = _posterior(tmp_path / "fit")
    pos = tmp_path / "pos.csv"
    pos.write_text("position_mm\n" + "0\n" * (MAX_POSITIONS + 1))
    assert main(_predict(fit, "--positions", str(pos), "--out", str(tmp_path / "p.csv"))) == 2
    err = _err(capsys)
    assert f"{pos}:{MAX_POSITIONS + 2}: more than {MAX_POSITIONS} positions" in err


def test_predict_refuses_a_posterior_claiming_a_5000_x_5000_mesh(tmp_path, capsys):
    fit = _posterior(tmp_path / "fit", nx=5000, ny=5000)
    assert main(_predict(fit, "--out", str(tmp_path / "p.csv"))) == 2
    err = _err(capsys)
    assert str(fit / "posterior.json") in err and "machine.nx" in err and "1..200" in err
    assert "5000" in err


@pytest.mark.parametrize("mesh", ["5000x5000", "201x10"])
def test_mesh_option_is_bounded(tmp_path, capsys, mesh):
    assert main(["fit", "--measurements", "x.csv", "--mesh", mesh, "--out",
                 str(tmp_path / "o")]) == 2
    err = _err(capsys)
    assert "--mesh" in err and "1..200" in err and mesh in err


# --- imported matrices -------------------------------------------------------------------------

def _card(*fields):
    return "".join(f"{f:<8}" for f in fields)


def test_a_40000_dof_dmig_is_refused_before_its_matrix_exists(tmp_path):
    """Its diagonal alone (a small file) would make a 12.8 GB dense matrix."""
    n = 40_000
    lines = [_card("DMIG", "K", "0", "6", "2")]
    lines += [_card("DMIG", "K", str(g), "1", "", str(g), "1", "1.0") for g in range(1, n + 1)]
    p = tmp_path / "big.pch"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=rf"big\.pch:\d+: {n} retained DOF: allowed "
                                         rf"1\.\.{MAX_REDUCED_DOFS}"):
        read_dmig(p)


def test_a_user_element_claiming_a_million_nodes_is_refused(tmp_path):
    p = tmp_path / "big.mtx"
    p.write_text("*USER ELEMENT, NODES=1000000, LINEAR\n** ELEMENT NODES\n** 1\n1\n")
    with pytest.raises(ValueError, match=r"big\.mtx:1: NODES=1000000: at most 5000"):
        read_user_element_matrix(p)
