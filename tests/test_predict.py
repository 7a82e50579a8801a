"""Prediction from a fit (``diffguide predict``, :func:`diffguide.inverse.predict.predict`): the
errors at a point no instrument stood at and their σ from the fit's full posterior.

The bundled data set is fitted once (the command line, as a user runs it); the σ is checked
against a finite-difference Jacobian (rails: the plain forward model with one coefficient moved;
structure: the table condensed again at a moved thickness, the preload set through the
specification) times the posterior covariance; the lead error against a spline that reproduces
a line; at a measured point the prediction against the fit's own fitted values."""

import csv
import dataclasses
import json
import shutil
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide._core.caches import Caches
from diffguide.cli import main
from diffguide.guideway.rails import AbstractRailProfile, SplineRail
from diffguide.inverse import posterior_sweep
from diffguide.inverse.error_map import check_grid, error_map
from diffguide.inverse.predict import FitPosterior, _predict_recondensed, predict
from diffguide.io.config import default_config, load_config, spec_from_config
from diffguide.io.fit_posterior import (
    FORMAT_1,
    content_fingerprint,
    machine_snapshot,
    read_fit_posterior,
    stamped_text,
)
from diffguide.machine.build import build_machine
from diffguide.machine.kinematics import joint_errors
from diffguide.studies.compensation import fitted_compensation

X = np.linspace(-0.3, 0.3, 5)  # one shape for every prediction here: one compilation
Q = {"Q": (0.3, 0.1)}  # no instrument stood there


def _fit(tmp_path_factory, *extra):
    out = tmp_path_factory.mktemp("predict") / "fit"
    assert main(["fit", "--measurements", "data/majda2012_measurements.csv", "--out", str(out),
                 "--no-plots", "-q", *extra]) == 0
    post, meta = read_fit_posterior(out)
    return out, post, meta, spec_from_config(default_config())


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    return _fit(tmp_path_factory)


@pytest.fixture(scope="module")
def prediction(fitted):
    _, post, meta, spec = fitted
    return predict(post, spec, Q, X, measured_points=meta["points_m"])


@pytest.fixture(scope="module")
def fitted_joint(tmp_path_factory):
    """The bundled data fitted with a rail joint stated at s = 137 mm."""
    return _fit(tmp_path_factory, "--rail-joints-mm", "137")


class _Stepped(AbstractRailProfile):
    """A spline plus steps of heights ``h`` (m) at ``joints`` (m), each rising over ``w`` (m)
    as the quintic ``6u⁵ − 15u⁴ + 10u³`` (written out here, not the package's ramp)."""

    spline: SplineRail
    joints: tuple = eqx.field(static=True)
    w: float = eqx.field(static=True)
    hv: jax.Array
    hh: jax.Array

    def __call__(self, s):
        ey, ez = self.spline(s)
        for j, s0 in enumerate(self.joints):
            u = jnp.clip((s - s0) / self.w + 0.5, 0.0, 1.0)
            H = 6 * u**5 - 15 * u**4 + 10 * u**3
            ey, ez = ey + self.hh[j] * H, ez + self.hv[j] * H
        return ey, ez


def _rails(post, c):
    c = np.asarray(c).reshape(2, 2, -1)
    b = post.basis
    n = b.n_coeffs
    splines = [SplineRail(b.start, b.spacing, c[r, 0, :n], c[r, 1, :n]) for r in range(2)]
    if not b.joints:
        return tuple(splines)
    return tuple(_Stepped(splines[r], tuple(b.joints), b.joint_width, c[r, 0, n:],
                          c[r, 1, n:]) for r in range(2))


def _errors(machine, post, c):
    """Errors at Q (the last point) (n_pos, 6), SI, by the plain forward model."""
    je = joint_errors(machine, _rails(post, c), X)
    assert bool(np.all(np.asarray(je.converged)))
    return np.asarray(je.errors)[:, -1]


def test_sigma_is_the_finite_difference_jacobian_times_the_posterior(fitted, prediction):
    _check_sigma(fitted, prediction)


