"""Design with gradients (:mod:`diffguide.studies.design`, ``diffguide design``).

The per-sample derivatives w.r.t. thickness and carriage spacing against central differences
of *rebuilt* machines (the spacing by a new ``carriage_x``, the mesh rebuilt around it), and
w.r.t. preload and the table's modulus against machines built with the perturbed value; the
objective's gradient (mean, Harrell–Davis percentile) against central differences of the same
statistic; the Harrell–Davis weights against their closed form; the spacing range against
rebuilt meshes; the optimum of two problems (one at an active mass constraint, one with an
interior optimum) against brute-force grids over rebuilt machines; the sweep sharded over two
devices; bad input; the command line.

One mesh (10 × 5), five positions, eight samples and the same two variables throughout, so that
the traced build and sweep compile once for the module."""

import dataclasses
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import equinox as eqx
import numpy as np
import pytest

from diffguide.cli import main
from diffguide.io.config import default_config, spec_from_config
from diffguide.jobs.design import CONSTRAINT_UNITS, VARIABLE_UNITS, parse_vary
from diffguide.machine.build import build_machine, with_overrides
from diffguide.studies.design import (
    Objective,
    design,
    design_knots,
    harrell_davis_weights,
    paired_improvement,
    parse_objective,
    statistic,
)
from diffguide.studies.design_space import (
    CONSTRAINTS,
    MIN_GAP,
    VARIABLES,
    check_bounds,
    parse_constraint,
    table_mass,
)
from diffguide.studies.design_sweep import DesignSweep
from diffguide.studies.montecarlo import batched_sweep
from diffguide.studies.random_rails import GaussianRailModel, sample_rails
from diffguide.studies.tolerance import measure_values

ROOT = Path(__file__).resolve().parents[1]
SPEC = with_overrides(spec_from_config(default_config()), nx=10, ny=5)
X = np.linspace(-0.3, 0.3, 5)
NAMES = ("thickness", "carriage_spacing")
X0 = np.array([0.05, 0.30])
N = 8


@pytest.fixture(scope="module")
def rails():
    return sample_rails(0, N, GaussianRailModel(1e-6, 0.2))


@pytest.fixture(scope="module")
def sweep(rails):
    return DesignSweep(SPEC, NAMES, rails, X, "roll_difference", x0=X0, chunk_size=N)


def rebuilt(thickness, spacing):
    """The machine rebuilt from its specification: the carriages at ±spacing/2, no traced
    spacing (the mesh lines put where the new footprints are)."""
    g = dataclasses.replace(SPEC.guideway, carriage_x=(-spacing / 2, spacing / 2))
    spec = eqx.tree_at(lambda s: s.guideway, SPEC, g)
    return build_machine(spec, thickness=thickness)


def measures(rails, x, measure="roll_difference"):
    return measure_values(batched_sweep(rebuilt(*x), rails, X, chunk_size=N), measure)


@pytest.fixture(scope="module")
def differences(rails):
    """Central differences (relative step 1e-5) of the rebuilt machines' measures."""
    out = []
    for j in range(2):
        h = 1e-5 * X0[j]
        e = np.eye(2)[j] * h
        out.append((measures(rails, X0 + e), measures(rails, X0 - e), h))
    return out


def test_derivatives_match_central_differences_of_rebuilt_machines(sweep, rails, differences):
    m, dm, ok = sweep(X0)
    assert ok.all()
    np.testing.assert_allclose(m, measures(rails, X0), rtol=1e-9)
    for j, (plus, minus, h) in enumerate(differences):
        fd = (plus - minus) / (2 * h)
        np.testing.assert_allclose(dm[:, j], fd, rtol=1e-4, atol=1e-6 * np.max(np.abs(fd)))


