"""Typed machine specification, the one CSV reader for rail files, the rigid transfer, the knot
grid and solver result codes."""

import dataclasses
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide import presets
from diffguide._core.rigid import rigid_transfer, skew, transfer
from diffguide.guideway.rails import SplineRail, knot_centres, knot_grid
from diffguide.io.config import config_from_spec, default_config, dump_config, spec_from_config
from diffguide.io.rails_csv import rails_at, read_rails_csv, read_rails_samples
from diffguide.machine import RESULTS

ROOT = Path(__file__).resolve().parents[1]


def test_spec_round_trips_through_the_configuration():
    spec = presets.majda2012()
    cfg = config_from_spec(spec)
    assert cfg == default_config()
    back = spec_from_config(cfg)
    # the material's label is the only thing a configuration does not carry
    back = eqx.tree_at(lambda s: s.table.material, back, spec.table.material)
    assert eqx.tree_equal(back, spec)
    assert "thickness_mm = 50.0" in dump_config(cfg)


def test_build_machine_takes_only_a_spec():
    """One way to build a machine: a configuration dictionary (diffguide 0.1) is refused before
    anything is built, with the two ways to a spec named."""
    from diffguide.machine.build import build_machine

    with pytest.raises(TypeError, match=r"spec_from_config\(cfg\).*presets\.majda2012\(\)"):
        build_machine(default_config(), nx=2, ny=2)


def test_error_units_are_the_iso_names_in_micrometres_and_microradians():
    from diffguide.machine.errors import ERROR_UNITS, error_columns, to_user
    from diffguide.machine.kinematics import ERROR_NAMES

    assert ERROR_NAMES == ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX")
    assert ERROR_UNITS == ("um",) * 3 + ("urad",) * 3
    assert error_columns()[0] == "EXX_um" and error_columns("_sd")[5] == "ECX_sd_urad"
    np.testing.assert_array_equal(to_user(np.full((2, 6), 1e-6)), np.ones((2, 6)))


def test_spec_fields_can_be_traced_and_replaced():
    spec = presets.majda2012()
    f = jax.jit(lambda t: eqx.tree_at(lambda s: s.table.thickness, spec, t).table.thickness * 2)
    assert float(f(0.06)) == pytest.approx(0.12)
    with pytest.raises(ValueError, match="law"):
        dataclasses.replace(spec.carriage, law="magic")
    with pytest.raises(ValueError, match="off the table"):
        dataclasses.replace(spec, points={"P9": (0.9, 0.0)})


def test_bundled_truth_loads_as_simulate_rails():
    path = ROOT / "data" / "majda2012_truth.csv"
    samples = read_rails_samples(path)  # a '#' comment line, then the header
    rails = read_rails_csv(path)
    for r, rail in enumerate(rails, start=1):
        s, v, h = samples[r].T
        ey, ez = (np.asarray(a) for a in rail(jnp.asarray(s)))
        np.testing.assert_allclose(ez, v, atol=1e-9 * max(np.abs(v).max(), 1e-6))
        np.testing.assert_allclose(ey, h, atol=1e-9 * max(np.abs(h).max(), 1e-6))
    at = rails_at(path, samples[1][:5, 0])
    np.testing.assert_array_equal(at[0, 0], samples[1][:5, 1])


def test_rails_csv_errors_name_file_and_line(tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("# comment\nrail,s_mm,vertical_um,horizontal_um\n1,0,1,x\n")
    with pytest.raises(ValueError, match=r"r\.csv:3: field 'horizontal_um'"):
        read_rails_csv(path)


def test_rigid_transfer_is_the_rigid_motion_of_a_body():
    rng = np.random.default_rng(0)
    t, theta = rng.normal(size=3), rng.normal(size=3) * 1e-3
    a, b = rng.normal(size=3), rng.normal(size=3)
    # a small rigid motion (t, θ) about the origin moves every point p by t + θ × p
    at_a = np.concatenate([t + np.cross(theta, a), theta])
    at_b = np.concatenate([t + np.cross(theta, b), theta])
    np.testing.assert_allclose(transfer(at_a, b - a), at_b, atol=1e-15)
    np.testing.assert_allclose(
        np.asarray(rigid_transfer(jnp.asarray(b - a))) @ at_a, at_b, atol=1e-15
    )
    np.testing.assert_allclose(np.asarray(skew(jnp.asarray(a))) @ b, np.cross(a, b), atol=1e-15)


def test_knot_grid_covers_and_reproduces_lines():
    start, h, n = knot_grid(-0.53, 0.53, 0.048)
    assert start + (n - 3) * h >= 0.53 > start + (n - 4) * h
    line = lambda s: 2e-6 + 3e-6 * s  # noqa: E731
    rail = SplineRail(start, h, jnp.asarray(line(knot_centres(start, h, n))), jnp.zeros(n))
    s = np.linspace(-0.5, 0.5, 7)
    np.testing.assert_allclose(np.asarray(rail(jnp.asarray(s))[1]), line(s), atol=1e-18)


def test_solver_result_codes_and_throw():
    from diffguide.guideway import majda2012_carriage, solve_carriage

    c = majda2012_carriage()
    ok = solve_carriage(c, jnp.array([0.0, 0.0, -500.0, 0.0, 0.0, 0.0]), throw=True)
    assert ok.result == RESULTS.successful
    few = solve_carriage(c, jnp.array([0.0, 0.0, -500.0, 0.0, 0.0, 0.0]), max_steps=1)
    assert few.result == RESULTS.nonlinear_max_steps_reached
    bad = solve_carriage(c, jnp.array([0.0, 0.0, jnp.nan, 0.0, 0.0, 0.0]))
    assert bad.result == RESULTS.nonfinite
    with pytest.raises(Exception, match="steps"):
        solve_carriage(c, jnp.array([0.0, 0.0, -500.0, 0.0, 0.0, 0.0]), max_steps=1, throw=True)
