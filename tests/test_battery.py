"""The identification battery (issue 11, part 4): hidden-style cases, each with a truth made by a
different model than the fit uses (tests/battery). Per case: the fit returns a result; the truth
lies inside ±2σ at >= 85 % of the profile points and >= 70 % for every profile (gauge removed,
10 % trimmed at each end); on the wrong-structure cases every profile is within 15 % RMS of the
truth.

Each case is simulated and fitted once per session (tests/battery/cases.result); the truth
machines are built once each. The battery's own machinery is checked against closed forms first.
"""

import dataclasses

import numpy as np
import pytest
from battery import cases
from battery.cases import CASES, result
from battery.score import TRIM, score_fit, score_profiles

from diffguide.inverse import RailBasis, blind_wavelengths
from diffguide.io.measurements import QUANTITIES

WRONG_STRUCTURE = [name for name, make in CASES.items() if make().wrong_structure]
#: Cases measured with the planned layout already (the planned-layout comparisons skip them).
ALREADY_PLANNED = [name for name, make in CASES.items() if make().sensors == cases.PLANNED]

#: Cases that still fail, per test, with the numbers measured with the fit whose structure comes
#: from the marginal likelihood (bench/battery_table.py). Kept as expected failures so that the
#: suite shows them; each is an open problem, not a pass.
_NOW = "measured: "
XFAIL: dict[tuple[str, str], str] = {
    ("coverage", "with_straightness"): _NOW + "coverage 86 % overall, 70.4 % worst (at the "
    "bound; 82/61 % before the floor on the undetermined directions, inverse/bands.py) on this "
    "case's "
    "seed (707), where the thickness comes back 43 ± 5 mm (truth 50) and χ²/dof is 0.77; the "
    "structure estimate sits 2.1σ (thickness and preload jointly) from the truth in the direction "
    "that moves the horizontal profiles most; on seeds 1-40 of the same case it passes (overall "
    ">= 93 %, worst >= 84 %, error/σ 0.52-1.17): a tail draw (bench/battery_seeds.py)",
    ("error", "thickness_70mm"): _NOW + "profile errors 8/18/9/28 % (joint estimate 7/25/10/34 %, "
    "structure fixed at the preset 9/35/12/47 %); thickness 77 ± 12 mm (70). With the structure "
    "known (oracle) 7/21/9/30 %: the bound is below what these data hold. The miss is the rails' "
    "horizontal half-difference, 22 % (oracle 24 %); means and vertical difference 3-7 %. Fitted "
    "with the machine that made the data, worst profile 30 %, 27 % with the half-difference's "
    "prior scale chosen in hindsight: test_the_15_percent_bound_is_beyond_the_data"
    "; with the planned layout it holds: test_the_15_percent_bound_holds_with_the_planned_layout",
    ("error", "preload_2pct"): _NOW + "profile errors 10/25/7/24 %: the preload is not determined "
    "by these data (reported as such) and the thickness takes up part of its effect; with the "
    "structure known (oracle) 9/22/5/20 %; the miss is the horizontal half-difference, 22 % "
    "(oracle 19 %); means and vertical difference 3-8 %. With the machine that made the data "
    "21 % (22 % at the hindsight-best prior scale): test_the_15_percent_bound_is_beyond_the_data"
    "; with the planned layout it holds: test_the_15_percent_bound_holds_with_the_planned_layout",
    ("error", "preload_13pct"): _NOW + "profile errors 6/8/5/16 % (joint estimate 6/16/5/21 %); "
    "with the structure known (oracle) 6/8/5/17 %; horizontal half-difference 10 % (oracle "
    "11 %), the other combinations 3-7 %. With the machine that made the data 18 % (17 % at the "
    "hindsight-best prior scale): test_the_15_percent_bound_is_beyond_the_data"
    "; with the planned layout it holds: test_the_15_percent_bound_holds_with_the_planned_layout",
    ("error", "planned_undetermined"): _NOW + "profile errors 22/28/27/35 %: the case puts "
    "0.5 µm sines at 285/320/363 mm, the wavelengths the planned layout leaves undetermined (the "
    "rails' mean around the carriage spacing, where pitch and yaw cancel); no layout of these "
    "instruments holds them, and the bands say so (test_truth_inside_2_sigma_per_plane)",
    ("combinations", "planned_undetermined"): _NOW + "the two planes' means 23/30 % off: that is "
    "where this case's content at the undetermined wavelengths (285-363 mm) sits",
}


