"""The fit's predicted σ for a measurement plan as a design objective
(:mod:`diffguide.studies.design_plan`, ``diffguide design --objective plan:…``).

Its value against the measurement planner's (:func:`~diffguide.planning.planner.build_planner`:
another formulation — the numpy posterior of eigen-factored blocks from the planner's own
Jacobian over every site); its derivatives w.r.t. every design variable (thickness, carriage and
rail spacing, preload, modulus) against central differences of *rebuilt* machines; a design's
optimum against the optimality conditions at its bounds; bad input; the command line."""

import dataclasses
import json

import equinox as eqx
import numpy as np
import pytest

from diffguide.cli import main
from diffguide.planning.instruments import Instrument, bundled_layout_mm
from diffguide.planning.planner import build_planner
from diffguide.io.config import default_config, spec_from_config
from diffguide.machine.build import build_machine, with_overrides
from diffguide.studies.design import design, parse_objective
from diffguide.studies.design_plan import MeasurementPlan, PlanSigma, on_plan_sites
from diffguide.studies.design_space import spec_values

SPEC = with_overrides(spec_from_config(default_config()), nx=10, ny=5)
NAMES = ("thickness", "carriage_spacing", "rail_spacing", "preload_fraction", "E")
POS = np.linspace(-0.3, 0.3, 7)
ROWS = tuple((k, x * 1e-3, y * 1e-3) for k, x, y in bundled_layout_mm(1000.0, 500.0))
PLAN = MeasurementPlan(ROWS, POS, work_point=(0.1, 0.05, ("EAX", "EBX")))
MESH = on_plan_sites(SPEC, PLAN)
X0 = spec_values(MESH, NAMES)


@pytest.fixture(scope="module")
def objectives():
    return {c: PlanSigma(MESH, NAMES, PLAN, c, x0=X0) for c in ("A", "worst", "work")}


def test_value_is_the_planners(objectives):
    """The planner with the structure known, the same plan, σ, runs and prior."""
    sites = PLAN.sites()
    named = {xy: n for n, xy in sites.items()}
    planner = build_planner(build_machine(MESH), [Instrument("level", 4),
                                                  Instrument("interferometer", 1)],
                            POS, runs=5, work_point=("WORK", ("EAX", "EBX")), n_draws=0)
    ev = planner.evaluate([(k, named[(x, y)]) for k, x, y in ROWS])
    assert objectives["A"].basis == planner.basis
    for c, want in (("A", ev.rms), ("worst", ev.worst), ("work", ev.work)):
        v, g, ok = objectives[c](X0)
        assert ok and np.all(np.isfinite(g))
        assert v == pytest.approx(want, rel=1e-9), c


def _rebuilt(thickness, spacing, rail_spacing, preload, modulus):
    """The specification rebuilt with the carriages at ±spacing/2 and the rails at
    ±rail_spacing/2 (no traced layout: the mesh lines put where the footprints are), the other
    values set as plain numbers."""
    g = dataclasses.replace(MESH.guideway, carriage_x=(-spacing / 2, spacing / 2),
                            rail_y=(-rail_spacing / 2, rail_spacing / 2))
    return with_overrides(eqx.tree_at(lambda s: s.guideway, MESH, g), thickness=thickness,
                          preload_fraction=preload, E=modulus)


@pytest.mark.parametrize("criterion, variables", [("A", NAMES),
                                                  ("work", ("thickness", "rail_spacing"))])
def test_gradient_matches_central_differences_of_rebuilt_machines(objectives, criterion,
                                                                  variables):
    """Every design variable (the layout's by machines rebuilt around the moved footprints);
    the work point's rows through one variable of the plate and one of the layout."""
    obj = objectives[criterion]
    _, g, _ = obj(X0)
    assert np.all(g != 0)
    for j in (NAMES.index(n) for n in variables):
        h = 1e-5 * X0[j]
        vals = []
        for sgn in (1, -1):
            x = X0 + sgn * h * np.eye(len(NAMES))[j]
            again = PlanSigma(_rebuilt(*x), ("thickness",), PLAN, criterion, x0=x[:1],
                              basis=obj.basis)
            vals.append(again(x[:1], grad=False)[0])
        fd = (vals[0] - vals[1]) / (2 * h)
        assert g[j] == pytest.approx(fd, rel=1e-4), (criterion, NAMES[j], g[j], fd)


