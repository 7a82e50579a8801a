"""Tolerance allocation (:mod:`diffguide.studies.tolerance`, ``diffguide tolerance``).

The order-statistic interval against the binomial distribution summed by hand and against
repeated sampling; the Wilson interval against its published value; the root-finder on a closed
form; the allocated grade against a second path (rails drawn directly at that grade — the
measure is then at the limit), against the model's homogeneity (rails in µm: errors all but
linear in the grade) and against a plain Monte Carlo on fresh rails."""

import json
import math

import numpy as np
import pytest

from diffguide.cli import main
from diffguide.machine.majda2012 import majda2012_machine
from diffguide.studies.montecarlo import batched_sweep
from diffguide.studies.random_rails import GaussianRailModel, sample_rails
from diffguide.studies.tolerance import (
    _root,
    allocate_grade,
    measure_unit,
    measure_values,
    order_statistic_bounds,
    wilson_interval,
)

X = np.linspace(-0.3, 0.3, 13)
N = 64
ELL = 0.2


@pytest.fixture(scope="module")
def machine():
    return majda2012_machine(nx=10, ny=5)


@pytest.fixture(scope="module")
def allocated(machine):
    return allocate_grade(machine, X, measure="roll_difference", limit=3e-6, probability=0.8,
                          correlation_length=ELL, n_samples=N, check_samples=128, chunk_size=32)


def _binom_cdf(k, n, p):
    return sum(math.comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(k + 1))


@pytest.mark.parametrize(("n", "p"), [(64, 0.8), (200, 0.95), (1000, 0.5)])
def test_order_statistic_bounds_are_the_binomials_tightest_equal_tails(n, p):
    lo, hi = order_statistic_bounds(n, p)
    assert 1 <= lo < hi <= n
    # P(m_(l) <= ξ_p <= m_(u)) = P(l <= B < u) = F(u-1) - F(l-1), each tail <= 2.5 %
    assert _binom_cdf(lo - 1, n, p) <= 0.025 < _binom_cdf(lo, n, p)
    assert 1 - _binom_cdf(hi - 1, n, p) <= 0.025 < 1 - _binom_cdf(hi - 2, n, p)


def test_order_statistic_interval_covers_the_quantile_by_sampling():
    """Uniform draws, whose p-quantile is p: the interval holds it at >= 95 % of 4000 draws."""
    n, p = 64, 0.8
    lo, hi = order_statistic_bounds(n, p)
    m = np.sort(np.random.default_rng(1).uniform(size=(4000, n)), axis=1)
    covered = (m[:, lo - 1] <= p) & (p <= m[:, hi - 1])
    assert covered.mean() >= 0.95 - 3 * np.sqrt(0.95 * 0.05 / 4000)


def test_too_few_samples_for_the_interval():
    with pytest.raises(ValueError, match="too few"):
        order_statistic_bounds(20, 0.95)


def test_wilson_interval_published_value():
    """8 of 10: 0.490 .. 0.943 (Newcombe, Stat. Med. 17 (1998) 857, Table I)."""
    lo, hi = wilson_interval(8, 10)
    assert lo == pytest.approx(0.4902, abs=1e-4) and hi == pytest.approx(0.9433, abs=1e-4)


def test_root_closed_form_and_infinite_side():
    g = lambda x: x**2 - 4e-12  # noqa: E731 — root at 2e-6
    assert _root(g, 1e-6, 4e-12, "g") == pytest.approx(2e-6, rel=1e-3)
    h = lambda x: (x - 3e-6) if x < 5e-6 else np.inf  # noqa: E731 — samples fail past 5 µm
    assert _root(h, 1e-7, 1e-6, "h") == pytest.approx(3e-6, rel=1e-3)
    with pytest.raises(ValueError, match="no grade"):
        _root(lambda x: 1.0, 1e-6, 1.0, "const")


