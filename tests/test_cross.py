"""The stacked cross table (``machine.cross``, ``cross_equilibrium``, ``volumetric``).

Checked against results obtained another way: the rigid limit against the two axes solved
separately as one-axis machines (the saddle loaded by the table's weight, computed here from
the plate's size and density) and composed by a homogeneous-transformation chain written here
(ISO 230-1 small-angle form); derivatives against central differences; zero loads and
straight rails against zero; the Y dependence of the X axis's errors against the saddle's tilt.
"""

import dataclasses

import equinox as eqx
import jax
import numpy as np
import pytest

from diffguide.guideway.rails import PaperPolynomialRail
from diffguide.machine.cross import build_cross
from diffguide.machine.cross_spec import CrossSpec
from diffguide.machine.equilibrium import equilibrium, rigid_body_map
from diffguide.machine.paper_cross import majda2012_cross_spec
from diffguide.machine.volumetric import cross_errors, cross_errors_traced

X = np.array([-0.3, 0.1, 0.35])
Y = np.array([-0.2, 0.15])


def _rails(a, b):
    """Rail 1 bent vertically by Δ = ``a``, rail 2 horizontally by ``b`` (m; Majda's eq. 4);
    array amplitudes, so that all the tests' rails share one compiled program."""
    return (PaperPolynomialRail(np.asarray(a), "vertical"),
            PaperPolynomialRail(np.asarray(b), "horizontal"))


RAILS_X = _rails(0.05e-3, 0.03e-3)
RAILS_Y = _rails(0.04e-3, 0.02e-3)
STRAIGHT = _rails(0.0, 0.0)


def _coarse(spec: CrossSpec) -> CrossSpec:
    """``spec`` on small meshes (the tests' cost; the footprint lines still refine them)."""
    x = dataclasses.replace(spec.x, table=dataclasses.replace(spec.x.table, nx=4, ny=2))
    y = dataclasses.replace(spec.y, table=dataclasses.replace(spec.y.table, nx=2, ny=2))
    return dataclasses.replace(spec, x=x, y=y)


@pytest.fixture(scope="module")
def spec():
    return _coarse(majda2012_cross_spec())


@pytest.fixture(scope="module")
def rigid(spec):
    """The rigid table on the rigid saddle, its Y blocks' preload an array (the gradient test
    scales it: the same program as the other tests)."""
    cross = build_cross(spec, rigid_table=True)
    return eqx.tree_at(lambda c: c.y_axis.carriage.preload_force, cross,
                       np.asarray(cross.y_axis.carriage.preload_force, dtype=float))


# ---- an independent chain: ISO 230-1 small-angle HTMs, written out ----


def _htm(t, e):
    """Nominal translation ``t`` followed by the small errors ``e = (δx, δy, δz, a, b, c)``."""
    dx, dy, dz, a, b, c = e
    return np.array([[1.0, -c, b, t[0] + dx], [c, 1.0, -a, t[1] + dy],
                     [-b, a, 1.0, t[2] + dz], [0.0, 0.0, 0.0, 1.0]])


def _rigid_motion(machine, u):
    """The rigid motion at the body's origin from its interface DOF ``u = Φ q`` (first patch)."""
    r0 = np.asarray(machine.table.ref_points[0])
    theta = u[3:6]
    return np.concatenate([u[:3] - np.cross(theta, r0), theta])


def _axes_separately(spec, cross, Xs, Ys):
    """The two axes as one-axis machines: the table's rigid motion on the saddle at each X, the
    saddle's (machine frame) at each (X, Y) under the table's weight."""
    xs = equilibrium(cross.x_axis, RAILS_X, Xs)
    q_x = np.array([_rigid_motion(cross.x_axis, u) for u in np.asarray(xs.interface)])
    t = spec.x.table
    weight = t.material.rho * spec.x.gravity * t.length * t.width * t.thickness
    saddle = cross.y_axis
    Phi = np.asarray(rigid_body_map(saddle.table.ref_points))
    q_y = []
    for x in Xs:
        # weight -W e_z at the table centre, (x, 0, dz) from the saddle centre: moment (0, xW, 0)
        # in the machine frame; in the Y axis frame (x' = Y, y' = -X) force (0, 0, -W), moment
        # (xW, 0, 0)
        w_local = np.array([0.0, 0.0, -weight, x * weight, 0.0, 0.0])
        f = np.asarray(saddle.table.f) + Phi @ np.linalg.solve(Phi.T @ Phi, w_local)
        ys = equilibrium(eqx.tree_at(lambda m: m.table.f, saddle, f), RAILS_Y, Ys)
        local = np.array([_rigid_motion(saddle, u) for u in np.asarray(ys.interface)])
        q_y.append(local[:, [1, 0, 2, 4, 3, 5]] * np.array([-1, 1, 1, -1, 1, 1]))
    return q_x, np.array(q_y)


