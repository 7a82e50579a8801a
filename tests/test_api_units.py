"""The API checks units like the CLI: lengths in metres within a plausible range (with a hint
when a value looks like millimetres), integers positive, a file path refused with what to pass;
early refusals (a one-element carriage row, a measurement grid of thousands of positions).

Each test is one of the audit's reproducers or a valid edge value that must stay accepted. The
refusals happen before any solve, so the tests are fast; one small linear fit serves
``RailFit.profiles``."""

import dataclasses
import types
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide import (
    MachineFamily,
    Prior,
    StraightRail,
    StructurePriors,
    fit_rails,
    joint_errors,
    majda2012_machine,
    paper_variant,
    read_measurements,
)
from diffguide._core.checks import instance, length, positive_int
from diffguide.cli import main
from diffguide.fe.table import TableSpec
from diffguide.inverse.basis import RailBasis
from diffguide.inverse.data import Measurements
from diffguide.inverse.fit import RailFit
from diffguide.inverse.merge import MAX_POSITIONS
from diffguide.inverse.problem import build_problem
from diffguide.io.config import load_config
from diffguide.machine.majda2012 import majda2012_spec
from diffguide.machine.spec import MachineSpec

DATA = Path(__file__).parents[1] / "data" / "majda2012_measurements.csv"


@pytest.fixture(scope="module")
def machine():
    return majda2012_machine(nx=10, ny=6)


@pytest.fixture(scope="module")
def meas():
    return read_measurements(DATA)


# --- the helpers ---------------------------------------------------------------------------------


def test_length_names_argument_value_range_and_mm_hint():
    with pytest.raises(ValueError) as exc:
        length("knot_spacing", 48.0, 1e-3, 5.0)
    text = str(exc.value)
    for part in ("knot_spacing", "48 m", "[0.001, 5] m", "did you mean 48 mm = 0.048 m?"):
        assert part in text, part
    # no hint when the value read as mm is not allowed either
    with pytest.raises(ValueError) as exc:
        length("x", -7.0, 0.0, 1.0)
    assert "did you mean" not in str(exc.value)
    with pytest.raises(ValueError, match="finite"):
        length("x", np.nan, 0.0, 1.0)
    assert length("x", 0.048, 1e-3, 5.0) == 0.048
    assert length("x", 1e-3, 1e-3, 5.0) == 1e-3  # ranges are inclusive


def test_length_lets_traced_values_through():
    # inside jit the value is a tracer: unchecked (its concrete caller was checked), and the
    # function still differentiates
    def f(t):
        return length("thickness", t, 1e-3, 2.0) ** 2

    assert float(jax.jit(f)(50.0)) == 2500.0
    assert float(jax.grad(f)(3.0)) == 6.0


@pytest.mark.parametrize("value", [0, -1, 2.5, np.inf])
def test_positive_int_refuses(value):
    with pytest.raises(ValueError, match=f"n must be an integer >= 1, got {value!r}"):
        positive_int("n", value)


def test_positive_int_types():
    with pytest.raises(TypeError, match="n must be an integer"):
        positive_int("n", "60")
    with pytest.raises(TypeError):
        positive_int("n", True)
    assert positive_int("n", np.int64(3)) == 3 and positive_int("n", 4.0) == 4
    with pytest.raises(ValueError, match=">= 2, got 1"):
        positive_int("n", 1, 2)


def test_instance_says_what_to_pass():
    with pytest.raises(TypeError, match=r"meas must be Measurements, got str 'a\.csv'; pass X"):
        instance("meas", "a.csv", Measurements, "pass X")


# --- fit_rails: refused before any work ---------------------------------------------------------


def test_fit_knot_spacing_in_metres_typed_as_mm_is_refused(machine, meas):
    with pytest.raises(ValueError, match=r"knot_spacing .*\[0\.001, 5\] m, got 48 m: did you "
                                         r"mean 48 mm = 0\.048 m\?"):
        fit_rails(machine, meas, knot_spacing=48.0)


def test_fit_knot_spacing_48_mm_is_accepted(machine, meas):
    # the valid edge value: the problem builds, with knots no wider than asked
    p = build_problem(machine, meas, knot_spacing=0.048, lam=None, criterion="ml", x_ref=0.0)
    assert 0.0 < p.basis.spacing <= 0.048 + 1e-12


@pytest.mark.parametrize("max_steps", [-1, 1.5])
def test_fit_max_steps_must_be_a_non_negative_integer(machine, meas, max_steps):
    # 0 is allowed, as in the CLI's --max-steps: the start only, reported as not converged
    with pytest.raises(ValueError, match=f"max_steps must be an integer >= 0, got {max_steps}"):
        fit_rails(machine, meas, max_steps=max_steps)


def test_fit_path_instead_of_measurements_is_a_type_error(machine):
    for path in (str(DATA), DATA):
        with pytest.raises(TypeError, match=r"meas must be Measurements.*"
                                            r"pass diffguide\.read_measurements\(path\)"):
            fit_rails(machine, path)