def _params(test: str, names) -> list:
    return [
        pytest.param(n, marks=pytest.mark.xfail(strict=False, reason=XFAIL[(test, n)]))
        if (test, n) in XFAIL
        else n
        for n in names
    ]


# ------------------------------------------------------------------ the battery's machinery


class _FakeFit:
    """The attributes the scorer reads, with chosen profiles and σ."""

    def __init__(self, basis, fix_slope, values, sigma):
        self.basis, self.fix_slope = basis, fix_slope
        self._values, self._sigma = values, sigma

    def profiles(self, s):
        return self._values(s), self._sigma(s)


def test_score_closed_forms():
    """Gauge modes are not errors; a cosine error of k whole periods over the scored range has
    RMS a/√2, and |cos| ≤ 1/√2 holds on half of each period."""
    basis = RailBasis.covering(-0.53, 0.53, 0.048)
    s = np.linspace(basis.start, basis.end, 401)
    L = basis.end - basis.start
    truth = cases.truth_profiles(cases.baseline(), s)
    # offsets of every profile and a common slope per plane: invisible
    gauge = np.array([1.0, -2.0, 3.0, 0.5])[:, None] * 1e-6 + np.zeros((4, len(s)))
    gauge += np.array([1.0, 3.0, 1.0, 3.0])[:, None] * 1e-6 * (s - s.mean())
    sc = score_profiles(
        basis,
        (True, True),
        truth + gauge.reshape(2, 2, -1),
        np.full((2, 2, len(s)), 1e-12),
        truth,
        s,
    )
    np.testing.assert_allclose(sc.rms_um, 0.0, atol=1e-9)
    assert sc.overall_coverage == 1.0
    # 5 periods over the range: 4 whole periods over the scored 80 %; symmetric about the
    # centre (no slope), mean a/401 from the endpoint (the closed forms hold to ~1 %)
    a = 1e-6
    e = a * np.cos(2 * np.pi * 5 * (s - basis.start) / L)
    err = np.zeros((2, 2, len(s)))
    err[0, 1] = e
    sc = score_profiles(
        basis, (True, True), truth + err, np.full((2, 2, len(s)), a / np.sqrt(8)), truth, s
    )
    np.testing.assert_allclose(sc.rms_um[0, 1], 1e6 * a / np.sqrt(2), rtol=0.01)
    np.testing.assert_allclose(sc.rms_um[1], 0.0, atol=1e-6)
    assert abs(sc.coverage[0, 1] - 0.5) < 0.02
    # rail 1's horizontal error is half in the plane's mean and half in its half-difference
    plane_rms = np.sqrt(np.mean(sc.truth_rms_um[:, 1] ** 2))
    np.testing.assert_allclose(sc.combination_rel[1], 1e6 * a / np.sqrt(8) / plane_rms, rtol=0.01)
    np.testing.assert_allclose(sc.combination_rel[0], 0.0, atol=1e-9)
    assert np.all(sc.coverage[1] == 1.0)
    assert np.isclose(sc.s[0] - basis.start, TRIM * L, atol=L / 400)