def test_with_a_rail_joint_the_steps_are_unknowns_of_the_prediction(fitted_joint):
    """The fit's posterior file holds the joint; the prediction's errors and σ include the
    steps (a spline plus a quintic step, written out in the test, by finite differences); the
    bundled rails have no joint at 137 mm: every fitted step is within 2σ of 0."""
    out, post, meta, spec = fitted_joint
    assert post.basis.joints == (0.137,) and post.coeffs.shape == (2, 2, post.basis.n_coeffs + 1)
    n = post.basis.n_coeffs
    steps = post.coeffs[:, :, n]
    sig = np.sqrt(np.diag(post.cov)[n::n + 1][:4]).reshape(2, 2)
    assert np.all(np.abs(steps) < 2 * sig), (steps * 1e6, sig * 1e6)
    report = json.loads((out / "report.json").read_text(encoding="utf-8"))
    listed = report["elastic"]["rail_joint_steps_um"]
    assert [(d["s_mm"], d["rail"], d["plane"]) for d in listed] == [
        (137.0, 1, "vertical"), (137.0, 1, "horizontal"), (137.0, 2, "vertical"),
        (137.0, 2, "horizontal")]
    np.testing.assert_allclose([d["value"] for d in listed], steps.ravel() * 1e6, atol=1e-9)
    html = (out / "report.html").read_text(encoding="utf-8")
    assert html.count("step at the rail joint s = 137 mm") == 4
    _check_sigma(fitted_joint, predict(post, spec, Q, X, measured_points=meta["points_m"]))


def _check_sigma(fitted, prediction):
    _, post, meta, spec = fitted
    pts = {**meta["points_m"], **Q}
    t, p = (post.structure[k]["value"] for k in ("thickness", "preload"))

    def machine(dt=0.0, dp=0.0):
        s_t, s_p = (post.structure[k]["prior_sigma_log"] for k in ("thickness", "preload"))
        return build_machine(spec, points=pts, thickness=t * np.exp(dt * s_t),
                             preload_fraction=p * np.exp(dp * s_p))

    m0 = machine()
    c0 = post.coeffs.reshape(-1)
    np.testing.assert_allclose(prediction.errors[:, 0], _errors(m0, post, c0), rtol=0,
                               atol=1e-12)
    n_c, h = c0.size, 1e-8  # 0.01 µm per coefficient: the model is all but linear in them
    J = np.zeros((len(X), 6, post.cov.shape[0]))
    for k in range(n_c):
        dc = np.zeros(n_c)
        dc[k] = h
        J[..., k] = (_errors(m0, post, c0 + dc) - _errors(m0, post, c0 - dc)) / (2 * h)
    dq = 0.05  # prior σ of the log
    J[..., n_c] = (_errors(machine(dt=dq), post, c0) - _errors(machine(dt=-dq), post, c0)) / (
        2 * dq)
    J[..., n_c + 1] = (_errors(machine(dp=dq), post, c0) - _errors(machine(dp=-dq), post, c0)) / (
        2 * dq)
    sigma = np.sqrt(np.einsum("pkv,vw,pkw->pk", J, post.cov, J))
    # the thickness column is a secant over ±σ in the prediction, a tangent here
    np.testing.assert_allclose(prediction.sigma[:, 0], sigma, rtol=0.03, atol=1e-9)
    assert not prediction.lead and not prediction.extrapolated.any()