def test_fit_x_ref_in_mm_is_refused(machine, meas):
    with pytest.raises(ValueError, match=r"x_ref .*\[-25, 25\] m, got 300 m: did you mean "
                                         r"300 mm = 0\.3 m\?"):
        fit_rails(machine, meas, x_ref=300.0)


def test_fit_positions_beyond_the_stroke_are_refused(machine, meas):
    """The audit's positions at 5 m: the bundled readings' positions × 14 (the majda2012 stroke
    is 700 mm, ±0.35 m; the readings reach ±0.35 m) are refused naming the stroke; the machine
    knows its stroke from its specification."""
    assert machine.stroke == pytest.approx(0.7)
    far = dataclasses.replace(meas, position=meas.position * 14.0)
    with pytest.raises(ValueError, match=r"meas\.position reaches -?4\.9 m, beyond the "
                                         r"machine's stroke \[-0\.35, 0\.35\] m"):
        fit_rails(machine, far)


@pytest.mark.parametrize("kw", [{"lam": -1.0}, {"lam": np.nan}, {"rtol": 0.0}])
def test_fit_weights_and_tolerances_must_be_positive(machine, meas, kw):
    name = next(iter(kw))
    with pytest.raises(ValueError, match=f"{name} must be a finite"):
        fit_rails(machine, meas, **kw)


def test_fit_default_knots_of_a_one_element_carriage_name_the_fix(machine, meas):
    one = majda2012_machine(nx=10, ny=6)
    one = dataclasses.replace(one, carriage=dataclasses.replace(one.carriage, xi=np.zeros(1)))
    with pytest.raises(ValueError, match=r"loaded length, is 0 m.*elements_per_row >= 2"):
        fit_rails(one, meas)


# --- the machine: table, carriage, priors -------------------------------------------------------


def test_50_m_plate_is_refused_with_the_mm_hint():
    with pytest.raises(ValueError, match=r"thickness .*\[0\.001, 2\] m, got 50 m: did you mean "
                                         r"50 mm = 0\.05 m\?"):
        majda2012_machine(nx=10, ny=6, thickness=50.0)
    t = majda2012_spec().table
    with pytest.raises(ValueError, match="thickness"):
        TableSpec(t.length, t.width, 50.0, t.material, t.nx, t.ny)
    with pytest.raises(ValueError, match=r"length .*got 1200 m: did you mean 1200 mm = 1\.2 m"):
        TableSpec(1200.0, t.width, t.thickness, t.material, t.nx, t.ny)


def test_25_mm_table_is_accepted():
    m = majda2012_machine(nx=10, ny=6, thickness=0.025)
    assert np.all(np.isfinite(np.asarray(m.table.K)))


def test_thickness_stays_differentiable(machine):
    # a traced thickness is not checked: the derivative of a condensed stiffness still exists
    g = jax.grad(lambda t: majda2012_machine(nx=4, ny=2, thickness=t).table.K[0, 0])(0.1)
    assert np.isfinite(float(g)) and float(g) != 0.0


def test_one_element_per_row_is_refused_by_the_spec():
    spec = majda2012_spec()
    carriage = dataclasses.replace(spec.carriage, elements_per_row=1)
    with pytest.raises(ValueError, match="carriage.elements_per_row must be an integer >= 2"):
        dataclasses.replace(spec, carriage=carriage)


def test_one_element_per_row_in_a_file_is_refused_up_front(tmp_path):
    f = tmp_path / "m.toml"
    f.write_text("[carriage]\nelements_per_row = 1\n")
    with pytest.raises(ValueError, match=r"key 'carriage\.elements_per_row': 1 outside the allowed "
                                         r"range \[2, 200\]"):
        load_config(f)
    f.write_text("[carriage]\nelements_per_row = 2\n")
    assert load_config(f)["carriage"]["elements_per_row"] == 2


def test_stroke_and_footprint_in_mm_are_refused():
    spec = majda2012_spec()
    with pytest.raises(ValueError, match=r"stroke .*got 700 m: did you mean 700 mm = 0\.7 m"):
        MachineSpec(spec.table, spec.guideway, spec.carriage, spec.screw, spec.points,
                    spec.ribs, spec.gravity, 700.0)
    with pytest.raises(ValueError, match=r"footprint\[0\] .*did you mean"):
        dataclasses.replace(spec.guideway, footprint=(70.0, 0.05))


def test_thickness_prior_in_mm_is_refused_before_condensing():
    calls = []

    def make(**kw):
        calls.append(kw)
        return majda2012_machine(nx=4, ny=2, **kw)

    with pytest.raises(ValueError, match=r"thickness .*did you mean 50 mm = 0\.05 m"):
        MachineFamily.build(make, StructurePriors(thickness=Prior(50.0, 25.0, 100.0)))
    assert len(calls) == 1  # refused on the first machine, no table condensed


# --- joint_errors: positions --------------------------------------------------------------------