def test_rigid_limit_is_the_htm_chain_of_the_two_axes(spec, rigid):
    """Rigid table and saddle: the table's frame at every control point equals
    ``Tr(saddle) E(ε_Y(Y; X)) · Tr(table) E(ε_X(X)) · Tr(P)`` of the two axes solved apart, and
    so does the volumetric error of a point 0.2 m above it, to 1e-9 of their size."""
    e = cross_errors(rigid, RAILS_X, RAILS_Y, X, Y)
    assert bool(np.all(e.converged))
    Xs, Ys = np.append(X, 0.0), np.append(Y, 0.0)
    q_x, q_y = _axes_separately(spec, rigid, Xs, Ys)
    t = spec.x.table
    dz = t.thickness / 2 + spec.x_guideway_height + spec.y.table.thickness / 2
    pts = np.asarray(e.points)

    def chain(i, j, p):
        T = _htm((0.0, Ys[j], -dz), q_y[i, j]) @ _htm((Xs[i], 0.0, dz), q_x[i])
        return T @ _htm(p, np.zeros(6))

    z = np.array([0.0, 0.0, 0.2, 1.0])
    vol = np.asarray(e.volumetric(0.2))
    scale = np.max(np.abs(vol))
    assert scale > 1e-6  # micrometres: the test is not vacuous
    for k, p in enumerate(pts):
        ref = (chain(-1, -1, p) - _htm(p, np.zeros(6))) @ z  # the reference is (0, 0)
        for i in range(len(X)):
            for j in range(len(Y)):
                T = chain(i, j, p)
                T0 = _htm((Xs[i] + p[0], Ys[j] + p[1], p[2]), np.zeros(6))
                np.testing.assert_allclose(np.asarray(e.poses[i, j, k]) - T0, T - T0,
                                           rtol=0, atol=1e-9 * scale)
                v = (T - T0) @ z - ref
                np.testing.assert_allclose(vol[i, j, k], v[:3], rtol=0, atol=1e-9 * scale)


def test_no_loads_and_straight_rails_give_no_errors(rigid):
    """Weightless, on straight rails: the table does not move relative to the bed."""
    zero = eqx.tree_at(
        lambda c: (c.x_axis.table.f, c.y_axis.table.f),
        rigid,
        replace_fn=lambda v: 0.0 * v,
    )
    e = cross_errors(zero, STRAIGHT, STRAIGHT, X, Y)
    assert bool(np.all(e.converged))
    np.testing.assert_allclose(np.asarray(e.errors), 0.0, rtol=0, atol=1e-18)
    np.testing.assert_allclose(np.asarray(e.volumetric(0.3)), 0.0, rtol=0, atol=1e-18)


def test_gradient_through_the_stacked_equilibrium(rigid):
    """``jvp`` of the errors w.r.t. a Y-rail error and the Y blocks' preload force equals
    central differences."""

    def inputs(p):
        delta, scale = p
        cross = eqx.tree_at(lambda c: c.y_axis.carriage.preload_force, rigid,
                            rigid.y_axis.carriage.preload_force * scale)
        return cross, (PaperPolynomialRail(delta, "vertical"), RAILS_Y[1])

    def errors(p):
        cross, rails_y = inputs(p)
        return cross_errors_traced(cross, RAILS_X, rails_y, X, Y).errors

    def f(p):  # the other tests' compiled program
        return cross_errors(*inputs(p)[:1], RAILS_X, inputs(p)[1], X, Y).errors

    p0 = np.array([0.04e-3, 1.0])
    tangents = jax.jit(lambda p: jax.vmap(lambda d: jax.jvp(errors, (p,), (d,))[1])(np.eye(2)))
    tangents = tangents(p0)
    for k, h in enumerate((1e-8, 1e-4)):  # the steps' truncation error: ~1e-7 relative
        direction = np.eye(2)[k]
        tangent = tangents[k]
        fd = (f(p0 + h * direction) - f(p0 - h * direction)) / (2 * h)
        scale = float(np.max(np.abs(fd)))
        assert scale > 0
        np.testing.assert_allclose(np.asarray(tangent), np.asarray(fd), rtol=0,
                                   atol=1e-5 * scale)


