"""Robustness: lift-off, reported non-convergence, random machines, the float32 guard."""

import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from diffguide.guideway.rails import BumpRail, SinusoidalRail, StraightRail
from diffguide.io.config import default_config, spec_from_config
from diffguide.machine import equilibrium, rigid_body_map
from diffguide.machine.build import build_machine
from diffguide.machine.majda2012 import majda2012_machine, paper_variant


@pytest.fixture(scope="module")
def machine():
    return majda2012_machine(nx=10, ny=5)


def total_wrench(m, state, rails, k):
    """Sum of all forces and moments on the table about the origin at position k: contact
    wrenches (elements → carriages → table), the screw's force, and gravity, the weight of the
    plate computed here from its dimensions (not from the FE load vector)."""
    x = state.positions[k]
    u = state.interface[k]
    c = m.carriage
    G = c.jacobian().reshape(-1, 6)
    F = state.forces[k].reshape(m.n_carriages, -1)
    wrenches = F @ G  # about each carriage's reference point
    ref = m.table.ref_points
    Phi = rigid_body_map(ref)  # transposed, it moves wrenches at the reference points to the origin
    w_contacts = Phi[: 6 * m.n_carriages].T @ wrenches.reshape(-1)
    screw = -m.screw_stiffness(x) * u[m.nut_dof]
    w_screw = Phi[6 * m.n_carriages :].T @ jnp.zeros(6).at[0].set(screw)
    cfg = default_config()
    t = cfg["table"]
    weight = t["density_kg_m3"] * 9.81 * t["length_mm"] * t["width_mm"] * t["thickness_mm"] * 1e-9
    w_gravity = jnp.zeros(6).at[2].set(-weight)  # at the centroid = the origin
    total = w_contacts + w_screw + w_gravity
    return np.asarray(total), weight


def test_lift_off_under_a_growing_bump(machine):
    # A vertical bump under carriage C11 (rail 1, x = −0.16 m) grows from 0 to 5× the preload
    # approach g0: the carriage is pushed up, its upper rows unload and lift off.
    g0 = float(machine.carriage.preload_approach)
    amps = np.linspace(0.0, 5 * g0, 41)
    x = jnp.array([0.0])

    def solve(a):
        rails = (BumpRail(a, -0.16, 0.03), StraightRail())
        return equilibrium(machine, rails, x)

    states = [solve(a) for a in amps]
    assert all(bool(s.converged[0]) for s in states)
    u = np.array([np.asarray(s.interface[0]) for s in states])
    # continuity: no jump larger than 3x the mean step between neighbouring amplitudes
    steps = np.linalg.norm(np.diff(u, axis=0), axis=1)
    assert steps.max() < 3 * steps.mean()
    # lifted off: at 5 g0 some elements of the carriage over the bump carry exactly nothing
    forces = np.asarray(states[-1].forces[0, 0])
    assert (forces == 0.0).sum() > 0 and np.asarray(states[0].forces[0, 0]).min() > 0
    # force balance: contacts + screw + gravity = 0 (1e-8 of the weight)
    for s in (states[0], states[20], states[-1]):
        total, weight = total_wrench(machine, s, None, 0)
        assert np.max(np.abs(total[:3])) <= 1e-8 * weight
        assert np.max(np.abs(total[3:])) <= 1e-8 * weight * 1.0  # moments (N·m), arm ~1 m
    # finite gradients all along, through lift-off
    dz = jax.vmap(jax.grad(lambda a: solve(a).interface[0, 2]))(jnp.asarray(amps))
    assert np.all(np.isfinite(np.asarray(dz)))


def test_non_convergence_is_reported_per_position(machine):
    state = equilibrium(machine, paper_variant(3), jnp.array([-0.3, 0.0, 0.3]), max_steps=1)
    assert not bool(jnp.any(state.converged))
    ok = equilibrium(machine, paper_variant(3), jnp.array([-0.3, 0.0, 0.3]))
    assert bool(jnp.all(ok.converged))


def test_cli_exits_non_zero_and_writes_nothing_on_failure(tmp_path, capsys, monkeypatch):
    import equinox as eqx

    import diffguide.machine.kinematics as kin
    from diffguide.cli import main
    from diffguide.machine import RESULTS

    real = kin.joint_errors

    def failing(machine, rails, positions, x_ref=0.0):
        """The real sweep, with the second position's result code set to a failure."""
        je = real(machine, rails, positions, x_ref)
        code = RESULTS.nonlinear_max_steps_reached._value
        bad = jnp.arange(je.positions.shape[0]) == 1
        failed = jax.tree_util.tree_map(lambda v: jnp.where(bad, code, v), je.result)
        return eqx.tree_at(lambda j: j.result, je, failed)

    monkeypatch.setattr(kin, "joint_errors", failing)
    out = tmp_path / "e.csv"
    rc = main(
        ["simulate", "--positions", "-300:300:3", "--mesh", "10x5", "--out", str(out), "--quiet"]
    )
    assert rc != 0 and not out.exists()
    err = capsys.readouterr().err
    assert "did not converge at 0 mm" in err