def test_lead_error_is_in_exx_with_its_sigma(fitted, prediction):
    """A lead spline whose coefficients lie on a line reproduces the line (a cubic B-spline
    property): EXX gains ``a·(x − x_ref)``; a covariance along the line, ``σ_a² g gᵀ``, adds
    ``σ_a²(x − x_ref)²`` to EXX's variance, a constant one (``σ₀²11ᵀ``, σ₀ = 1 mm: the
    lead's level, which the channel zero takes) nothing."""
    _, post, meta, spec = fitted
    ls, lh, ln = -0.4, 0.1, 11
    g = ls + (np.arange(ln) - 1.0) * lh  # the knot centres: a line's coefficients
    a, sa = 20e-6, 3e-6  # 20 µm/m, σ 3 µm/m
    nv = post.cov.shape[0]
    cases = ((sa**2 * np.outer(g, g), (sa * X) ** 2), (1e-6 * np.ones((ln, ln)), 0 * X))
    for extra, added in cases:
        cov = np.zeros((nv + ln, nv + ln))
        cov[:nv, :nv] = post.cov
        cov[nv:, nv:] = extra
        lead = dataclasses.replace(post, lead=a * g, lead_basis=(ls, lh, ln), cov=cov)
        pr = predict(lead, spec, Q, X, measured_points=meta["points_m"])
        assert pr.lead
        np.testing.assert_allclose(pr.errors[:, 0, 0] - prediction.errors[:, 0, 0], a * X,
                                   rtol=0, atol=1e-12)
        np.testing.assert_allclose(pr.sigma[:, 0, 0] ** 2 - prediction.sigma[:, 0, 0] ** 2,
                                   added, rtol=1e-6, atol=1e-20)
        np.testing.assert_allclose(pr.sigma[:, 0, 1:], prediction.sigma[:, 0, 1:], rtol=1e-12)
    # the compensation export is the same prediction: EXX with the lead, and its σ
    files, _ = fitted_compensation(spec, lead, X * 1e3, "Q", "csv",
                                   points={**meta["points_m"], **Q})
    rows = list(csv.DictReader(ln for ln in files[""].splitlines() if not ln.startswith("#")))
    for col, want in (("EXX_um", pr.errors), ("EXX_sigma_um", pr.sigma)):
        np.testing.assert_allclose([float(r[col]) for r in rows], want[:, 0, 0] * 1e6,
                                   atol=1e-3)
    # and at a tool point 200 mm above the table top: EXX + z·EBX
    files, _ = fitted_compensation(spec, lead, X * 1e3, "Q", "csv",
                                   points={**meta["points_m"], **Q}, z=0.2)
    assert "at 200 mm above the table top" in files[""]
    rows = list(csv.DictReader(ln for ln in files[""].splitlines() if not ln.startswith("#")))
    np.testing.assert_allclose([float(r["EXX_um"]) for r in rows],
                               (pr.errors[:, 0, 0] + 0.2 * pr.errors[:, 0, 4]) * 1e6, atol=1e-3)


def _fitted_curve(out, point, quantity):
    """The fit's own fitted values of one channel (fit.csv), per position: (mm, value)."""
    with open(out / "fit.csv", newline="", encoding="utf-8") as fh:
        rows = [r for r in csv.DictReader(fh) if r["point"] == point
                and r["quantity"] == quantity and r["status"] == "used"]
    x = np.array([float(r["position_mm"]) for r in rows])
    v = np.array([float(r["fitted"]) for r in rows])
    xs = np.unique(x)
    return xs, np.array([v[x == s][0] for s in xs])


def test_at_a_measured_point_the_prediction_is_the_fits_model(fitted):
    """Up to the channel's zero (a constant the fit profiles out)."""
    out, post, meta, spec = fitted
    pts = {k: meta["points_m"][k] for k in ("P1", "P5")}
    xs, _ = _fitted_curve(out, "P5", "EBX")
    xs = xs[np.argsort(np.abs(xs))][:5]  # five measured positions: the same compiled shape
    pr = predict(post, spec, pts, np.sort(xs) * 1e-3, measured_points=meta["points_m"])
    for j, (point, quantity, k) in enumerate((("P1", "EAX", 3), ("P5", "EBX", 4))):
        x_mm, v = _fitted_curve(out, point, quantity)
        ref = np.array([v[np.isclose(x_mm, s)][0] for s in np.sort(xs)])
        d = pr.errors[:, j, k] * 1e6 - ref
        assert np.ptp(d) < 2e-4 * np.ptp(ref) + 1e-5, (point, quantity, d)


