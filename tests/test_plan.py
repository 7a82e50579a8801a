"""Measurement planning (issue 15): the planner's predicted σ against the fit on simulated data.

What is compared, and with what:

- **The Bayesian check** (``SEEDS`` = 20 seeds per plan): a truth drawn from the plan's own prior —
  rails ``θ ~ N(0, (λΩ)⁻¹)`` (λ from ``rail_rms``) and structure ``q ~ N(0, I)`` (thickness and
  preload, ``diffguide fit``'s default priors) — simulated with the fit's machine family at that
  structure, merged values with Gaussian noise of the planned σ (``σ_reading/√10``: 5 runs, two
  directions), fitted by ``fit_rails(family, meas, lam=plan.lam)`` (the same prior). Then (a) the
  empirical RMS of ``(fit − truth)/σ_pred`` over the seeds and the rail length, which must be
  ≈ 1 when the predicted σ is the real scatter (asserted within 20 %; measured 0.99 / 1.05 for
  the bundled / greedy plans); (b) the σ the fit reports against the planner's, RMS over the
  seeds and the rail length, within 20 % (asserted; measured 1.02× / 1.01×); (c) the fits' RMS
  error against the planner's RMS σ — an expected failure for both plans (0.74×; greedy
  0.80×): the fits do better than predicted at the horizontal profiles' ends. The fixture prints
  every ratio (``PLANSTAT`` lines with ``-s``).
- **Greedy vs the bundled layout** with the bundled instrument count (4 two-axis levels + 1
  interferometer): the worst-case profile σ the *fits* report, over the same seeds.
- **Woodbury = direct**: the greedy's rank-r updates against a direct inverse, and the λ
  equation against sampled prior rails integrated on a fine grid.
- **CLI**: outputs written; bad input exits 2 and writes nothing.

The 40 simulated fits take about 50 s on an idle 2-core machine (they share one compiled fit).
The simulation uses the fit's own 20 × 10 model (the Bayesian check asks whether the
planner's linear-Gaussian σ describes the nonlinear fit, not how large the model error of a
coarser mesh is; the battery covers that).
"""

import json

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from battery import cases

from diffguide.cli import main
from diffguide.guideway.rails import SplineRail
from diffguide.inverse import fit_rails
from diffguide.inverse.data import QUANTITIES, Measurements
from diffguide.planning import Instrument, build_planner, expected_rms_lambda, grid_sites, plan
from diffguide.machine.kinematics import joint_errors

#: Candidate sites: 5 × 3 over the table top, 50 mm inside the edges — it holds the bundled
#: layout's sites (corners (±450, ±200) mm, centre).
SITES = grid_sites(1.0, 0.5, 5, 3)
POSITIONS = np.linspace(-0.35, 0.35, 18)
SEEDS = 20
RUNS = 5  # per direction, both directions: σ_merged = σ_reading / √10
#: Prior rail draws the planner averages over (its default 8 is enough to rank plans; for a
#: comparison with 20 seeds at the 20 % level the planner's own Monte Carlo error must be small).
N_DRAWS = 32


def _bundled():
    """The battery's bundled layout as placements on :data:`SITES`."""
    out = []
    for _, x, y, inst, qs in cases.BUNDLED:
        site = next(
            n
            for n, (sx, sy) in SITES.items()
            if abs(sx * 1e3 - x) < 1e-9 and abs(sy * 1e3 - y) < 1e-9
        )
        assert set(qs) == set(Instrument(inst).quantities)
        out.append((inst, site))
    return out


BUNDLED = _bundled()


@pytest.fixture(scope="module")
def planned():
    family = cases.fit_machine(SITES)  # diffguide fit's default structural priors
    result = plan(family, POSITIONS, compare=BUNDLED, runs=RUNS, n_draws=N_DRAWS)
    return family, result