def test_design_optimum_meets_the_optimality_conditions():
    """Thickness within 30..80 mm at ≥ 110 kg of table (a thin table's errors say most about
    its rails, so the mass bound is active): the optimum's thickness is the one that mass allows,
    the objective's exact improvement is the difference of two evaluations."""
    from diffguide.studies.design_space import parse_constraint

    res = design(SPEC, POS, variables=["thickness"], bounds=[(0.03, 0.08)],
                 objective="plan:A", plan=PLAN, constraints=[parse_constraint("mass>=110")])
    t_mass = 110 / (SPEC.table.material.rho * SPEC.table.length * SPEC.table.width)  # ρLWt
    assert res.optimum[0] == pytest.approx(t_mass, rel=1e-6)
    assert res.sensitivities[0] > 0  # the constraint, not a stationary point, stops it
    assert res.constraints[0][2]  # active
    obj = PlanSigma(MESH, ("thickness",), PLAN, "A", x0=res.start)
    assert res.before.value == pytest.approx(obj(res.start)[0], rel=1e-9)
    assert res.after.value == pytest.approx(obj(res.optimum)[0], rel=1e-9)
    assert res.improvement.value == pytest.approx(res.before.value - res.after.value)
    assert res.improved and res.n_samples == 0 and res.unit == "µm"


def test_bad_input():
    with pytest.raises(ValueError, match="CRITERION must be one of A, worst, work"):
        parse_objective("plan:D")
    with pytest.raises(ValueError, match="needs plan=MeasurementPlan"):
        design(SPEC, POS, variables=["thickness"], objective="plan:A")
    with pytest.raises(ValueError, match="read only by such an objective"):
        design(SPEC, POS, variables=["thickness"], objective="roll_difference:mean", plan=PLAN)
    with pytest.raises(ValueError, match="at least 4 distinct"):
        MeasurementPlan(ROWS, POS[:3])
    with pytest.raises(ValueError, match="kind must be one of"):
        MeasurementPlan((("laser", 0.0, 0.0),), POS)
    with pytest.raises(ValueError, match="the same instrument twice"):
        MeasurementPlan(ROWS + ROWS[:1], POS)
    with pytest.raises(ValueError, match="a level reads"):
        MeasurementPlan(ROWS, POS, reads={"level": ("EYX",)})
    with pytest.raises(ValueError, match="needs the plan's work point"):
        PlanSigma(on_plan_sites(SPEC, MeasurementPlan(ROWS, POS)), NAMES,
                  MeasurementPlan(ROWS, POS), "work", x0=X0)
    with pytest.raises(ValueError, match="lacks the plan's sites"):
        PlanSigma(SPEC, NAMES, PLAN, "A", x0=X0)


def test_cli(tmp_path, capsys):
    out, js = tmp_path / "d.csv", tmp_path / "d.json"
    assert main(["design", "--mesh", "10x5", "--objective", "plan:work", "--work-point",
                 "100,50", "--work-reads", "EAX", "--positions=-300:300:7",
                 "--vary", "thickness=40:60", "--out", str(out), "--json", str(js)]) == 0
    text = capsys.readouterr().out
    assert "deterministic, no random rails" in text and "exact" in text
    r = json.loads(js.read_text())
    assert r["objective"] == "plan:work" and r["unit"] == "µrad" and r["samples"] == 0
    assert r["after"]["value"] <= r["before"]["value"]
    assert out.read_text().splitlines()[0].startswith("evaluation,iteration,thickness_mm")


@pytest.mark.parametrize("argv, match", [
    (["--objective", "plan:work"], "needs --work-point"),
    (["--objective", "roll-difference:mean", "--work-point", "0,0"], "read only with"),
    (["--objective", "plan:A", "--plan-runs", "0"], "--plan-runs must be in"),
    (["--objective", "plan:A", "--work-point", "0,0", "--work-reads", "EXX"],
     "work point quantities"),
])
def test_cli_bad_input(tmp_path, capsys, argv, match):
    assert main(["design", "--mesh", "10x5", "--vary", "thickness", "--out",
                 str(tmp_path / "d.csv"), "--json", str(tmp_path / "d.json"), *argv]) != 0
    assert match in capsys.readouterr().err