def test_combination_sigma_closed_form():
    """A profile whose coefficients are fully correlated with variance a² has σ = a at every s
    (the B-splines sum to one); rails independent: each combination (e₁ ± e₂)/2 has σ = a/√2."""
    import types

    from battery.score import combination_sigma_rel

    basis = RailBasis.covering(-0.53, 0.53, 0.048)
    n, a = basis.n_coeffs, 0.2e-6
    fit = types.SimpleNamespace(basis=basis, fix_slope=(True, True),
                                cov=np.kron(np.eye(4), np.full((n, n), a**2)))
    case = cases.baseline()
    truth = lambda s: cases.truth_profiles(case, s)  # noqa: E731
    s = np.linspace(basis.start, basis.end, 401)
    tg = basis.gauge_fix(s, truth(s).reshape(4, -1), (True, True)).reshape(2, 2, -1)
    keep = (s >= basis.start + TRIM * (basis.end - basis.start) - 1e-12) & (
        s <= basis.end - TRIM * (basis.end - basis.start) + 1e-12)
    plane_rms = np.sqrt(np.mean(tg[..., keep] ** 2, axis=(0, 2)))
    np.testing.assert_allclose(combination_sigma_rel(fit, truth),
                               (a / np.sqrt(2) / plane_rms)[:, None] * np.ones((2, 2)),
                               rtol=1e-9)


def test_readings_round_trip_through_the_input_path():
    """Noise-free readings written as CSV text come back from parse + merge as the errors they
    were made from (SI), one merged row per position, point and quantity, 10 readings each."""
    case = cases.with_straightness()
    rng = np.random.default_rng(1)
    n_pos, n_pt = case.n_positions, len(case.sensors)
    errors = rng.normal(0.0, 5.0, (n_pos, n_pt, 6))  # µm, µm/m
    meas = cases.measurements(case, errors, noise=False)
    assert meas.point_names == tuple(case.points())
    assert meas.n == n_pos * sum(len(q) for *_, q in case.sensors)
    pos = case.positions_mm() * 1e-3
    i = np.searchsorted(pos, meas.position - 1e-9)
    np.testing.assert_allclose(pos[i], meas.position, atol=1e-9)
    expected = errors[i, meas.point, meas.quantity] * 1e-6
    np.testing.assert_allclose(meas.value, expected, atol=1e-11)
    assert np.all(meas.n_readings == 2 * case.runs)
    straight = meas.quantity == QUANTITIES.index("EZX")
    assert straight.sum() == n_pos and set(meas.instrument) == {"level", "interferometer"}


def test_noise_levels_and_outliers():
    """The pooled repeatability of the noisy readings is the stated noise per instrument
    (4 µm/m level, 2 µm/m interferometer, 1 µm straightness) within its sampling error, and
    exactly ``outliers`` readings sit beyond 8 σ of the noise-free values."""
    case = dataclasses.replace(cases.with_straightness(), outliers=5, seed=7)
    errors = np.zeros((case.n_positions, len(case.sensors), 6))
    meas = cases.measurements(dataclasses.replace(case, outliers=0), errors)
    assert set(meas.sigma_source) == {"scatter"}
    for q, inst, sig in (
        ("EBX", "level", 4.0),
        ("EBX", "interferometer", 2.0),
        ("EZX", "interferometer", 1.0),
    ):
        sel = (meas.quantity == QUANTITIES.index(q)) & (np.array(meas.instrument) == inst)
        # merged σ = σ_reading / √10; the pooled estimate has ~288 degrees of freedom
        got = np.median(meas.sigma[sel]) * np.sqrt(2 * case.runs) * 1e6
        assert abs(got / sig - 1) < 0.15, (q, inst, got)
    noisy = cases.readings_csv(case, errors).splitlines()[2:]
    off = 0
    for line in noisy:
        f = line.split(",")
        sig = cases.NOISE[(f[9], "linear" if f[4] in cases.LINEAR else "angular")]
        off += abs(float(f[5])) > 8 * sig
    assert off == case.outliers