def test_preload_and_modulus_derivatives_match_central_differences(rails):
    """The other two variables: each rebuilt with the perturbed value (roll range at P1)."""
    x0 = np.array([0.06, 110e9])
    names = ("preload_fraction", "E")
    sw = DesignSweep(SPEC, names, rails, X, "range:EAX:P1", x0=x0, chunk_size=N)
    m, dm, ok = sw(x0)
    assert ok.all()

    def at(x):
        machine = build_machine(SPEC, preload_fraction=x[0], E=x[1])
        return measure_values(batched_sweep(machine, rails, X, chunk_size=N), "range:EAX:P1")

    np.testing.assert_allclose(m, at(x0), rtol=1e-9)
    for j in range(2):
        e = np.eye(2)[j] * 1e-5 * x0[j]
        fd = (at(x0 + e) - at(x0 - e)) / (2e-5 * x0[j])
        np.testing.assert_allclose(dm[:, j], fd, rtol=1e-4, atol=1e-6 * np.max(np.abs(fd)))


@pytest.mark.parametrize("stat", ["mean", "p60"])
def test_objective_gradient_matches_central_differences(sweep, rails, differences, stat):
    obj = Objective("roll_difference", stat)
    m, dm, ok = sweep(X0)
    _, g = statistic(obj, m, dm, ok)
    for j, (plus, minus, h) in enumerate(differences):
        f = [statistic(obj, v, None, np.ones(N, bool))[0].value for v in (plus, minus)]
        assert g[j] == pytest.approx((f[0] - f[1]) / (2 * h), rel=1e-4)


def test_harrell_davis_weights_closed_form():
    """n = 3, p = 1/2: a = b = 2, I_x(2, 2) = 3x² − 2x³, so w = (7, 13, 7)/27."""
    np.testing.assert_allclose(harrell_davis_weights(3, 0.5), np.array([7, 13, 7]) / 27)
    w = harrell_davis_weights(200, 0.9)
    assert w.sum() == pytest.approx(1.0) and np.argmax(w) in range(175, 185)


def test_intervals():
    rng = np.random.default_rng(3)
    b = rng.normal(10.0, 1.0, 400)
    a = b - 0.5 + rng.normal(0.0, 0.1, 400)
    ok = np.ones(400, bool)
    est, _ = statistic(Objective("roll_difference", "mean"), b, None, ok)
    half = 1.959963984540054 * b.std(ddof=1) / 20
    assert est.interval == pytest.approx((b.mean() - half, b.mean() + half))
    mean = paired_improvement(Objective("roll_difference", "mean"), b, a, ok)
    assert mean.interval[0] < 0.5 < mean.interval[1] and mean.interval[1] - mean.interval[0] < 0.05
    p90 = paired_improvement(Objective("roll_difference", "p90"), b, a, ok)
    assert p90.interval[0] < 0.5 < p90.interval[1]


@pytest.mark.parametrize("name, nominal", [("carriage_spacing", 0.32), ("rail_spacing", 0.34)])
def test_spacing_range_is_where_the_mesh_keeps_its_topology(name, nominal):
    lo, hi = VARIABLES[name].bounds(SPEC)
    assert lo < nominal < hi
    for s in (lo, hi):
        build_machine(SPEC, **{name: s})  # valid at both ends
    for s in (hi + 3 * MIN_GAP, lo - 3 * MIN_GAP):
        with pytest.raises(Exception, match=f"{name} = .* moves a footprint's grid line"):
            build_machine(SPEC, **{name: s})


def test_rail_spacing_derivative_matches_central_differences_of_rebuilt_machines(rails):
    """The rails moved apart: rebuilt with ``rail_y = ±s/2`` (mesh lines where the new
    footprints are), against the design sweep's forward-mode derivative (roll range at P1)."""
    s0 = 0.34
    sw = DesignSweep(SPEC, ("rail_spacing",), rails, X, "range:EAX:P1", x0=np.array([s0]),
                     chunk_size=N)
    m, dm, ok = sw(np.array([s0]))
    assert ok.all()

    def at(s):
        g = dataclasses.replace(SPEC.guideway, rail_y=(-s / 2, s / 2))
        machine = build_machine(eqx.tree_at(lambda sp: sp.guideway, SPEC, g))
        return measure_values(batched_sweep(machine, rails, X, chunk_size=N), "range:EAX:P1")

    np.testing.assert_allclose(m, at(s0), rtol=1e-9)
    h = 1e-5 * s0
    fd = (at(s0 + h) - at(s0 - h)) / (2 * h)
    np.testing.assert_allclose(dm[:, 0], fd, rtol=1e-4, atol=1e-6 * np.max(np.abs(fd)))