def _measurements(errors, placements, planner, rng):
    """Merged values (SI) of a plan: truth + Gaussian noise of the merged σ."""
    names = list(SITES)
    cols = {k: [] for k in ("pos", "pt", "q", "v", "s", "inst")}
    for kind, site in placements:
        inst = planner.instrument[kind]
        sig = inst.sigma / np.sqrt(planner.readings)
        for q in inst.quantities:
            e = errors[:, names.index(site), QUANTITIES.index(q)]
            cols["pos"] += list(POSITIONS)
            cols["pt"] += [site] * len(POSITIONS)
            cols["q"] += [q] * len(POSITIONS)
            cols["v"] += list(e + sig * rng.standard_normal(len(POSITIONS)))
            cols["s"] += [sig] * len(POSITIONS)
            cols["inst"] += ["level" if kind == "level" else "interferometer"] * len(POSITIONS)
    return Measurements.from_arrays(
        SITES, cols["pos"], cols["pt"], cols["q"], cols["v"], cols["s"], instrument=cols["inst"]
    )


@pytest.fixture(scope="module")
def simulated(planned):
    """Per plan ('bundled', 'greedy'): over the seeds, the fits' σ², their worst σ, the errors
    (fit − truth) — each seed one truth from the prior and one noise draw, the same for both
    plans."""
    family, res = planned
    pl = res.planner
    b = pl.basis
    ps = family.prior_sigma()
    Lth = np.linalg.cholesky(np.linalg.inv(pl.lam * pl.Omega))
    E_s = np.kron(np.eye(4), b.matrix(pl.s)) @ pl.Pi  # gauge-fixed profiles at pl.s

    @eqx.filter_jit
    def simulate(q, c_um):
        c = c_um.reshape(2, 2, b.n_coeffs) * 1e-6
        rails = tuple(SplineRail(b.start, b.spacing, c[r, 0], c[r, 1]) for r in range(2))
        je = joint_errors(family.machine(q * ps), rails, jnp.asarray(POSITIONS))
        return je.errors, je.converged

    out = {}
    for label, placements in (("bundled", BUNDLED), ("greedy", res.placements)):
        s2, worst, err, conv = [], [], [], []
        for seed in range(SEEDS):
            rng = np.random.default_rng(seed)
            c = pl.Z @ (Lth @ rng.standard_normal(pl.n_theta))
            q = rng.standard_normal(family.n_params)
            errors, ok = simulate(jnp.asarray(q), jnp.asarray(c))
            assert bool(np.all(np.asarray(ok)))
            truth = (E_s @ c).reshape(2, 2, -1) * 1e-6
            fit = fit_rails(
                family, _measurements(np.asarray(errors), placements, pl, rng), lam=res.lam
            )
            val, sig = fit.profiles(pl.s)
            s2.append(sig**2)
            worst.append(sig.max())
            err.append(val - truth)
            conv.append(fit.converged)
        e, s = np.array(err), np.sqrt(np.mean(np.array(s2), axis=0))
        ev = res.compare if label == "bundled" else res.best
        print(
            f"PLANSTAT {label}: z_rms {np.sqrt(np.mean((e / ev.sigma) ** 2)):.3f}, "
            f"rms error / rms σ_pred {np.sqrt(np.mean(e**2)) / ev.rms:.3f}, "
            f"rms σ_fit / rms σ_pred {np.sqrt(np.mean(s**2)) / ev.rms:.3f}, "
            f"(fit - truth)/σ_fit rms {np.sqrt(np.mean(e**2 / np.array(s2))):.3f}, "
            f"worst σ_fit {np.mean(worst) * 1e6:.3f} µm, planner worst {ev.worst * 1e6:.3f} µm, "
            f"rms error {np.sqrt(np.mean(e**2)) * 1e6:.4f} µm, converged {np.mean(conv):.2f}"
        )
        out[label] = {
            "s2": np.array(s2),
            "worst": np.array(worst),
            "err": np.array(err),
            "converged": np.array(conv),
        }
    return out


def _eval(res, label):
    return res.compare if label == "bundled" else res.best


@pytest.mark.parametrize("label", ["bundled", "greedy"])
def test_predicted_sigma_is_the_real_scatter_of_the_fits(planned, simulated, label):
    """The planner's σ against the real scatter of the fits about the truths: RMS of
    (fit − truth)/σ_pred over the seeds and the rail length ≈ 1 (within 20 %)."""
    _, res = planned
    ev = _eval(res, label)
    sim = simulated[label]
    assert sim["converged"].mean() >= 0.9  # a fit returns its best estimate either way
    z = sim["err"] / ev.sigma
    z_rms = float(np.sqrt(np.mean(z**2)))
    assert z_rms == pytest.approx(1.0, abs=0.2), z_rms