def test_blind_wavelengths_are_the_presets():
    """The blind-wavelength case puts its content where the preset's rigid-table formulae say."""
    machine = cases.fit_machine(cases.baseline().points()).base
    bw = blind_wavelengths(machine, 1.0)
    expected = [
        bw["carriage_averaging_m"][0],
        bw["carriage_spacing_m"],
        bw["roll_difference_m"][0],
        bw["roll_difference_m"][1],
    ]
    np.testing.assert_allclose(cases.BLIND_WAVELENGTHS, expected, rtol=1e-9)
    assert bw["carriage_spacing_m"] in bw["pitch_yaw_mean_m"]


# ------------------------------------------------------------------ the battery


@pytest.mark.parametrize("name", _params("fit", CASES))
def test_case_returns_a_fit(name):
    res = result(name)
    assert res.error is None, res.error
    assert np.all(np.isfinite(res.score.rms_um)) and np.isfinite(res.fit.chi2_dof)


@pytest.mark.parametrize("name", list(CASES))
def test_case_converges_with_default_settings(name):
    """No case ends "not converged" with the fit's defaults (issue 28: the rich data set
    stopped after 60 Levenberg–Marquardt steps)."""
    res = result(name)
    assert res.fit is not None, res.error
    assert res.fit.converged, res.fit.message


@pytest.mark.parametrize("name", _params("coverage", CASES))
def test_truth_inside_2_sigma(name):
    res = result(name)
    assert res.fit is not None, res.error
    sc = res.score
    assert sc.overall_coverage >= 0.85, sc.coverage
    assert sc.worst_coverage >= 0.70, sc.coverage


@pytest.mark.parametrize("name", _params("error", WRONG_STRUCTURE))
def test_wrong_structure_profiles_within_15_percent(name):
    res = result(name)
    assert res.fit is not None, res.error
    assert res.score.worst_rel <= 0.15, res.score.rel


def test_stated_waviness_covers_the_blind_content():
    """What the knots cannot resolve and the carriages average out (the blind-wavelength case's
    48 mm content, 0.28 µm RMS) no data can bound; a user who states the rails' short-wave
    waviness (``waviness=``, here 0.3 µm RMS) gets bands that hold the truth: ≥ 85 % of the
    points, ≥ 70 % for every profile — and every σ² is the unstated fit's plus the waviness²."""
    from diffguide.inverse import fit_rails

    res = result("blind_wavelengths")
    case = res.case
    meas = cases.measurements(case)
    points = dict(zip(meas.point_names, map(tuple, np.asarray(meas.points_xy, float))))
    w = 0.3e-6
    fit = fit_rails(cases.fit_machine(points), meas, waviness=w)
    s = np.linspace(fit.basis.start, fit.basis.end, 51)
    np.testing.assert_allclose(fit.profiles(s)[1] ** 2, res.fit.profiles(s)[1] ** 2 + w**2,
                               rtol=1e-6)
    sc = score_fit(fit, lambda s: cases.truth_profiles(case, s))
    assert sc.overall_coverage >= 0.85 and sc.worst_coverage >= 0.70, sc.coverage


def test_blind_case_bands_hold_everything_the_data_can_see():
    """The blind-wavelength case's coverage (70/65 % before the floor on the undetermined
    directions, inverse/bands.py; 87/84 % with it) was lost entirely to the content no
    data can see: scored against its truth without the 48 mm sines (the carriages' averaging
    wavelength, also the knot spacing), the same fit holds the truth inside ±2σ at ≥ 85 % of
    the points and ≥ 70 % on every profile — the long blind wavelengths (213/320/640 mm), which
    the table's bending makes partly visible, are inside the bands. Measured: 90 % overall,
    83–95 % per profile (70 %/65 % with the 48 mm content)."""
    res = result("blind_wavelengths")
    case = res.case
    planes = {k: dataclasses.replace(p, waves=tuple(w for w in p.waves if abs(w[1] - 0.048) > 1e-9))
              for k, p in case.truth.planes.items()}
    seen = dataclasses.replace(case, truth=cases.Truth(planes))
    sc = score_fit(res.fit, lambda s: cases.truth_profiles(seen, s))
    assert sc.overall_coverage >= 0.85 and sc.worst_coverage >= 0.70, sc.coverage


