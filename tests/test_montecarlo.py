"""Batched sweeps: equal to one-at-a-time ``joint_errors`` (1e-10 relative), chunking and padding,
batched machines, sharding over two (forced) CPU devices, statistics, the rail-offset gauge, and
the ``montecarlo`` command."""

import argparse
import csv
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from diffguide.machine.kinematics import joint_errors
from diffguide.machine.majda2012 import majda2012_machine
from diffguide.studies.montecarlo import (
    MonteCarloResult,
    batched_sweep,
    default_corners,
    stack_machines,
)
from diffguide.studies.random_rails import (
    GaussianRailModel,
    RailBatch,
    default_knots,
    linear_coefficients,
    sample_rails,
)

POSITIONS = np.linspace(-0.35, 0.35, 11)
CHUNK = 4
EAX = 3


@pytest.fixture(scope="module")
def machine():
    return majda2012_machine(nx=10, ny=5)


@pytest.fixture(scope="module")
def batch():
    # straightness in both planes plus the loosest catalogue mounting class: large, varied loads
    return sample_rails(2024, 6, GaussianRailModel(5e-6, 0.2), "size25-ZO")


@pytest.fixture(scope="module")
def result(machine, batch):
    # 6 samples in chunks of 4: two chunks, the second one padded
    return batched_sweep(machine, batch, POSITIONS, chunk_size=CHUNK, keep_errors=True)


def _assert_close(batched, single, rtol=1e-10):
    # relative to the largest value of each error curve type (elementwise relative error is
    # meaningless at the zero crossings)
    scale = np.abs(single).max(axis=(0, 1))
    assert np.all(scale > 0)
    np.testing.assert_array_less(np.abs(batched - single).max(axis=(0, 1)), rtol * scale)


def test_batched_equals_one_at_a_time(machine, batch, result):
    assert result.converged.all()
    assert result.errors.shape == (6, 11, 5, 6)
    for i in range(len(batch)):
        je = joint_errors(machine, batch.rails(i), POSITIONS)
        assert bool(np.all(je.converged))
        _assert_close(result.errors[i], np.asarray(je.errors))


def test_statistics(result):
    e = result.errors
    np.testing.assert_allclose(result.ranges, np.ptp(e, axis=1), rtol=1e-13, atol=1e-18)
    assert result.pairs == (("P1", "P2"), ("P1", "P3"), ("P1", "P4"), ("P2", "P3"),
                            ("P2", "P4"), ("P3", "P4"))
    names = result.point_names
    for q, (a, b) in enumerate(result.pairs):
        d = e[:, :, names.index(a), EAX] - e[:, :, names.index(b), EAX]
        np.testing.assert_allclose(result.roll_difference[:, q], np.abs(d).max(axis=1),
                                   rtol=1e-13, atol=1e-18)
    np.testing.assert_allclose(result.max_roll_difference, result.roll_difference.max(axis=1))
    # the roll ranges at the corners differ (the elastic table) and are µrad-sized
    assert np.all(result.max_roll_difference > 1e-7)


def test_summary_only_matches_kept(machine, batch, result):
    # without keep_errors the same statistics come back, and no curves
    r = batched_sweep(machine, batch[:3], POSITIONS, chunk_size=CHUNK)
    assert r.errors is None
    np.testing.assert_array_equal(r.ranges, result.ranges[:3])
    np.testing.assert_array_equal(r.roll_difference, result.roll_difference[:3])
    assert r.stats["chunk_size"] == 3 and r.stats["n_devices"] == 1


def test_columns_and_csv(result):
    cols = result.columns()
    assert list(cols)[:3] == ["sample", "converged", "EXX_range_P1_um"]
    assert "EAX_range_P3_urad" in cols and "roll_diff_P2_P4_urad" in cols
    np.testing.assert_allclose(cols["roll_diff_max_urad"], result.max_roll_difference * 1e6)
    rows = list(csv.DictReader(result.to_csv().splitlines()))
    assert len(rows) == 6
    assert float(rows[2]["ECX_range_P5_urad"]) == pytest.approx(result.ranges[2, 4, 5] * 1e6,
                                                              rel=1e-5)


def test_rail_offset_is_invisible_but_slope_difference_is_not(machine):
    # a constant offset of rail 2 leaves every relative error unchanged; a slope difference
    # between the rails does not (the gauge: joint errors are relative)
    start, spacing, n = default_knots()
    zero = np.zeros(n)
    offset = linear_coefficients(start, spacing, n, 20e-6, 20e-6)
    slope = linear_coefficients(start, spacing, n, -10e-6, 10e-6)
    v = np.stack([np.stack([zero, zero]), np.stack([zero, offset]), np.stack([zero, slope]),
                  np.stack([zero, zero])])
    h = np.stack([np.stack([zero, zero]), np.stack([zero, offset]), np.stack([zero, zero]),
                  np.stack([zero, slope])])
    r = batched_sweep(machine, RailBatch(start, spacing, v, h), POSITIONS, chunk_size=CHUNK)
    assert r.converged.all()
    um = r.ranges * 1e6
    np.testing.assert_allclose(um[1], um[0], atol=1e-6)  # offset: identical to straight rails
    assert um[2].max() > 1.0  # vertical slope difference: the table rolls with x
    assert um[2][:, EAX].min() > 10.0
    assert um[3].max() > 0.1  # horizontal: the rails squeeze the carriages across