def test_outside_the_measured_range_refused_or_flagged(fitted):
    _, post, meta, spec = fitted
    narrow = dataclasses.replace(post, position_range=(-0.25, 0.25))
    with pytest.raises(ValueError, match=r"outside the measured range \[-250, 250\] mm"):
        predict(narrow, spec, Q, X, measured_points=meta["points_m"])
    pr = predict(narrow, spec, Q, X, measured_points=meta["points_m"], extrapolate=True)
    np.testing.assert_array_equal(pr.extrapolated, np.abs(X) > 0.25)
    assert np.all(np.isfinite(pr.sigma))
    with pytest.raises(ValueError, match="beyond the machine's stroke"):
        predict(post, spec, Q, [0.0, 0.4], measured_points=meta["points_m"], extrapolate=True)
    with pytest.raises(ValueError, match="off the table"):
        predict(post, spec, {"R": (0.6, 0.0)}, X)


def _rotation(a, b, c):
    """The exact rotation by roll a (about X), pitch b (about Y), yaw c (about Z)."""
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    return rz @ ry @ rx


def test_at_a_tool_point_above_the_table(fitted, prediction):
    """At height z the table top's point moves with the rigid body above it: its errors are
    the top's plus the turned lever ``R(EAX, EBX, ECX)(0, 0, z) − (0, 0, z)`` (exact rotation,
    to its second-order remainder); the σ of EXX(z) = EXX + z·EBX is a quadratic in z whose
    z² coefficient is σ(EBX)², read from three heights."""
    _, post, meta, spec = fitted
    z = 0.3
    up = predict(post, spec, Q, X, measured_points=meta["points_m"], z=z)
    e0 = prediction.errors[:, 0]
    second_order = np.max(np.abs(e0[:, 3:])) ** 2 * z  # the remainder of the small angles
    for i in range(len(X)):
        a, b, c = e0[i, 3:]
        lever = _rotation(a, b, c) @ [0.0, 0.0, z] - [0.0, 0.0, z]
        np.testing.assert_allclose(up.errors[i, 0, :2], e0[i, :2] + lever[:2], rtol=0,
                                   atol=second_order)
    assert np.max(np.abs(up.errors[:, 0, :2] - e0[:, :2])) > 100 * second_order
    np.testing.assert_allclose(up.errors[:, 0, 2:], e0[:, 2:], rtol=0, atol=0)
    np.testing.assert_allclose(up.sigma[:, 0, 2:], prediction.sigma[:, 0, 2:], rtol=1e-12)
    v = [prediction.sigma[:, 0, 0] ** 2, up.sigma[:, 0, 0] ** 2,
         predict(post, spec, Q, X, measured_points=meta["points_m"], z=2 * z).sigma[:, 0, 0] ** 2]
    curvature = (v[2] - 2 * v[1] + v[0]) / (2 * z**2)
    np.testing.assert_allclose(curvature, prediction.sigma[:, 0, 4] ** 2, rtol=1e-6)
    assert up.z == z
    with pytest.raises(ValueError, match="height above the table top"):
        predict(post, spec, Q, X, measured_points=meta["points_m"], z=300.0)


def _read_csv(path):
    with open(path, encoding="utf-8") as fh:
        lines = [ln for ln in fh if not ln.startswith("#")]
    return list(csv.DictReader(lines))


