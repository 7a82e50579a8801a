"""``diffguide table`` end to end, and the preset table against a hand estimate."""

import csv

import numpy as np
import pytest

from diffguide.cli import main


def test_table_command_writes_plot_and_csv(tmp_path, capsys):
    png, out = tmp_path / "table.png", tmp_path / "nodes.csv"
    rc = main(["table", "--preset", "majda2012", "--mesh", "10x5", "--plot", str(png),
               "--out", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "max sag under gravity" in text and "µm" in text
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    rows = list(csv.DictReader(out.open()))
    uz = np.array([float(r["uz_um"]) for r in rows])
    sag = float(text.split("max sag under gravity:")[1].split("µm")[0])
    assert sag == pytest.approx(-uz.min(), abs=1e-3)  # printed to 3 decimals
    # order of magnitude: the 310 mm overhang beyond the carriages as a cantilever plate strip,
    # w = q L⁴ / 8 D (q = ρ g t, D = E t³ / 12 (1 - ν²)) ≈ 2.3 µm; the table also rotates at the
    # carriages, so the corner sag is larger but of the same order
    from diffguide.presets import majda2012

    t = majda2012().table.thickness
    q, L, D = 7200 * 9.81 * t, 0.31, 110e9 * t**3 / 12 / (1 - 0.26**2)
    w_cant = q * L**4 / (8 * D) * 1e6
    assert w_cant < sag < 3 * w_cant


def test_table_command_rejects_bad_mesh(capsys):
    assert main(["table", "--mesh", "0x5"]) == 2
    assert "--mesh" in capsys.readouterr().err


def test_table_command_caches_its_table_only_when_asked_and_only_while_it_runs(tmp_path):
    """``--cache-dir``: the condensed table is written to ``<dir>/tables`` and read back by the
    next run (the same numbers); the caches are the command's own (none active afterwards), and
    ``--no-cache`` writes nothing."""
    from diffguide._core.caches import active_caches

    cache = tmp_path / "cache"
    outs = []
    for k in range(2):
        out = tmp_path / f"nodes{k}.csv"
        args = ["table", "--mesh", "6x3", "--out", str(out), "--quiet"]
        assert main([*args, "--cache-dir", str(cache)]) == 0
        assert active_caches() is None
        outs.append(out.read_text())
        assert len(list((cache / "tables").glob("*.npz"))) == 1
    assert outs[0] == outs[1]
    other = tmp_path / "other"
    out = tmp_path / "nodes_nc.csv"
    assert main(["table", "--mesh", "6x3", "--out", str(out), "--quiet",
                 "--cache-dir", str(other), "--no-cache"]) == 0
    assert out.read_text() == outs[0] and not list(other.rglob("*.npz"))