def test_batched_machines(machine, batch):
    machines = [machine, majda2012_machine(nx=10, ny=5, preload_fraction=0.04)]  # 8 %, 4 % C
    stacked = stack_machines(machines)
    r = batched_sweep(stacked, batch[:2], POSITIONS, chunk_size=CHUNK, machine_batched=True,
                      keep_errors=True)
    for i in range(2):
        _assert_close(r.errors[i], np.asarray(joint_errors(machines[i], batch.rails(i),
                                                           POSITIONS).errors))
    with pytest.raises(ValueError, match="leading axis"):
        batched_sweep(stacked, batch[:3], POSITIONS, machine_batched=True)


def test_default_corners(machine):
    assert default_corners(machine) == ("P1", "P2", "P3", "P4")


def test_bad_arguments(machine, batch):
    with pytest.raises(ValueError, match="RailBatch"):
        batched_sweep(machine, batch.rails(0), POSITIONS)
    with pytest.raises(ValueError, match="corners"):
        batched_sweep(machine, batch, POSITIONS, corners=("P1", "P9"))
    with pytest.raises(ValueError, match="chunk_size"):
        batched_sweep(machine, batch, POSITIONS, chunk_size=0)


_SHARDED = textwrap.dedent(
    """
    import jax, numpy as np
    jax.config.update("jax_enable_x64", True)
    from diffguide.cli._study_options import split_cpu_into_devices
    from diffguide.studies.montecarlo import batched_sweep
    assert split_cpu_into_devices(2)  # before the first array
    from diffguide.machine.majda2012 import majda2012_machine
    from diffguide.studies.random_rails import GaussianRailModel, sample_rails
    assert len(jax.devices()) == 2, jax.devices()
    m = majda2012_machine(nx=10, ny=5)
    b = sample_rails(5, 5, GaussianRailModel(5e-6, 0.2), "size25-ZB")
    x = np.linspace(-0.35, 0.35, 11)
    two = batched_sweep(m, b, x, chunk_size=3, keep_errors=True)  # rounded up to 4, padded
    one = batched_sweep(m, b, x, chunk_size=4, keep_errors=True, devices=jax.devices()[:1])
    assert two.stats["n_devices"] == 2 and two.stats["chunk_size"] == 4, two.stats
    assert two.converged.all() and one.converged.all()
    scale = np.abs(one.errors).max(axis=(0, 1, 2))
    err = np.abs(two.errors - one.errors).max(axis=(0, 1, 2)) / scale
    assert np.all(err < 1e-10), err
    print("OK", err.max())
    """
)


def test_sharded_over_two_cpu_devices(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    script = tmp_path / "sharded.py"
    script.write_text(_SHARDED)
    out = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "OK" in out.stdout


def test_split_cpu_is_a_no_op_once_jax_runs(machine):
    from diffguide.cli._study_options import split_cpu_into_devices

    before = os.environ.get("XLA_FLAGS")
    assert split_cpu_into_devices(2) is False  # the backends are up: too late, nothing changed
    assert os.environ.get("XLA_FLAGS") == before


def _cli(argv):
    from diffguide.cli import montecarlo

    parser = argparse.ArgumentParser()
    montecarlo.add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["montecarlo", *argv])
    return args.func(args)


def test_cli(tmp_path, capsys):
    out, png = tmp_path / "mc.csv", tmp_path / "mc.png"
    argv = ["--samples", "5", "--mesh", "10x5", "--chunk", str(CHUNK), "--positions=-350:350:11",
            "--rail-rms-um", "5", "--corr-mm", "200", "--mounting", "size25-ZA",
            "--out", str(out), "--plot", str(png)]
    assert _cli(argv) == 0
    err = capsys.readouterr().err
    assert "5/5 samples" in err and "largest roll difference" in err
    rows = list(csv.DictReader(out.read_text().splitlines()))
    assert len(rows) == 5 and all(r["converged"] == "1" for r in rows)
    assert float(rows[0]["roll_diff_max_urad"]) > 0
    assert png.stat().st_size > 10_000
    # the same seed gives the same file; --quiet prints nothing
    first = out.read_text()
    assert _cli(argv[:-2] + ["--quiet"]) == 0
    assert capsys.readouterr().err == ""
    assert out.read_text() == first


@pytest.mark.parametrize(
    "argv, match",
    [
        (["--samples", "0"], "--samples"),
        (["--corr-mm", "0"], "--corr-mm"),
        (["--rail-rms-um", "-1"], "--rail-rms-um"),
        (["--positions=-400:400:5"], "stroke"),
        (["--cpu-devices", "0"], "--cpu-devices"),
    ],
)
def test_cli_bad_arguments(tmp_path, argv, match):
    with pytest.raises(ValueError, match=match):
        _cli([*argv, "--mesh", "10x5", "--out", str(tmp_path / "x.csv")])


def test_result_without_corners():
    r = MonteCarloResult(np.zeros(2), 0.0, ("A",), (), np.zeros((3, 1, 6)), np.zeros((3, 0)),
                         np.ones(3, bool), None, {})
    assert "roll_diff_max_urad" not in r.columns()
    np.testing.assert_array_equal(r.max_roll_difference, 0)