def _grid_argmin(rails, ts, ss, measure, feasible=lambda t, s: True):
    best = (np.inf, None)
    for t in ts:
        for s in ss:
            if feasible(t, s):
                f = np.mean(measures(rails, (t, s), measure))
                best = min(best, (f, (t, s)), key=lambda b: b[0])
    return np.array(best[1])


def test_optimum_at_the_mass_constraint_matches_a_grid(rails):
    """Roll difference falls with thickness and rises with spacing: the optimum sits at the
    mass limit (t = 150 kg / ρLW) and the smallest spacing; a 6 × 4 grid of rebuilt machines,
    its infeasible points left out, finds the same within its spacing."""
    res = design(SPEC, X, variables=NAMES, bounds=[(0.03, 0.08), (0.27, 0.33)],
                 constraints=[parse_constraint("mass<=150")], n_samples=N, check_samples=N,
                 chunk_size=N)
    mass = table_mass(with_overrides(SPEC, thickness=res.optimum[0]))
    assert float(mass) == pytest.approx(150.0, rel=1e-6)
    assert res.constraints[0][2] and res.constraints[0][0] == "mass <= 150 kg"
    ts, ss = np.linspace(0.03, 0.08, 6), np.linspace(0.27, 0.33, 4)
    rho_lw = float(table_mass(with_overrides(SPEC, thickness=1.0)))
    grid = _grid_argmin(rails, ts, ss, "roll_difference", lambda t, s: rho_lw * t <= 150)
    assert np.all(np.abs(res.optimum - grid) <= [ts[1] - ts[0], ss[1] - ss[0]])
    assert res.evaluations < 24 and res.success
    assert res.fresh_before is not None and res.improvement is not None
    np.testing.assert_allclose(res.start, [0.05, 0.32])


def test_interior_optimum_matches_a_grid(rails):
    """The roll range at P1 falls with thickness but is smallest at an inner carriage spacing
    (on these rails): the optimum at the thickness bound and inside the spacing range, where
    a 3 × 7 grid of rebuilt machines puts it too."""
    res = design(SPEC, X, variables=NAMES, bounds=[(0.03, 0.08), (0.27, 0.33)],
                 objective="range:EAX:P1:mean", n_samples=N, check_samples=0, chunk_size=N)
    ts, ss = np.linspace(0.03, 0.08, 3), np.linspace(0.27, 0.33, 7)
    grid = _grid_argmin(rails, ts, ss, "range:EAX:P1")
    assert 0.27 < grid[1] < 0.33 and 0.27 < res.optimum[1] < 0.33
    assert np.all(np.abs(res.optimum - grid) <= [ts[1] - ts[0], ss[1] - ss[0]])


def test_bad_input():
    with pytest.raises(ValueError, match="design variable must be one of thickness"):
        design(SPEC, X, variables=("nut_x",))
    with pytest.raises(ValueError, match="overlaps the carriages' footprints"):
        design(SPEC, X, variables=("carriage_spacing",), bounds=[(0.05, 0.4)])
    with pytest.raises(ValueError, match="puts the rails' footprints off the table"):
        design(SPEC, X, variables=("rail_spacing",), bounds=[(0.2, 0.5)])
    with pytest.raises(ValueError, match="0 < lo < hi"):
        design(SPEC, X, variables=("thickness",), bounds=[(0.08, 0.03)])
    with pytest.raises(ValueError, match="n_samples: 8 samples are too few"):
        design(SPEC, X, variables=("thickness",), objective="roll_difference:p95", n_samples=8)
    with pytest.raises(ValueError, match="objective statistic must be 'mean' or 'pNN'"):
        parse_objective("roll-difference:p100")
    with pytest.raises(ValueError, match="range:ERR:POINT"):
        parse_objective("range:EQX:P1:mean")
    with pytest.raises(ValueError, match="QUANTITY one of mass<=V"):
        parse_constraint("weight<=10")
    with pytest.raises(ValueError, match="--vary 'thickness=80:30'"):
        parse_vary("thickness=80:30")
    assert parse_vary("thickness=40:80") == ("thickness", pytest.approx((0.04, 0.08)))