_MEASURED = (
    "measured (same seeds; bundled / greedy): the fits' RMS error is 0.740x / 0.799x the "
    "planner's RMS σ (the greedy plan's just outside the 20 %) while (fit - truth)/σ_pred has "
    "RMS 0.99 / 1.05, the σ the fits report is 1.02x / 1.01x the planner's and (fit - truth)/"
    "σ_fit has RMS 1.00 / 0.99: the fits' errors at the horizontal profiles' ends, where the "
    "predicted σ is largest, are smaller than predicted there"
)


@pytest.mark.parametrize(
    "label", [pytest.param(label, marks=pytest.mark.xfail(reason=_MEASURED))
              for label in ("bundled", "greedy")]
)
def test_predicted_rms_sigma_agrees_with_the_fits_rms_error(planned, simulated, label):
    """The RMS error of the fits (over the seeds, the four profiles and the rail length) against
    the planner's RMS σ, within 20 %."""
    _, res = planned
    ev = _eval(res, label)
    empirical = float(np.sqrt(np.mean(simulated[label]["err"] ** 2)))
    assert empirical / ev.rms == pytest.approx(1.0, abs=0.2), (empirical, ev.rms)


@pytest.mark.parametrize("label", ["bundled", "greedy"])
def test_predicted_sigma_agrees_with_the_sigma_the_fit_reports(planned, simulated, label):
    """The planner's σ against the σ the fit reports (RMS over the seeds; compared as the RMS
    over the four profiles and the rail length), within 20 %."""
    _, res = planned
    ev = _eval(res, label)
    fit_sigma = np.sqrt(simulated[label]["s2"].mean(axis=0))
    rms_fit = float(np.sqrt(np.mean(fit_sigma**2)))
    assert rms_fit / ev.rms == pytest.approx(1.0, abs=0.2), (rms_fit, ev.rms)


def test_greedy_plan_beats_the_bundled_layout_in_simulated_fits(planned, simulated):
    """Same instruments (4 two-axis levels, 1 pitch/yaw interferometer), same truths and noise:
    the greedy plan's fits report a smaller worst-case profile σ than the bundled layout's — not
    only by the planner's own number. (Their actual RMS errors over these 20 truths are not
    asserted: the planner predicts only 3 % between the plans in RMS σ, within the Monte Carlo
    noise of 20 truths; measured 0.251 against 0.259 µm with one version of the fit, 0.220
    against 0.208 µm with the next.)"""
    _, res = planned
    kinds = sorted(k for k, _ in res.placements)
    assert kinds == sorted(k for k, _ in BUNDLED)
    assert res.best.worst < res.compare.worst
    g, b = simulated["greedy"], simulated["bundled"]
    assert np.mean(g["worst"]) < np.mean(b["worst"])


def test_greedy_updates_equal_a_direct_recomputation(planned):
    """Every greedy step's criterion (rank-r Woodbury updates of the posterior) equals the
    posterior recomputed by a direct inverse of P + ΣJᵀJ for the placements so far; each step
    buys something."""
    _, res = planned
    pl = res.planner
    chosen = []
    for step in res.steps:
        chosen.append(step.placement)
        direct = pl.evaluate(chosen)
        assert step.worst == pytest.approx(direct.worst, rel=1e-8)
        assert step.rms == pytest.approx(direct.rms, rel=1e-8)
        assert step.logdet == pytest.approx(direct.logdet, rel=1e-10)
        assert step.after < step.before
    np.testing.assert_allclose(res.best.sigma, pl.evaluate(res.placements).sigma, rtol=1e-8)
    # D and A criteria through the same updates
    for crit in ("D", "A"):
        steps, ev = pl.greedy({"level": 2}, crit)
        d = pl.evaluate(ev.placements)
        assert ev.logdet == pytest.approx(d.logdet, rel=1e-10)
        assert ev.rms == pytest.approx(d.rms, rel=1e-8)