def test_command_line_end_to_end(fitted, prediction, tmp_path, capsys):
    out, post, *_ = fitted
    pts = tmp_path / "points.csv"
    pts.write_text("point,x_mm,y_mm\nQ,300,100\n", encoding="utf-8")
    csv_out = tmp_path / "pred.csv"
    assert main(["predict", "--fit", str(out), "--points", str(pts), "--positions-mm",
                 "-300:300:5", "--out", str(csv_out)]) == 0
    header = csv_out.read_text(encoding="utf-8").splitlines()[:6]
    assert any("units:" in h and "um" in h and "urad" in h for h in header)
    assert any("ISO 230-1" in h for h in header) and any("EXX" in h for h in header)
    rows = _read_csv(csv_out)
    assert len(rows) == 5 and {r["point"] for r in rows} == {"Q"}
    got = np.array([[float(r[c]) for c in ("EZX_um", "EBX_urad", "EYX_sigma_um")] for r in rows])
    want = np.stack([prediction.errors[:, 0, 2] * 1e6, prediction.errors[:, 0, 4] * 1e6,
                     prediction.sigma[:, 0, 1] * 1e6], axis=1)
    np.testing.assert_allclose(got, want, atol=1e-5)
    assert "wrote" in capsys.readouterr().out
    # a fit measured over a narrower range: refused, then flagged with --extrapolate
    narrow = tmp_path / "narrow"
    shutil.copytree(out, narrow)
    d = json.loads((narrow / "posterior.json").read_text(encoding="utf-8"))
    d["position_range_m"] = [-0.25, 0.25]
    (narrow / "posterior.json").write_text(stamped_text(d), encoding="utf-8")
    argv = ["predict", "--fit", str(narrow), "--point", "Q:300,100", "--positions-mm",
            "-300:300:5", "--out", str(tmp_path / "x.csv")]
    assert main(argv) == 2
    assert "outside the measured range [-250, 250] mm" in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()
    assert main(argv + ["--extrapolate", "-q"]) == 0
    flags = [r["extrapolated"] for r in _read_csv(tmp_path / "x.csv")]
    assert flags == ["1", "0", "0", "0", "1"]
    # not a fit folder with a posterior
    assert main(["predict", "--fit", str(tmp_path), "--point", "Q:0,0", "--out",
                 str(tmp_path / "y.csv")]) == 2
    assert "posterior.json: not found" in capsys.readouterr().err
    # at the tool's height: the CSV says so and holds the Abbe terms
    z_out = tmp_path / "z.csv"
    assert main(["predict", "--fit", str(out), "--points", str(pts), "--positions-mm",
                 "-300:300:5", "--z-mm", "150", "--out", str(z_out), "-q"]) == 0
    assert "at 150 mm above the table top" in z_out.read_text(encoding="utf-8")
    got = np.array([float(r["EXX_um"]) for r in _read_csv(z_out)])
    want = (prediction.errors[:, 0, 0] + 0.15 * prediction.errors[:, 0, 4]) * 1e6
    np.testing.assert_allclose(got, want, atol=1e-5)
    assert main(["predict", "--fit", str(out), "--point", "Q:0,0", "--z-mm", "5000", "--out",
                 str(tmp_path / "w.csv")]) == 2
    assert "--z-mm must be in [-500, 2000] mm" in capsys.readouterr().err