def test_structure_sensitivity_matches_refitting(monkeypatch):
    """The delta method's ``G = ∂ĉ/∂q`` (``RailFit.structure_sensitivity``, a secant over ±σ_q)
    against finite differences of whole fits: the straightness case's data refitted with the
    structure held at ``q̂ ± 0.02`` (log units) along each unknown, with the fit's λ and prior
    shape — each profile's change within 10 % RMS (measured 1–5 %: the secant follows the rails'
    curvature in ``q``). The Gauss–Newton tangent ``−H⁻¹J_cᵀJ_q`` used before had the
    thickness column a third of this."""
    from diffguide.inverse import fit_rails
    from diffguide.inverse import problem as problemmod

    res = result("with_straightness")
    fit = res.fit
    meas = cases.measurements(res.case)
    points = dict(zip(meas.point_names, map(tuple, np.asarray(meas.points_xy, float))))
    family = cases.fit_machine(points)
    fixed = problemmod.fixed_weight  # refits with the fit's λ *and* its prior shape κ
    monkeypatch.setattr(problemmod, "fixed_weight", lambda *a, **k: dataclasses.replace(
        fixed(*a, **k), kappa=fit.weight.kappa))
    prior_sigma = family.prior_sigma()
    q = np.array([np.log(v["value"] / v["prior_value"]) for v in fit.structure.values()])
    s = fit.basis.grid(201)
    B = fit.basis.matrix(s)
    h = 0.02
    for i in range(len(q)):
        step = np.zeros_like(q)
        step[i] = h
        a, b = (fit_rails(family.machine(q + sgn * step), meas, lam=fit.lam).coeffs
                for sgn in (-1.0, 1.0))
        fd = (b - a) / (2 * h) * prior_sigma[i]  # m per prior σ
        g = fit.structure_sensitivity[..., i]
        for r in range(2):
            for p in range(2):
                d_fd = B @ fd[r, p]
                d_fd = d_fd - d_fd.mean()
                d_g = B @ g[r, p]
                d_g = d_g - d_g.mean()
                rel = np.sqrt(np.mean((d_g - d_fd) ** 2) / np.mean(d_fd**2))
                assert rel <= 0.10, (i, r, p, rel)


@pytest.mark.parametrize("name", [n for n in WRONG_STRUCTURE if n not in ALREADY_PLANNED])
def test_wrong_structure_nearly_as_good_as_knowing_it(name):
    """What estimating the structure costs: against the *oracle* fit — the same data and fit
    with the truth's thickness and preload given (``cases.oracle_score``) — the profile error,
    overall and on the worst profile, is at most 20 % (plus 0.02 of the truth) larger, and the
    truth stays inside ±2σ as often as there (the oracle's bands lack the structure's share).
    Measured: overall 0.154/0.165/0.087/0.061 against 0.164/0.141/0.090/0.061 (70 mm, 2 %,
    13 %, 30 mm), worst profile 0.28/0.25/0.17/0.09 against 0.30/0.22/0.17/0.09: the 15 %
    per-profile bound of the test above is beyond what these data hold for the horizontal
    profiles even with the structure known. Cases measured with the planned layout already
    (``ALREADY_PLANNED``) are left out: what they stress is the layout's undetermined
    wavelengths, which no structure estimate changes."""
    res = result(name)
    assert res.fit is not None, res.error
    sc, oracle = res.score, cases.oracle_score(name)
    assert sc.overall_rel <= 1.2 * oracle.overall_rel + 0.02, (sc.overall_rel, oracle.overall_rel)
    assert sc.worst_rel <= 1.2 * oracle.worst_rel + 0.02, (sc.rel, oracle.rel)
    assert sc.overall_coverage >= min(oracle.overall_coverage, 0.95) - 0.02