def test_prior_weight_gives_the_stated_rail_rms(planned):
    """λ from the expected RMS: rails sampled from N(0, (λΩ)⁻¹), gauge-fixed and integrated on a
    fine grid, have that RMS (Monte Carlo, 4000 draws: ±3 %)."""
    _, res = planned
    pl = res.planner
    rng = np.random.default_rng(7)
    Lth = np.linalg.cholesky(np.linalg.inv(pl.lam * pl.Omega))
    s = pl.basis.grid(2001)
    E = np.kron(np.eye(4), pl.basis.matrix(s)) @ pl.Pi @ pl.Z @ Lth
    e = E @ rng.standard_normal((pl.n_theta, 4000))  # µm
    rms = float(np.sqrt(np.mean(e**2)))
    assert rms == pytest.approx(res.rail_rms * 1e6, rel=0.03)
    # and the stated RMS enters as 1/ρ²
    lam2 = expected_rms_lambda(pl.basis, pl.Z, pl.Omega, pl.Pi, 2.0)
    assert lam2 == pytest.approx(pl.lam / 4.0, rel=1e-12)


def test_planner_input_errors(planned):
    family, res = planned
    with pytest.raises(ValueError, match="kind"):
        Instrument("laser")
    with pytest.raises(ValueError, match="reads"):
        Instrument("level", 1, ("ECX",))
    with pytest.raises(ValueError, match="positions"):
        build_planner(family, [Instrument("level")], [0.0, 0.1])
    with pytest.raises(ValueError, match="criterion"):
        res.planner.greedy(None, "E")
    with pytest.raises(ValueError, match="placement"):
        res.planner.evaluate([("level", "nowhere")])


def test_cli_writes_the_plan_and_refuses_bad_input(tmp_path, capsys):
    out = tmp_path / "plan"
    rc = main(
        [
            "plan",
            "--grid",
            "3x2",
            "--positions",
            "8",
            "--levels",
            "2",
            "--structure",
            "fixed",
            "--draws",
            "1",
            "--mesh",
            "8x4",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert rc == 0
    assert sorted(p.name for p in out.iterdir()) == [
        ".diffguide-output.json",  # the marker: what diffguide plan wrote there
        "plan.csv",
        "plan.png",
        "report.json",
        "sigma.png",
    ]
    report = json.loads((out / "report.json").read_text())
    assert report["compare"]["worst_profile_sigma_um"] > 0
    assert report["mesh"] == "8x4"
    assert len(report["steps"]) == 3  # 2 levels + 1 interferometer
    assert report["plan"]["worst_profile_sigma_um"] < report["prior_only"]["worst_profile_sigma_um"]
    lines = (out / "plan.csv").read_text().splitlines()
    assert lines[0].startswith("step,instrument,site,x_mm,y_mm") and len(lines) == 4
    sites = tmp_path / "sites.csv"
    sites.write_text("name,x_mm,y_mm\nA,0,0\nB,900,0\n")
    bad_grid = ["--grid", "0x3"]
    conflict = tmp_path / "conflict.csv"
    conflict.write_text("instrument,point,x_mm,y_mm\nlevel,P1,450,200\nlevel,P1,-450,200\n")
    for extra in (
        bad_grid,
        ["--compare", str(conflict)],
        ["--levels", "-1"],
        ["--rail-rms-um", "0"],
        ["--compare", str(tmp_path / "missing.csv")],
        ["--sites", str(sites)],
        ["--criterion", "work"],
        ["--level-reads", "ECX"],
        ["--mesh", "0x4"],
    ):
        dest = tmp_path / "bad"
        assert main(["plan", "--out", str(dest), "--quiet", *extra]) == 2, extra
        assert not dest.exists()
    err = capsys.readouterr().err
    assert "--grid" in err and "off the table" in err and "missing.csv" in err
    assert "conflict.csv:3: field 'point': 'P1' is at (-450, 200) mm here but at (450, 200)" in err


def test_the_cli_offers_what_the_planner_models():
    """``diffguide plan`` and its settings keep their own table of who reads what (the parser
    and the settings' checks must not import JAX); it is the planner's
    :data:`~diffguide.planning.KINDS`, kind for kind."""
    from diffguide.jobs.plan import KIND_READS
    from diffguide.planning import KINDS

    assert KIND_READS == KINDS
