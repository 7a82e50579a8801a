"""The automatic knot refinement (:func:`diffguide.inverse.fit.refine_knots`): its rule on
stand-in fits (χ²/dof as a stated function of the spacing); on a real case (large rails, rows
unloading: χ²/dof 5 → 1.1 on knots half as far apart) in tests/test_battery.py."""

import types

import pytest

from diffguide.inverse.fit import REFINE_CHI2, REFINE_FLOOR, refine_knots


def _fit(h, chi2):
    return types.SimpleNamespace(basis=types.SimpleNamespace(spacing=h), chi2_dof=chi2,
                                 message="")


def _fitter(chi2_of, calls):
    def fit_on(h, note):
        calls.append(h)
        f = _fit(h, chi2_of(h))
        f.message = note
        return f
    return fit_on


def test_a_good_fit_is_left_alone():
    calls = []
    fit = _fit(0.048, 1.3)
    assert refine_knots(fit, _fitter(lambda h: 1.0, calls)) is fit and calls == []


def test_refines_while_it_helps_and_says_so():
    calls = []
    chi2 = {0.024: 2.5, 0.012: 1.1}
    out = refine_knots(_fit(0.048, 6.0), _fitter(chi2.get, calls))
    assert calls == pytest.approx([0.024, 0.012]) and out.basis.spacing == pytest.approx(0.012)
    assert "χ²/dof 6 on 48 mm knots: refitted on 24 mm knots" in out.message
    assert out.message.endswith("χ²/dof 2.5 on 24 mm knots: refitted on 12 mm knots")


def test_keeps_the_coarser_fit_when_finer_knots_do_not_help():
    calls = []
    fit = _fit(0.048, 6.0)
    assert refine_knots(fit, _fitter(lambda h: 5.0, calls)) is fit and len(calls) == 1


def test_stops_at_the_floor():
    calls = []
    chi2 = {0.024: 50.0, 0.012: 20.0, 0.006: 8.0}
    out = refine_knots(_fit(0.048, 100.0), _fitter(chi2.get, calls))
    assert calls == pytest.approx([0.024, 0.012]) and min(calls) == pytest.approx(
        REFINE_FLOOR * 0.048)
    assert out.chi2_dof == 20.0 > REFINE_CHI2