@pytest.mark.parametrize("name", _params("combinations", WRONG_STRUCTURE))
def test_wrong_structure_determined_combinations_within_15_percent(name):
    """What the data determine, the structure estimated recovers within the 15 % bound: per
    plane, the two rails' mean and, in the vertical plane, their difference (pitch, yaw and roll
    see these), each within 15 % of the plane's truth RMS. The horizontal half-difference
    ``(e₂ − e₁)/2`` moves the table only through its deformation — less the stiffer the table
    and the softer the carriages — and carries the per-profile misses of the test above.
    Measured (mean V, half-difference V, mean H | half-difference H): 3/7/5 | 22 % (70 mm),
    3/8/6 | 22 % (2 %), 5/3/7 | 10 % (13 %), 3/4/6 | 5 % (30 mm); with the truth's structure
    given (the oracle) the horizontal half-difference is 24/19/11/5 %."""
    res = result(name)
    assert res.fit is not None, res.error
    rel = res.score.combination_rel
    determined = [rel[0, 0], rel[0, 1], rel[1, 0]]
    assert max(determined) <= 0.15, rel


#: The wrong-structure cases whose 15 % per-profile bound fails (XFAIL above).
_BEYOND_THE_DATA = [n for n in WRONG_STRUCTURE
                    if ("error", n) in XFAIL and n not in ALREADY_PLANNED]


@pytest.mark.parametrize("name", _BEYOND_THE_DATA)
def test_the_15_percent_bound_is_beyond_the_data(name):
    """Why the 15 % per-profile bound stays an expected failure on these cases: fitted with *the
    machine that made the data* (``cases.truth_model_fit``: the truth's 40 × 20 mesh, thickness
    and preload — nothing unknown but the rails), the worst profile is still more than 15 % off,
    and the fit's own σ there says as much (RMS σ at least half the RMS error; the profile
    inside ±2σ at ≥ 70 % of its points): the data do not hold the horizontal half-difference to
    that bound. Measured (bench/battery_limits.py): worst profile 30/21/18 % (70 mm, 2 %, 13 %),
    the half-difference's own σ 23/18/12 % of the plane's truth RMS; with its prior's scale
    chosen in hindsight (five decades, knowing the truth) the worst profile is still 27/22/17 %.
    If this test fails, the data hold more than measured and the bound may be within reach."""
    case = result(name).case
    fit = cases.truth_model_fit(name)
    sc = score_fit(fit, lambda s: cases.truth_profiles(case, s))
    worst = np.unravel_index(int(sc.rel.argmax()), sc.rel.shape)
    assert sc.rel[worst] > 0.15, sc.rel
    assert sc.sigma_rms_um[worst] >= 0.5 * sc.rms_um[worst], (sc.rms_um, sc.sigma_rms_um)
    assert sc.coverage[worst] >= 0.70, sc.coverage


@pytest.mark.parametrize("name", [n for n in WRONG_STRUCTURE if n not in ALREADY_PLANNED])
def test_the_15_percent_bound_holds_with_the_planned_layout(name):
    """What the bound needs is more data, and the planner says which: the same wrong-structure
    case (truth, machine, noise seed, fit with the structure unknown) measured with
    ``cases.PLANNED`` — the bundled layout plus the 8 levels and 2 interferometers that
    ``diffguide plan --start bundled`` adds — meets every bound of the battery: every profile
    within 15 % of its truth RMS, the truth inside ±2σ at ≥ 85 % of the points and ≥ 70 % on
    every profile. Measured on the cases' own seeds: worst profile 8/12/10/7 % (30 mm, 70 mm,
    2 %, 13 %). A single draw can still miss: over seeds 1–10 (``bench/battery_seeds.py
    --layout planned``) the worst profile is within 15 % on 10/6/9/8 of 10 seeds, against
    8/0/0/2 with the bundled layout (README, "With more instruments").

    The structure is not asserted here: on the 2 % case the thickness comes back 62 ± 6 mm
    (2.0σ from 50 mm) with the preload undetermined (7 ± 5 %). That case's preload sits at its
    prior's 2σ edge, and the posterior correlates the two (0.8). The posterior itself is right:
    integrated on a 13 × 13 grid it gives the Laplace σ within 4 %, and the truth's joint
    −2 log p is 3.4 above the estimate's."""
    res = cases.run_case(cases.planned(CASES[name]()))
    assert res.fit is not None, res.error
    sc = res.score
    assert sc.worst_rel <= 0.15, sc.rel
    assert sc.overall_coverage >= 0.85 and sc.worst_coverage >= 0.70, sc.coverage