def test_measure_names_and_units(machine):
    assert measure_unit("roll_difference") == "µrad"
    assert measure_unit("range:EZX:P1") == "µm" and measure_unit("range:ECX:P5") == "µrad"
    for bad in ("range:EQX:P1", "range:EAX", "peak:EAX:P1"):
        with pytest.raises(ValueError, match="roll_difference' or 'range:ERR:POINT"):
            measure_unit(bad)
    rails = sample_rails(0, 2, GaussianRailModel(1e-6, ELL), knots=None)
    res = batched_sweep(machine, rails, X[:3])
    with pytest.raises(ValueError, match="no control point 'Q9'"):
        measure_values(res, "range:EAX:Q9")


def test_the_quantile_at_the_grade_is_the_limit(machine, allocated):
    """Second path: the same draws made directly at the grade (sample_rails at RMS σ*)."""
    res = allocated
    rails = sample_rails(0, N, GaussianRailModel(res.grade, ELL))
    m = np.sort(measure_values(batched_sweep(machine, rails, X), "roll_difference"))
    q = m[math.ceil(N * 0.8) - 1]
    assert q == pytest.approx(3e-6, rel=3e-3)
    lo, hi = res.interval
    assert lo < res.grade < hi and res.failed == 0


def test_the_grade_scales_as_the_model_is_linear(machine, allocated):
    """Rails of µm: the errors are homogeneous of degree one in the grade, so the grade for a
    limit L is L over the quantile at 1 µm (to the model's slight nonlinearity)."""
    rails = sample_rails(0, N, GaussianRailModel(1e-6, ELL))
    m = np.sort(measure_values(batched_sweep(machine, rails, X), "roll_difference"))
    assert allocated.grade == pytest.approx(1e-6 * 3e-6 / m[math.ceil(N * 0.8) - 1], rel=0.01)


def test_plain_monte_carlo_check_holds(allocated):
    c = allocated.check
    assert c is not None and c.n == 128 and c.seed == 1
    assert c.claimed == pytest.approx(wilson_interval(math.ceil(N * 0.8), N))
    assert c.holds, c


def test_a_mounting_class_that_alone_breaks_the_limit(machine):
    with pytest.raises(ValueError, match="size25-ZO.*choose a tighter mounting class"):
        allocate_grade(machine, X, measure="range:EBX:P1", limit=1e-6, probability=0.8,
                       correlation_length=ELL, mounting="size25-ZO", n_samples=32,
                       check_samples=0, chunk_size=32)


def test_bad_arguments(machine):
    for kw, match in (({"limit": -1.0}, "limit"), ({"probability": 1.0}, "probability"),
                      ({"measure": "range:EAX"}, "measure")):
        args = {"measure": "roll_difference", "limit": 1e-6, "probability": 0.8, **kw}
        with pytest.raises(ValueError, match=match):
            allocate_grade(machine, X, correlation_length=ELL, n_samples=32, **args)


def test_cli(tmp_path, capsys):
    out = tmp_path / "tol.json"
    assert main(["tolerance", "--limit", "3", "--probability", "0.8", "--samples", "64",
                 "--check-samples", "64", "--mesh", "10x5", "--positions=-300:300:13",
                 "--chunk", "32", "--out", str(out), "--no-cache"]) == 0
    text = capsys.readouterr().out
    assert "rail straightness grade for roll_difference <= 3 µrad at probability 0.8" in text
    d = json.loads(out.read_text())
    assert d["unit"] == "µrad" and d["samples"] == 64 and d["check"]["samples"] == 64
    assert d["interval_um"][0] < d["grade_um"] < d["interval_um"][1]


@pytest.mark.parametrize(("argv", "match"), [
    (["--limit", "0"], "--limit must be"),
    (["--limit", "3", "--probability", "1.5"], "--probability must be"),
    (["--limit", "3", "--samples", "8"], "--samples must be"),
    (["--limit", "3", "--measure", "range:EQX:P1"], "range:ERR:POINT"),
])
def test_cli_bad_arguments(tmp_path, capsys, argv, match):
    assert main(["tolerance", *argv, "--no-cache"]) == 2
    assert match in capsys.readouterr().err