def test_the_stored_sweep_programs_predict_the_same(fitted, prediction, tmp_path, monkeypatch):
    """With an export folder (the command line's cache), the sweep's programs are stored
    (traced once) and a later process reads them back instead of tracing: both give the
    prediction of the traced functions themselves."""
    _, post, meta, spec = fitted
    progs = (posterior_sweep._interface_jit, posterior_sweep._interface_and_jacobian)

    def fresh():  # as in a new process: no sweep, no program in memory
        monkeypatch.setattr(posterior_sweep, "_SWEEPS", {})
        for prog in progs:
            monkeypatch.setattr(prog, "_programs", {})
        return predict(post, spec, Q, X, measured_points=meta["points_m"])

    with Caches(exports=tmp_path / "exports") as caches:
        stored = fresh()
        assert caches.export_stats["exports"] == 2 and caches.export_stats["hits"] == 0
        loaded = fresh()
        assert caches.export_stats["exports"] == 2 and caches.export_stats["hits"] == 2
    for a, b in ((stored, loaded), (loaded, prediction)):
        np.testing.assert_allclose(a.errors, b.errors, rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(a.sigma, b.sigma, rtol=1e-12, atol=1e-18)


def test_from_fit_refuses_a_fit_without_posterior():
    class Old:
        posterior_cov = np.zeros((0, 0))
        position_range = ()

    with pytest.raises(ValueError, match="no full posterior"):
        FitPosterior.from_fit(Old())


def _rel(a, b):
    """The largest difference of each quantity relative to its largest magnitude."""
    scale = np.abs(b).max(axis=(0, 1))
    return float(np.max(np.abs(a - b).max(axis=(0, 1)) / scale))


def test_equal_to_the_recondensed_prediction(fitted):
    """The prediction from the sweep of the fitted model equals the former route (the table
    condensed again with grid lines through the requested points) to round-off, σ included:
    on the former route's own mesh, and at nodes of the fit's mesh that no instrument stood at
    (interpolated there: the nodal values), at a tool point above the top."""
    _, post, meta, spec = fitted
    mp = meta["points_m"]
    off = {"A": (0.333, -0.077), "B": (-0.21, 0.123)}  # no grid line through them
    nodes = {**Q, "C": (-0.25, -0.17)}  # grid lines of the fit's mesh
    for pts, mesh in ((off, {**mp, **off}), (nodes, None)):
        new = predict(post, spec, pts, X, measured_points=mp, mesh_points=mesh, z=0.1)
        old = _predict_recondensed(post, spec, pts, X, measured_points=mp, z=0.1)
        assert _rel(new.errors, old.errors) < 1e-9 and _rel(new.sigma, old.sigma) < 1e-9
    # between the fit's nodes: interpolated, within the mesh's discretisation of the former
    # route's (which moves grid lines: tests/test_recovery.py has the convergence)
    new = predict(post, spec, off, X, measured_points=mp)
    old = _predict_recondensed(post, spec, off, X, measured_points=mp)
    assert _rel(new.errors, old.errors) < 0.05 and _rel(new.sigma, old.sigma) < 0.05


def test_error_map_over_the_table_top(fitted, tmp_path, capsys):
    """The grid's errors and σ are predict's at its points; the grid is checked; the command
    line writes one row per point and position, and the figure."""
    out, post, meta, spec = fitted
    emap = error_map(post, spec, (3, 2), X, measured_points=meta["points_m"])
    assert emap.grid_shape == (3, 2) and emap.errors.shape == (len(X), 6, 6)
    np.testing.assert_allclose(emap.points_xy[[0, 1, 5]],
                               [[-0.5, -0.25], [-0.5, 0.25], [0.5, 0.25]])
    assert emap.point_names[1] == "G1_2"
    pr = predict(post, spec, {"c": (0.0, 0.25)}, X, measured_points=meta["points_m"])
    np.testing.assert_allclose(emap.errors[:, 3], pr.errors[:, 0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(emap.sigma[:, 3], pr.sigma[:, 0], rtol=1e-12, atol=1e-18)
    for shape, msg in (((1, 5), r"NX must be an integer in 2 \.\. 201"),
                       ((5, 202), r"NY must be an integer in 2 \.\. 201.*got 202"),
                       ((5.0, 3), "NX must be an integer"),
                       ((201, 201), "at most 2868471")):
        with pytest.raises(ValueError, match=msg):
            check_grid(shape, 72)
    csv_out, png = tmp_path / "map.csv", tmp_path / "map.png"
    assert main(["predict", "--fit", str(out), "--grid", "3x2", "--positions-mm",
                 "-300:300:5", "--grid-plot", str(png), "--out", str(csv_out)]) == 0
    rows = _read_csv(csv_out)
    assert len(rows) == 5 * 6 and rows[1]["point"] == "G1_2" and png.stat().st_size > 0
    np.testing.assert_allclose([float(r["EZX_um"]) for r in rows[3::6]],
                               emap.errors[:, 3, 2] * 1e6, atol=1e-5)
    assert "grid 3 x 2 over the table top" in capsys.readouterr().out
    for argv, msg in ((["--grid", "300x11"], "--grid 300x11: grid NX must be an integer in "
                       "2 .. 201"),
                      (["--grid", "21by11"], "--grid must be NXxNY"),
                      (["--grid", "3x2", "--point", "Q:0,0"], "--grid or --point/--points"),
                      (["--point", "Q:0,0", "--grid-plot", "x.png"], "--grid-plot needs --grid")):
        assert main(["predict", "--fit", str(out), *argv, "--out",
                     str(tmp_path / "no.csv")]) == 2
        assert msg in capsys.readouterr().err
    assert not (tmp_path / "no.csv").exists()


# ---- posterior.json read strictly: its checksum, every field's type, the machine ----

def _write(folder, d, *, stamp=True):
    folder.mkdir(exist_ok=True)
    text = stamped_text(d) if stamp else json.dumps(d)
    (folder / "posterior.json").write_text(text, encoding="utf-8")
    return folder


def _set(d, path, value):
    *head, last = path
    for k in head:
        d = d[k]
    if value is _DELETE:
        del d[last]
    else:
        d[last] = value


_DELETE = object()


@pytest.mark.parametrize("path, value, message", [
    (("rigid",), "false", "field 'rigid' must be a JSON bool (true or false), got a string"),
    (("rigid",), 0, "field 'rigid' must be a JSON bool"),
    (("x_ref_m",), _DELETE, "required field 'x_ref_m' is missing"),
    (("knots",), _DELETE, "required field 'knots' is missing"),
    (("cov", 3, 3), -1e-12, "the variance cov[3][3] = -1e-12 is negative"),
    (("cov", 0, 1), 1.0, "field 'cov' must be symmetric"),
    (("knots", "n"), "26", "field 'knots.n' must be int"),
    (("knots", "spacing_m"), -0.05, "field 'knots.spacing_m' must be > 0"),
    (("coeffs_m", 0, 0, 0), "1e-6", "field 'coeffs_m' must hold finite numbers only"),
    (("structure", "thickness", "prior_sigma_log"), -0.3,
     "field 'structure.thickness.prior_sigma_log' must be > 0"),
    (("points_m", "P1"), [0.45], "field 'points_m.P1' must be [x, y]"),
    (("x0_mm",), "0", "field 'x0_mm' must be a finite number"),
    (("machine", "preset"), None, "must name exactly one of 'preset' and 'config'"),
    (("format",), "diffguide fit posterior 9", "field 'format'"),
])
def test_every_field_is_checked_and_named(fitted, tmp_path, path, value, message):
    out = fitted[0]
    d = json.loads((out / "posterior.json").read_text(encoding="utf-8"))
    _set(d, path, value)
    folder = _write(tmp_path / "bad", d)  # a valid checksum: the field itself is refused
    with pytest.raises(ValueError) as exc:
        read_fit_posterior(folder)
    assert str(exc.value).startswith(str(folder / "posterior.json"))
    assert message in str(exc.value)


def test_the_checksum_catches_an_edit_and_ignores_the_layout(fitted, tmp_path):
    out = fitted[0]
    d = json.loads((out / "posterior.json").read_text(encoding="utf-8"))
    assert d["format"] == "diffguide fit posterior 2" and len(d["checksum"]) == 64
    # the same content indented: still the fit's
    (tmp_path / "pretty").mkdir()
    (tmp_path / "pretty" / "posterior.json").write_text(json.dumps(d, indent=2))
    read_fit_posterior(tmp_path / "pretty")
    # a coefficient edited by hand (its type right): refused
    d["coeffs_m"][0][0][3] += 1e-6
    with pytest.raises(ValueError, match="does not match its checksum"):
        read_fit_posterior(_write(tmp_path / "edited", d, stamp=False))
    del d["checksum"]
    with pytest.raises(ValueError, match="field 'checksum' is missing"):
        read_fit_posterior(_write(tmp_path / "unsummed", d, stamp=False))


def test_a_format_1_file_is_read_with_a_warning(fitted, tmp_path):
    out, post, *_ = fitted
    d = json.loads((out / "posterior.json").read_text(encoding="utf-8"))
    del d["checksum"], d["machine"]["fingerprint"], d["machine"]["snapshot"]
    d["format"] = FORMAT_1
    old, meta = read_fit_posterior(_write(tmp_path / "old", d, stamp=False))
    np.testing.assert_array_equal(old.cov, post.cov)
    assert len(meta["warnings"]) == 1 and "without a checksum" in meta["warnings"][0]
    # strict types hold for the old format too
    d["rigid"] = "false"
    with pytest.raises(ValueError, match="JSON bool"):
        read_fit_posterior(_write(tmp_path / "old", d, stamp=False))


def test_the_fits_machine_fingerprint(fitted):
    _, _, meta, _ = fitted
    assert meta["warnings"] == []
    snap = machine_snapshot(default_config())
    assert meta["machine"]["fingerprint"] == content_fingerprint(snap)
    assert "fit" not in snap and "points" not in snap  # not the machine predict builds
    assert "export" not in snap  # controller settings: how a table is written


def test_export_settings_are_not_a_machine_change(tmp_path):
    # a fit made before the machine file gained (or changed) its [export] table is the same
    # machine: predict must not refuse it
    from diffguide.io.fit_posterior import machine_changes

    before = machine_snapshot(default_config())
    before.pop("export", None)  # a fit of 0.2 or earlier: no such section at all
    meta = {"machine": {"fingerprint": content_fingerprint(before), "snapshot": before}}
    toml = tmp_path / "machine.toml"
    toml.write_text('[export]\ncec_axis_names = {X = "X1", Y = "Y1", Z = "Z1"}\n',
                    encoding="utf-8")
    assert machine_changes(meta, default_config()) == []
    assert machine_changes(meta, load_config(toml)) == []


def test_predict_refuses_a_machine_changed_since_the_fit(fitted, tmp_path, capsys):
    # a fit made with a machine file (the preset's values); the file edited afterwards
    out = fitted[0]
    toml = tmp_path / "machine.toml"
    toml.write_text("[guideway]\nrail_y_mm = [-170.0, 170.0]\n", encoding="utf-8")
    snap = machine_snapshot(load_config(toml))
    assert snap == machine_snapshot(default_config())
    d = json.loads((out / "posterior.json").read_text(encoding="utf-8"))
    d["machine"] = {"preset": None, "config": str(toml), "nx": None, "ny": None,
                    "fingerprint": content_fingerprint(snap), "snapshot": snap}
    folder = _write(tmp_path / "fit", d)
    toml.write_text("[guideway]\nrail_y_mm = [-170.0, 175.0]\n", encoding="utf-8")
    csv_out = tmp_path / "p.csv"
    argv = ["predict", "--fit", str(folder), "--point", "Q:300,100", "--positions-mm",
            "-300:300:5", "--out", str(csv_out), "-q"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"the machine file {toml} changed since the fit" in err
    assert "guideway.rail_y_mm: [-170.0, 170.0] at the fit, [-170.0, 175.0] now" in err
    assert "--accept-machine-change" in err and not csv_out.exists()
    # accepted: a warning on stderr and in the file's header
    assert main(argv + ["--accept-machine-change"]) == 0
    assert "warning: the machine file" in capsys.readouterr().err
    head = csv_out.read_text(encoding="utf-8").splitlines()[0]
    assert "WARNING" in head and "guideway.rail_y_mm" in head


def test_an_imported_tables_files_are_in_the_fingerprint(tmp_path):
    # an imported table is fingerprinted by its files' bytes, not by their paths: the same
    # files elsewhere are the same machine; a changed matrix file is a changed machine
    from diffguide.io.fit_posterior import machine_changes

    src = Path(__file__).resolve().parents[1] / "data" / "examples" / "superelement"
    a = load_config(src / "machine.toml")
    shutil.copytree(src, tmp_path / "se")
    b_path = tmp_path / "se" / "machine.toml"
    snap = machine_snapshot(a)
    files = snap["table_source"]["files"]
    assert set(files) == {"plate.toml", "plate.dat", "plate_nodes.inp", "plate_held_loads.inp"}
    assert machine_snapshot(load_config(b_path)) == snap
    meta = {"machine": {"fingerprint": content_fingerprint(snap), "snapshot": snap}}
    with open(tmp_path / "se" / "plate.dat", "a", encoding="utf-8") as fh:
        fh.write("\n")
    changes = machine_changes(meta, load_config(b_path))
    assert len(changes) == 1 and changes[0].startswith("table_source.files.plate.dat: ")