@pytest.mark.parametrize("name", _params("structure", WRONG_STRUCTURE))
def test_wrong_structure_parameters_within_2_sigma(name):
    """Where the truth machine differs from the prior, each structural parameter that the data
    determine comes back within its reported 2σ of the truth (undetermined ones must say so:
    their σ stays near the prior's)."""
    res = result(name)
    case = res.case
    truth = {"thickness": case.thickness or cases.FIT_PRIORS[0][0],
             "preload": case.preload or cases.FIT_PRIORS[1][0]}
    for pname, v in res.fit.structure.items():
        if v["determined"]:
            assert abs(np.log(v["value"] / truth[pname])) <= 2 * v["sigma_log"], (pname, v)
        else:
            assert v["sigma_log"] >= 0.7 * v["prior_sigma_log"]


@pytest.mark.parametrize("name", list(CASES))
def test_large_errors_come_with_large_sigma(name):
    """Honesty of σ: where the error is large, σ is large too — the RMS error of every profile
    stays below 3× its RMS σ (a Gaussian error inside its band has ratio ≈ 1)."""
    res = result(name)
    sc = res.score
    assert np.all(sc.rms_um <= 3 * sc.sigma_rms_um + 1e-3), (sc.rms_um, sc.sigma_rms_um)


def test_the_structure_estimate_is_the_minimum_of_its_objective(monkeypatch):
    """The marginal search ends at a minimum of its own objective (``−2 log p(y|q) + ‖q‖²``),
    checked by brute force: on the 30 mm table measured with ``cases.PLANNED`` (seed 2), where
    thickness and preload make a narrow, curved valley, no point of a 7 × 7 grid of ±3
    conditional σ around the estimate lies lower, nor does the truth. With a fixed 0.3 prior-σ
    difference step the search stopped at (−1.0, +2.1) prior σ, 2.3 above the objective at the
    truth, and called it converged."""
    import dataclasses

    import diffguide.inverse.structure_stage as stage_module

    calls = []
    search = stage_module.maximise_marginal

    def recording(score, q0, bounds, **kw):
        sol = search(score, q0, bounds, **kw)
        calls.append((score, sol.value, sol.state.cov, bounds))
        return sol

    monkeypatch.setattr(stage_module, "maximise_marginal", recording)
    case = dataclasses.replace(cases.planned(CASES["thickness_30mm"]()), seed=2)
    res = cases.run_case(case)
    assert res.fit is not None, res.error
    score, q, cov, bounds = calls[-1]
    f0 = score(q)
    thickness = res.fit.structure["thickness"]  # q is ln(t / prior value) in prior σ
    truth = np.array([np.log(case.thickness / thickness["prior_value"])
                      / thickness["prior_sigma_log"], 0.0])
    assert f0 <= score(truth) + 0.05, (q, f0, score(truth))
    H = np.linalg.inv(cov / 2.0)  # the search's curvature (cov = 2 H⁻¹, widened at most)
    cond = np.sqrt(2.0 / np.diag(H))
    for a in np.linspace(-3, 3, 7):
        for b in np.linspace(-3, 3, 7):
            p = np.clip(q + np.array([a, b]) * cond, bounds[:, 0], bounds[:, 1])
            assert score(p) >= f0 - 0.05, (p, score(p), q, f0)


#: Issue 28's two cases whose bands must hold in each plane: large rails with horizontal
#: content (rows unload: the model is not linear across the posterior) and the planned layout
#: with content at the wavelengths it leaves undetermined (the bands there are the prior's).
PER_PLANE = ("large_rails_horizontal", "large_random_rails", "planned_undetermined")