def test_x_axis_errors_depend_on_y_through_the_y_rails(rigid):
    """A cross table's consequence: the X axis's errors measured along X on the table (zeroed at
    X_ref on each line) depend on the line's Y when a Y rail is bent, and not when the Y rails
    are straight; the change in EZ at the table centre is the saddle's tilt about Y times the
    travel, ``−Δθ_y · X``, within the saddle's load-dependent compliance."""
    Xs = np.array([-0.3, 0.0, 0.3])  # includes X_ref = 0
    c = rigid.x_axis.point_names.index("P5")

    def along_x(rails_y):
        e = cross_errors(rigid, RAILS_X, rails_y, Xs, Y)
        line = np.asarray(e.errors[:, :, c])
        return line - line[1], np.asarray(e.errors[1, :, c])  # along X; the saddle at X_ref

    straight, _ = along_x(STRAIGHT)
    np.testing.assert_allclose(straight[:, 0], straight[:, 1], rtol=0, atol=1e-12 * np.max(
        np.abs(straight)))
    bent, at_ref = along_x(RAILS_Y)
    dez = bent[:, 1, 2] - bent[:, 0, 2]
    assert np.max(np.abs(dez)) > 0.1e-6  # a tenth of a micrometre over the stroke
    tilt = at_ref[1, 4] - at_ref[0, 4]  # EB of the centre = the saddle's tilt (rigid table)
    np.testing.assert_allclose(dez, -tilt * Xs, rtol=0, atol=0.1 * np.max(np.abs(dez)))


@pytest.fixture(scope="module")
def cli_cache(tmp_path_factory):
    """One cache folder for the command-line tests (the second reuses the first's program)."""
    return str(tmp_path_factory.mktemp("cross-cache"))


def _rows(path):
    import csv

    return list(csv.DictReader(open(path)))


@pytest.fixture(scope="module")
def preset_rows(tmp_path_factory, cli_cache):
    """``simulate --preset majda2012-cross --grid-xy 3x3``'s CSV rows, read by the csv module."""
    out = tmp_path_factory.mktemp("cross-out") / "cross.csv"
    assert main_simulate(["--grid-xy", "3x3", "--cache-dir", cli_cache, "--out", str(out),
                          "-q"]) == 0
    return _rows(out)


def test_simulate_writes_the_cross_grid(preset_rows):
    """``diffguide simulate --preset majda2012-cross``: one row per (X, Y, point) over both
    strokes, read back by the csv module; zero at the reference position (X, Y) = (0, 0), not
    elsewhere. (With a cache folder: the command's exported program, compiled fast.)"""
    rows = preset_rows
    assert len(rows) == 3 * 3 * 5 and all(r["converged"] == "1" for r in rows)
    assert {(float(r["X_mm"]), float(r["Y_mm"])) for r in rows} == {
        (x, y) for x in (-350.0, 0.0, 350.0) for y in (-230.0, 0.0, 230.0)}
    names = [f"{n}_{'um' if k < 3 else 'urad'}" for k, n in enumerate("EX EY EZ EA EB EC".split())]
    values = np.array([[float(r[n]) for n in names] for r in rows])
    at_ref = np.array([float(r["X_mm"]) == 0 and float(r["Y_mm"]) == 0 for r in rows])
    assert np.all(values[at_ref] == 0.0)
    assert np.all(np.max(np.abs(values[~at_ref]), axis=1) > 0.1)  # µm, µrad


def test_simulate_reads_a_cross_machine_file(tmp_path, cli_cache, preset_rows):
    """``simulate --config`` a file with a ``[saddle]``: the cross table of that file (a
    heavier saddle, a taller X guideway: other errors than the preset's, the same rows)."""
    from diffguide.cli import main

    machine = tmp_path / "cross.toml"
    machine.write_text("[saddle]\nthickness_mm = 120\n[cross]\nx_guideway_height_mm = 50\n")
    out = tmp_path / "file.csv"
    assert main(["simulate", "--config", str(machine), "--grid-xy", "3x3", "--cache-dir",
                 cli_cache, "--out", str(out), "-q"]) == 0
    preset, custom = preset_rows, _rows(out)
    assert [r["point"] for r in preset] == [r["point"] for r in custom]
    diff = [abs(float(a["EX_um"]) - float(b["EX_um"])) for a, b in zip(preset, custom)]
    assert max(diff) > 1e-3  # µm: the taller stack's Abbe offset