_SHARDED = textwrap.dedent(
    """
    import sys
    import jax, numpy as np
    jax.config.update("jax_enable_x64", True)
    from diffguide.cli._study_options import split_cpu_into_devices
    assert split_cpu_into_devices(2)  # before the first array
    from diffguide.io.config import default_config, spec_from_config
    from diffguide.machine.build import with_overrides
    from diffguide.studies.design_sweep import DesignSweep
    from diffguide.studies.random_rails import GaussianRailModel, sample_rails
    assert len(jax.devices()) == 2, jax.devices()
    spec = with_overrides(spec_from_config(default_config()), nx=10, ny=5)
    rails = sample_rails(0, 8, GaussianRailModel(1e-6, 0.2))
    x0 = np.array([0.05, 0.30])
    sw = DesignSweep(spec, ("thickness", "carriage_spacing"), rails, np.linspace(-0.3, 0.3, 5),
                     "roll_difference", x0=x0, chunk_size=3)  # rounded up to 4: 2 chunks
    assert sw.chunk == 4 and sw.mesh is not None
    m, dm, ok = sw(x0)
    np.save(sys.argv[1], np.column_stack([m, dm, ok]))
    """
)


def test_sharded_over_two_cpu_devices(tmp_path, sweep):
    """The same measures and derivatives with the samples sharded over two CPU devices."""
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    script, out = tmp_path / "sharded.py", tmp_path / "sharded.npy"
    script.write_text(_SHARDED)
    run = subprocess.run([sys.executable, str(script), str(out)], env=env, capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    two = np.load(out)
    m, dm, ok = sweep(X0)
    np.testing.assert_allclose(two[:, 0], m, rtol=1e-10)
    np.testing.assert_allclose(two[:, 1:3], dm, rtol=1e-8, atol=1e-12)
    assert two[:, 3].all()


def test_cli_units_agree_with_the_tables():
    assert {n: (v.unit, v.scale) for n, v in VARIABLES.items()} == VARIABLE_UNITS
    assert {n: q.unit for n, q in CONSTRAINTS.items()} == CONSTRAINT_UNITS


def test_cli(tmp_path, capsys):
    out, js, png = tmp_path / "d.csv", tmp_path / "d.json", tmp_path / "d.png"
    assert main(["design", "--vary", "thickness=30:80", "--vary", "carriage_spacing=270:330",
                 "--constraint", "mass<=150", "--mesh", "10x5", "--positions=-300:300:5",
                 "--samples", "8", "--check-samples", "8", "--chunk", "8", "--out", str(out),
                 "--json", str(js), "--plot", str(png), "--no-cache", "--cpu-devices", "1"]) == 0
    text = capsys.readouterr().out
    assert "design for minimum roll_difference:mean" in text
    assert "constraint mass <= 150 kg: active" in text
    d = json.loads(js.read_text())
    assert d["variables"]["thickness"]["optimum"] == pytest.approx(150 / 7200 / 0.5 * 1e3)
    assert d["variables"]["carriage_spacing"]["unit"] == "mm"
    rows = out.read_text().splitlines()
    assert rows[0].startswith("evaluation,iteration,thickness_mm,carriage_spacing_mm,"
                              "objective_urad")
    assert len(rows) == 1 + d["evaluations"] and png.stat().st_size > 1000


@pytest.mark.parametrize(("argv", "match"), [
    (["--vary", "thickness=0:80"], "--vary 'thickness=0:80': bounds must be"),
    (["--vary", "ribs=1:2"], "NAME must be one of"),
    (["--vary", "thickness", "--samples", "4"], "--samples must be"),
    (["--vary", "thickness", "--constraint", "mass<<3"], "a constraint is QUANTITY<=V"),
    (["--vary", "thickness", "--objective", "roll:mean"], "range:ERR:POINT"),
    (["--vary", "thickness", "--vary", "thickness"], "each variable once"),
    (["--vary", "carriage_spacing=100:960", "--mesh", "10x5"], "footprints off the table"),
    (["--vary", "thickness", "--config",
      str(ROOT / "data" / "examples" / "superelement" / "machine.toml")],
     "a design varies the plate and the layout"),
])
def test_cli_bad_input(tmp_path, capsys, argv, match):
    assert main(["design", *argv, "--out", str(tmp_path / "d.csv"), "--json",
                 str(tmp_path / "d.json"), "--no-cache"]) == 2
    assert match in capsys.readouterr().err


def test_rail_length_constraint_is_stroke_plus_spacing_plus_carriage():
    """The rail length the stroke needs, from the machine file's own numbers: stroke 700 mm,
    carriages at ±160 mm, each footprint 60 mm along X (``default_config``)."""
    cfg = default_config()
    stroke = cfg["machine"]["stroke_mm"]
    cx = cfg["guideway"]["carriage_x_mm"]
    b = cfg["guideway"]["carriage_footprint_mm"][0]
    c = parse_constraint("rail_length<=1200")
    assert c.value == pytest.approx(1.2)
    need = (stroke + (cx[1] - cx[0]) + b) * 1e-3
    assert float(CONSTRAINTS["rail_length"].of(SPEC)) == pytest.approx(need)
    assert float(c.slack(SPEC)) == pytest.approx(1.2 - need)
    moved = with_overrides(SPEC, carriage_spacing=0.3)
    assert float(CONSTRAINTS["rail_length"].of(moved)) == pytest.approx(need - 0.02)


def test_wide_bounds_recentre_the_mesh_to_the_users_bound():
    """Carriage spacing over 200..330 mm, wider than the first mesh's range (261..339 mm): the
    roll-difference mean falls with the spacing, so the optimum is the user's lower bound,
    reached by re-centring the mesh; its objective there is that of the machine rebuilt at
    200 mm (``carriage_x = ±100 mm``) by the ordinary sweep on the same rails."""
    res = design(SPEC, X, variables=("carriage_spacing",), bounds=[(0.2, 0.33)], n_samples=N,
                 check_samples=0, chunk_size=N)
    assert res.stages[0]["bounds"][0][0] > 0.25 and res.stages[0]["recentred"]
    assert res.optimum[0] == pytest.approx(0.2, abs=1e-9)
    assert res.active_bounds == (("carriage_spacing", "lower"),)
    assert res.stages[-1]["carriage_x"] == pytest.approx((-0.1, 0.1))
    assert {r["stage"] for r in res.history} == set(range(len(res.stages)))
    knots = design_knots(SPEC, X, 0.2, (0.2, 0.33))
    rails = sample_rails(0, N, GaussianRailModel(1e-6, 0.2), knots=knots)
    plain = np.mean(measures(rails, (float(SPEC.table.thickness), 0.2)))
    assert res.after.value == pytest.approx(plain, rel=1e-9)
    assert res.after.value < res.before.value
    # the command line takes such bounds (its parse, then the design's check)
    name, b = parse_vary("carriage_spacing=200:400")
    assert check_bounds(SPEC, [name], [b]) == (pytest.approx((0.2, 0.4)),)


def test_rail_spacing_recentres_past_a_point_line():
    """Rail spacing over 300..420 mm: the first mesh stops at 348 mm (the footprint's edge meets
    the grid line of the points at y = ±200 mm), the roll difference falls as the rails move
    apart, so the mesh is re-centred (twice: the footprint then straddles that line) to the
    user's bound; the objective there is that of the machine rebuilt with ``rail_y = ±210 mm``
    by the ordinary sweep on the same rails."""
    res = design(SPEC, X, variables=("rail_spacing",), bounds=[(0.30, 0.42)], n_samples=N,
                 check_samples=0, chunk_size=N)
    assert res.stages[0]["bounds"][0][1] < 0.35 and res.stages[0]["recentred"]
    assert res.optimum[0] == pytest.approx(0.42, abs=1e-9)
    assert res.active_bounds == (("rail_spacing", "upper"),)
    assert res.stages[-1]["rail_y"] == pytest.approx((-0.21, 0.21))
    knots = design_knots(SPEC, X, 0.2)
    rails = sample_rails(0, N, GaussianRailModel(1e-6, 0.2), knots=knots)
    g = dataclasses.replace(SPEC.guideway, rail_y=(-0.21, 0.21))
    moved = build_machine(eqx.tree_at(lambda s: s.guideway, SPEC, g))
    plain = np.mean(measure_values(batched_sweep(moved, rails, X, chunk_size=N),
                                   "roll_difference"))
    assert res.after.value == pytest.approx(plain, rel=1e-9)
    assert res.after.value < res.before.value