@pytest.mark.parametrize("name", _params("per_plane", PER_PLANE))
def test_truth_inside_2_sigma_per_plane(name):
    """The truth inside ±2σ at ≥ 85 % of the points in each plane (vertical, horizontal; both
    rails' profiles together, scored on the same points). Measured (vertical / horizontal),
    before → after the floor on the undetermined directions (inverse/bands.py) and the
    randomised-maximum-likelihood spread (inverse/spread.py): planned_undetermined 71/91 % →
    100/100 % (σ RMS 0.21 → 0.60 µm against errors of 0.32-0.37 µm RMS);
    large_rails_horizontal 95/60 % → 98/83 % → 100/98 % with the knots refined where χ²/dof
    stayed at 5 (:func:`diffguide.inverse.fit.refine_knots`: 46 → 23 mm, χ²/dof 1.1);
    large_random_rails (issue 39: random rails, content from 90 mm up, 15/12 µm) 99/100 %
    (χ²/dof 22 on 46 mm knots → 1.14 on 23 mm)."""
    res = result(name)
    assert res.fit is not None, res.error
    sc = res.score
    per_plane = sc.coverage.mean(axis=0)
    assert np.all(per_plane >= 0.85), (per_plane, sc.coverage)

def test_rich_data_structure_within_2_sigma():
    """The rich data set (a level and an interferometer at each corner, 71 positions; issue 39:
    on a hidden case of this kind the preload came back 5.65 ± 0.86 % against 8 %, 2.7σ):
    thickness and preload each within 2σ of the truth (50 mm, 8 %), the z-score taken in the
    log units the fit reports (``|ln(value/truth)| / sigma_log``)."""
    res = result("rich_data")
    assert res.fit is not None, res.error
    truth = {"thickness": cases.FIT_PRIORS[0][0], "preload": cases.FIT_PRIORS[1][0]}
    for pname, v in res.fit.structure.items():
        z = np.log(v["value"] / truth[pname]) / v["sigma_log"]
        assert abs(z) <= 2.0, (pname, v["value"], v["sigma"], z)


# ------------------------------------------------------------------ prediction (issue 28)


@pytest.mark.parametrize("name", _params("prediction", CASES))
def test_prediction_at_unmeasured_points_within_2_sigma(name):
    """The fit's prediction of the six joint errors at (±300, ±100) mm, where no instrument
    stood (:func:`battery.cases.prediction_score`): the truth inside ±2σ at >= 85 % of the
    (position, point, quantity) values."""
    res = result(name)
    assert res.fit is not None, res.error
    sc = cases.prediction_score(name)
    assert sc.coverage >= 0.85, (sc.coverage, sc.coverage_q, sc.rel_q)


def test_rail_joint_steps_recovered_within_2_sigma():
    """The ``rail_joint_step`` case, its joint stated to the fit (137 mm): rail 1 steps 3 µm
    vertically and 2 µm horizontally (a tanh of 2.5 mm, not the fit's quintic ramp), rail 2 not
    at all; each fitted step within 2σ of that. Without the joint the spline rang over ±150 mm
    around it and the prediction at the unmeasured points covered 76 % (bench/battery_predict.py
    before the step term); with it, the prediction test above."""
    fit = result("rail_joint_step").fit
    steps = {(d["rail"], d["plane"]): (d["value"], d["sigma"]) for d in fit.joint_steps()}
    truth = {(1, "vertical"): 3e-6, (1, "horizontal"): 2e-6, (2, "vertical"): 0.0,
             (2, "horizontal"): 0.0}
    for key, want in truth.items():
        value, sigma = steps[key]
        assert abs(value - want) <= 2 * sigma, (key, value * 1e6, sigma * 1e6)
        assert sigma < 1e-6, (key, sigma)  # the data determine the step: not the prior's width