def test_simulate_cross_refuses_one_axis_options(tmp_path, capsys):
    out = tmp_path / "cross.csv"
    assert main_simulate(["--rigid-table", "--out", str(out)]) == 2
    assert "--rigid-table is not available with --preset majda2012-cross" in (
        capsys.readouterr().err)
    assert not out.exists()


def main_simulate(extra):
    from diffguide.cli import main

    return main(["simulate", "--preset", "majda2012-cross", *extra])

@pytest.mark.parametrize("call, words", [
    (lambda c: cross_errors(c, RAILS_X, RAILS_Y, np.array([350.0]), Y), "X"),
    (lambda c: cross_errors(c, RAILS_X[0], RAILS_Y, X, Y), "rails must be a pair"),
    (lambda c: cross_errors(c, RAILS_X, RAILS_Y, X, np.zeros((2, 2))), "1-D"),
])
def test_bad_arguments_are_refused(rigid, call, words):
    with pytest.raises((ValueError, TypeError)) as info:
        call(rigid)
    assert words in str(info.value)


def test_y_axis_errors_depend_on_x_through_the_tables_weight(spec, rigid):
    """The other consequence: on straight rails the saddle tilts as the table's weight moves
    over it. The tilt between X = −0.3 and +0.3 m equals the linear estimate ``K⁻¹ ΔM`` with
    ``K = Σ_c J_cᵀ T_c J_c`` the four Y carriages' tangents at preload carried to the saddle
    centre (assembled here) and ``ΔM = W ΔX`` about the machine's Y axis, within 5 % (1 %
    found; the roller contacts are nearly linear: F ∝ δ^(10/9))."""
    from diffguide._core.rigid import rigid_transfer

    Xs = np.array([-0.3, 0.0, 0.3])
    e = cross_errors(rigid, STRAIGHT, STRAIGHT, Xs, Y)
    eb = np.asarray(e.errors[:, 0, rigid.x_axis.point_names.index("P5"), 4])
    y_axis = rigid.y_axis
    carriage = y_axis.carriage.resolved()
    a0 = carriage.approaches(np.zeros(6), np.zeros((carriage.xi.shape[0], 2)))
    T = -np.asarray(carriage.tangent(a0))  # the contact stiffness (tangent: d wrench / d pose)
    K = np.zeros((6, 6))
    for r in np.asarray(y_axis.table.ref_points)[:-1]:  # the carriages (the nut: axial only)
        J = np.asarray(rigid_transfer(r))
        K += J.T @ T @ J
    K[0, 0] += float(y_axis.screw_stiffness(0.0))  # the screw holds x' (no load along it)
    t = spec.x.table
    weight = t.material.rho * spec.x.gravity * t.length * t.width * t.thickness
    dq = np.linalg.solve(K, np.array([0.0, 0.0, 0.0, weight * 0.6, 0.0, 0.0]))
    assert abs(eb[2] - eb[0]) > 1e-7  # a tenth of a µrad
    np.testing.assert_allclose(eb[2] - eb[0], dq[3], rtol=0.05)  # θ about x' = machine Y


def test_error_field_at_the_control_points_is_their_errors(rigid):
    """The errors over the whole table top (every mesh node, from the nodes' modes) at the
    control points' nodes equal the control points' errors (from the points' own rows)."""
    from diffguide.machine.volumetric import cross_error_field

    e = cross_errors(rigid, RAILS_X, RAILS_Y, X, Y)
    xy, field = cross_error_field(rigid, e, 2, -1)
    xy, field = np.asarray(xy), np.asarray(field)
    for k, p in enumerate(np.asarray(e.points)[:, :2]):
        node = int(np.argmin(np.sum((xy - p) ** 2, axis=1)))
        assert np.allclose(xy[node], p, atol=1e-12)
        np.testing.assert_allclose(field[node], np.asarray(e.errors[2, -1, k]), rtol=0,
                                   atol=1e-12 * float(np.max(np.abs(e.errors))))
    with pytest.raises(IndexError, match="i must be in -3 .. 2"):
        cross_error_field(rigid, e, 3, 0)