# ---------------------------------------------------------------------------------------------
# random machines


def random_machine_case(draw):
    cfg = default_config()
    length = draw(st.floats(700.0, 1500.0))
    width = draw(st.floats(400.0, 800.0))
    cfg["table"].update(
        length_mm=length,
        width_mm=width,
        thickness_mm=draw(st.floats(30.0, 120.0)),
        mesh_nx=8,
        mesh_ny=4,
    )
    rail = draw(st.floats(0.25, 0.4)) * width
    spacing = draw(st.floats(0.2, 0.5)) * length
    cfg["guideway"].update(rail_y_mm=(-rail, rail), carriage_x_mm=(-spacing / 2, spacing / 2))
    cfg["carriage"].update(
        preload_fraction=draw(st.sampled_from([0.02, 0.08, 0.13])),
        elements_per_row=draw(st.integers(6, 16)),
    )
    cfg["points"] = {"A": (0.4 * length, 0.4 * width), "B": (-0.4 * length, -0.4 * width)}
    cfg["screw"]["free_length_at_ref_mm"] = length
    cfg["machine"]["stroke_mm"] = 0.6 * length
    amp = draw(st.floats(0.0, 30.0)) * 1e-6
    lam = draw(st.floats(0.1, 1.5))
    phase = draw(st.floats(0.0, 6.28))
    return cfg, amp, lam, phase


@st.composite
def machine_cases(draw):
    return random_machine_case(draw)


def check_random_machine(case):
    cfg, amp, lam, phase = case
    m = build_machine(spec_from_config(cfg))
    rails = (
        SinusoidalRail(amp, lam, phase),
        SinusoidalRail(0.5 * amp, 0.7 * lam, 0.0, "horizontal"),
    )
    half = cfg["machine"]["stroke_mm"] / 2e3
    x = jnp.linspace(-half, half, 5)
    state = equilibrium(m, rails, x)
    conv = np.asarray(state.converged)
    assert np.all(np.isfinite(np.asarray(state.interface)[conv]))
    worst = 0.0
    for k in np.flatnonzero(conv):
        total, weight = total_wrench_cfg(m, state, k, cfg)
        worst = max(worst, float(np.max(np.abs(total)) / weight))
    grad = jax.grad(
        lambda a: jnp.sum(equilibrium(m, (SinusoidalRail(a, lam, phase), rails[1]), x).interface)
    )(amp)
    assert np.isfinite(float(grad))
    return bool(conv.all()), worst


def total_wrench_cfg(m, state, k, cfg):
    t = cfg["table"]
    x = state.positions[k]
    u = state.interface[k]
    G = m.carriage.jacobian().reshape(-1, 6)
    F = state.forces[k].reshape(m.n_carriages, -1)
    Phi = rigid_body_map(m.table.ref_points)
    w = Phi[: 6 * m.n_carriages].T @ (F @ G).reshape(-1)
    w = w + Phi[6 * m.n_carriages :].T @ jnp.zeros(6).at[0].set(
        -m.screw_stiffness(x) * u[m.nut_dof]
    )
    weight = t["density_kg_m3"] * 9.81 * t["length_mm"] * t["width_mm"] * t["thickness_mm"] * 1e-9
    return np.asarray(w.at[2].add(-weight)), weight


@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(machine_cases())
def test_random_machines_converge_balance_and_have_finite_gradients(case):
    converged, worst = check_random_machine(case)
    assert converged
    assert worst <= 1e-8


@pytest.mark.slow
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(machine_cases())
def test_random_machines_large_run(case):
    converged, worst = check_random_machine(case)
    print(f"RANDOM-MACHINE converged={converged} worst_balance={worst:.2e}")
    assert converged and worst <= 1e-8


# ---------------------------------------------------------------------------------------------
# the float32 guard

GUARD = """
import jax.numpy as jnp
from diffguide.guideway import majda2012_carriage
from diffguide.guideway.solve import solve_carriage
try:
    solve_carriage(majda2012_carriage(), jnp.zeros(6))
except RuntimeError as exc:
    print("GUARD:", exc)
"""


def test_float32_guard_raises_a_clear_error():
    out = subprocess.run([sys.executable, "-c", GUARD], capture_output=True, text=True, timeout=300)
    assert "GUARD:" in out.stdout
    assert "float64" in out.stdout and "enable_x64" in out.stdout