def test_joint_errors_positions_in_mm_are_refused(machine):
    with pytest.raises(ValueError, match=r"positions .*\[-25, 25\] m, got 300 m: did you mean "
                                         r"300 mm = 0\.3 m\?"):
        joint_errors(machine, paper_variant(3), [-0.3, 300.0])
    with pytest.raises(ValueError, match=r"x_ref .*got -350 m"):
        joint_errors(machine, paper_variant(3), [0.1], -350.0)


def test_joint_errors_traced_positions_are_not_checked(machine):
    # under jit the positions are tracers: the shape is still checked, the values are not
    rails = (StraightRail(), StraightRail())
    out = jax.eval_shape(lambda x: joint_errors(machine, rails, x).errors, jnp.zeros(3))
    assert out.shape[0] == 3


# --- RailFit.profiles: the fitted range ---------------------------------------------------------


@pytest.fixture(scope="module")
def small_fit(machine, meas):
    return fit_rails(machine, meas, method="linear", lam=1.0)


def test_profiles_in_mm_are_refused_with_the_fitted_range(small_fit):
    lo, hi = small_fit.basis.start, small_fit.basis.end
    with pytest.raises(ValueError) as exc:
        small_fit.profiles(300.0)
    text = str(exc.value)
    for part in (f"[{lo:g}, {hi:g}] m", f"{lo * 1e3:g} .. {hi * 1e3:g} mm", "got 300 m",
                 "did you mean 300 mm = 0.3 m?", "extrapolate=True"):
        assert part in text, part
    val, _ = small_fit.profiles(0.3)  # the meant value
    assert val.shape == (2, 2) and np.all(np.isfinite(val))
    small_fit.profiles([lo, hi])  # the ends are inside
    with pytest.raises(ValueError, match="fitted range"):
        small_fit.to_dataframe([hi + 0.01])


@pytest.fixture(scope="module")
def stub_fit():
    rng = np.random.default_rng(5)
    fit = types.SimpleNamespace(basis=RailBasis(-0.4, 0.1, 11),
                                coeffs=rng.normal(size=(2, 2, 11)) * 1e-6,
                                cov=np.eye(44) * 1e-14, waviness=0.0)
    fit.profiles = lambda s, **kw: RailFit.profiles(fit, s, **kw)
    return fit


def test_profiles_extrapolate_continues_the_end_cubics(stub_fit):
    # independent: scipy's B-spline on the same uniform knots, extrapolating its end pieces
    from scipy.interpolate import BSpline

    b = stub_fit.basis
    s = np.array([b.start - 0.05, b.end + 0.07])
    with pytest.raises(ValueError, match="fitted range"):
        RailFit.profiles(stub_fit, s)
    val, _ = RailFit.profiles(stub_fit, s, extrapolate=True)
    t = b.start + (np.arange(b.n_coeffs + 4) - 3.0) * b.spacing
    for r in range(2):
        for p in range(2):
            ref = BSpline(t, stub_fit.coeffs[r, p], 3, extrapolate=True)(s)
            np.testing.assert_allclose(val[r, p], ref, rtol=1e-10, atol=1e-18)
    df = RailFit.to_dataframe(stub_fit, s, extrapolate=True)
    assert len(df) == 4


# --- the measurement grid -----------------------------------------------------------------------


def _swapped(tmp_path) -> Path:
    """The bundled file with its position_mm and value columns swapped (the audit's case)."""
    lines = DATA.read_text().splitlines()
    out, header = [], True
    for line in lines:
        if line.startswith("#") or not line.strip() or header:
            header = header and (line.startswith("#") or not line.strip())
            out.append(line)
            continue
        cells = line.split(",")
        cells[0], cells[5] = cells[5], cells[0]
        out.append(",".join(cells))
    f = tmp_path / "swapped.csv"
    f.write_text("\n".join(out) + "\n")
    return f


def test_swapped_columns_are_refused_early(tmp_path):
    f = _swapped(tmp_path)
    n_readings = sum(1 for line in DATA.read_text().splitlines()
                     if line.strip() and not line.startswith("#")) - 1
    with pytest.raises(ValueError) as exc:
        read_measurements(f)
    text = str(exc.value)
    assert f"from {n_readings} readings" in text
    n = int(text.split(": ")[1].split(" distinct")[0])
    assert n > MAX_POSITIONS
    assert "position and value columns swapped?" in text and "allow_many_positions" in text
    # confirmed: merged (the positions are the readings' values, now in mm)
    meas = read_measurements(f, allow_many_positions=True)
    assert len(np.unique(np.round(meas.position, 6))) == n


def test_import_cli_refuses_swapped_columns_unless_confirmed(tmp_path, capsys):
    f = _swapped(tmp_path)
    out = tmp_path / "long.csv"
    assert main(["import", str(f), "--out", str(out)]) == 2
    assert "--allow-many-positions" in capsys.readouterr().err
    assert not out.exists()
    assert main(["import", str(f), "--out", str(out), "--allow-many-positions", "-q"]) == 0
    assert out.exists()


def test_bundled_grid_is_accepted(meas):
    assert len(np.unique(meas.position)) < MAX_POSITIONS
