"""The misfit diagnosis (:mod:`diffguide.inverse.diagnose`) on residuals constructed here with a
known cause — white noise, one channel's σ understated, a drift, content shorter than the knots
resolve, content they do resolve — and on a real fit with coarse knots."""

import numpy as np
import pytest

from diffguide.inverse.diagnose import (
    PEAK_F,
    TREND_F,
    channel_stats,
    diagnose,
    trial_wavelengths,
)

X = np.linspace(-0.35, 0.35, 71)  # positions (m), the bundled 10 mm grid
N_CHAN = 6
LABELS = [f"P{c} EBX" for c in range(N_CHAN)]


def _residuals(seed=0, scale=None, extra=None):
    """White N(0, 1) per channel (times ``scale[c]``) plus ``extra(c, x)``: ``(z, chan, x)``."""
    rng = np.random.default_rng(seed)
    z, chan, x = [], [], []
    for c in range(N_CHAN):
        v = rng.normal(0.0, 1.0, len(X)) * (1.0 if scale is None else scale[c])
        if extra is not None:
            v = v + extra(c, X)
        z.append(v)
        chan.append(np.full(len(X), c))
        x.append(X)
    return np.concatenate(z), np.concatenate(chan), np.concatenate(x)


def _chi2_dof(z):
    return float(z @ z / (len(z) * 0.8))  # some dof taken by the fit: any value > threshold


def _run(z, chan, x, h=0.096, **kw):
    return diagnose(z, chan, x, chi2_dof=_chi2_dof(z), knot_spacing=h, default_spacing=0.048,
                    labels=LABELS, **kw)


def test_nothing_is_examined_below_the_threshold():
    z, chan, x = _residuals()
    assert diagnose(z, chan, x, chi2_dof=1.1, knot_spacing=0.048) == []


def test_white_residuals_are_neither_trend_nor_structure():
    """On white noise the trend and peak statistics stay below their thresholds over many
    draws (their false-alarm rates are tiny by construction)."""
    rng = np.random.default_rng(11)
    wl = trial_wavelengths(X)
    alarms = 0
    for _ in range(200):
        s = channel_stats(rng.normal(size=len(X)), X, wl)
        alarms += s.trend_f > TREND_F or s.peak_f > PEAK_F
    assert alarms <= 2


def test_every_sigma_understated():
    z, chan, x = _residuals(scale=[3.0] * N_CHAN)
    (f,) = _run(z, chan, x)
    assert f.cause == "sigma_all" and f.values["ratio"] == pytest.approx(3.0 / 0.8**0.5, rel=0.15)


def test_one_channel_sigma_understated():
    scale = [1.0] * N_CHAN
    scale[4] = 5.0
    z, chan, x = _residuals(scale=scale)
    found = _run(z, chan, x)
    assert [f.cause for f in found] == ["sigma"] and found[0].channels == (4,)
    assert found[0].values["ratio"] == pytest.approx(5.0, rel=0.25)
    assert "P4 EBX" in found[0].message


def test_a_drift_is_a_missing_nuisance():
    # channel 2 drifts linearly by ±8 σ over the stroke
    z, chan, x = _residuals(extra=lambda c, x: (c == 2) * 8.0 * x / 0.35)
    found = _run(z, chan, x)
    assert [f.cause for f in found] == ["nuisance"] and found[0].channels == (2,)
    assert found[0].values["slope_sigma_per_mm"] == pytest.approx(8.0 / 350.0, rel=0.15)


def test_content_shorter_than_the_knots_resolve():
    # a 100 mm wave in every channel (different phases), knots 96 mm: refit at the default
    z, chan, x = _residuals(extra=lambda c, x: 3.0 * np.sin(2 * np.pi * x / 0.1 + c))
    found = _run(z, chan, x, h=0.096)
    assert [f.cause for f in found] == ["knots"]
    assert found[0].values["wavelength_mm"] == pytest.approx(100.0, rel=0.05)
    assert found[0].values["suggested_knot_spacing_mm"] == 48.0
    assert found[0].action == "refit with --knot-spacing-mm 48"
    # 250 mm content with knots of 192 mm: a quarter wavelength, above the default
    z, chan, x = _residuals(extra=lambda c, x: 3.0 * np.sin(2 * np.pi * x / 0.25 + c))
    (f,) = _run(z, chan, x, h=0.192)
    assert f.cause == "knots" and f.values["suggested_knot_spacing_mm"] == pytest.approx(62, abs=2)


def test_content_the_knots_resolve_is_the_model():
    z, chan, x = _residuals(extra=lambda c, x: 3.0 * np.sin(2 * np.pi * x / 0.3 + c))
    (f,) = _run(z, chan, x, h=0.048)
    assert f.cause == "model" and f.values["wavelength_mm"] == pytest.approx(300.0, rel=0.08)


def test_uneven_positions_and_outlier_free_rows():
    """The periodogram is a least-squares one: uneven positions are fine."""
    rng = np.random.default_rng(4)
    xs = np.sort(rng.uniform(-0.35, 0.35, 60))
    z = np.concatenate([rng.normal(size=60) + 3.0 * np.sin(2 * np.pi * xs / 0.12 + c)
                        for c in range(3)])
    chan, x = np.repeat(np.arange(3), 60), np.tile(xs, 3)
    (f,) = diagnose(z, chan, x, chi2_dof=5.0, knot_spacing=0.096, default_spacing=0.048)
    assert f.cause == "knots" and f.values["wavelength_mm"] == pytest.approx(120.0, rel=0.06)


def test_a_real_fit_with_coarse_knots_names_the_knots():
    """Rails with content from 90 to 900 mm (the battery's rich truth), measured at the bundled
    layout through the preset's model with 0.3 µrad noise, fitted with knots every ~200 mm:
    χ²/dof far above 1, the knots named, and the suggested spacing brings it back near 1."""
    from battery import cases

    from diffguide.inverse import fit_rails
    from diffguide.inverse.data import Measurements
    from diffguide.inverse.diagnose import diagnose_fit
    from diffguide.machine.kinematics import joint_errors
    from diffguide.machine.majda2012 import majda2012_machine

    points = {name: (x * 1e-3, y * 1e-3) for name, x, y, _, _ in cases.BUNDLED}
    machine = majda2012_machine(points=points)
    je = joint_errors(machine, cases.truth_rails(cases.CASES["rich_truth"]()), X)
    err = np.asarray(je.errors)  # (n_pos, n_points, 6), SI
    rng = np.random.default_rng(7)
    rows = [(x, name, q, err[i, k, cases.QUANTITIES.index(q)] + 3e-7 * rng.normal(), inst)
            for i, x in enumerate(X) for k, (name, _, _, inst, qs) in enumerate(cases.BUNDLED)
            for q in qs]
    pos, point, quantity, value, inst = zip(*rows)
    meas = Measurements.from_arrays(points, pos, point, quantity, value, 3e-7, inst)
    fit = fit_rails(machine, meas, knot_spacing=0.2)
    findings = diagnose_fit(fit, meas, default_spacing=machine.carriage.length)
    assert fit.chi2_dof > 2.0 and findings and findings[0].cause == "knots", (fit.chi2_dof,
                                                                           findings)
    suggested = findings[0].values["suggested_knot_spacing_mm"]
    assert 48.0 <= suggested < 150.0
    refit = fit_rails(machine, meas, knot_spacing=suggested * 1e-3)
    assert refit.chi2_dof < 0.5 * fit.chi2_dof and diagnose_fit(refit, meas, 0.048) == []
