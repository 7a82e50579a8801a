"""Geometry you can differentiate: rail spacing, nut position and rib sizes as traced overrides
(with the carriage spacing, the layout variable that was traceable before).

References: machines REBUILT from specifications with the perturbed positions/sizes (their own
mesh lines, their own condensation, no tracing), compared value by value (a morphed mesh equals
the rebuilt one) and by central differences of an output (the traced derivative through the
equilibrium's implicit tangent equals the derivative of rebuilt machines), at preload and with
rails rough enough that rows unload.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffguide.fe.mesh import Rib
from diffguide.guideway.rails import SplineRail
from diffguide.machine.build import (
    build_machine,
    layout_ranges,
    machine_from_table,
    with_overrides,
)
from diffguide.machine.equilibrium import equilibrium
from diffguide.machine.kinematics import joint_errors
from diffguide.machine.morph import GeometryRangeError, apply_layout
from diffguide.machine.paper import majda2012_spec

MESH = {"nx": 8, "ny": 4}
POSITIONS = jnp.linspace(-0.3, 0.3, 4)
NUT = (0.012, 0.013)  # off the centre lines (x = 0, y = 0: a uniform line and P5's)
RIBS = (Rib("x", 0.0, 0.02, 0.06), Rib("y", 0.25, 0.03, 0.05))
#: the traced variables, in the order of the parameter vector, and their nominal values (m)
NAMES = ("rail_spacing", "nut_x", "nut_y", "rib_width", "rib_depth", "carriage_spacing")
NOMINAL = np.array([0.34, NUT[0], NUT[1], 0.025, 0.055, 0.32])
N = 15  # spline coefficients per rail and plane


def _spec(rail_spacing=0.34, nut=NUT, rib_width=(0.02, 0.03), rib_depth=(0.06, 0.05),
          carriage_spacing=0.32):
    """The coarse ``majda2012`` machine with its nut at ``nut`` and two ribs, built plainly
    (no override): the rails at ±rail_spacing/2, the carriages at ±carriage_spacing/2, the ribs
    with the given sizes (m)."""
    spec = majda2012_spec()
    guideway = dataclasses.replace(spec.guideway, rail_y=(-rail_spacing / 2, rail_spacing / 2),
                                   carriage_x=(-carriage_spacing / 2, carriage_spacing / 2))
    screw = dataclasses.replace(spec.screw, nut_xy=nut)
    ribs = tuple(dataclasses.replace(r, width=w, depth=d)
                 for r, w, d in zip(RIBS, rib_width, rib_depth))
    spec = dataclasses.replace(spec, guideway=guideway, screw=screw, ribs=ribs)
    return with_overrides(spec, **MESH)


def _rebuilt(p):
    """The machine rebuilt at parameters ``p`` (:data:`NAMES`, m): rib sizes alike on both."""
    s, nx, ny, w, d, c = (float(v) for v in p)
    return build_machine(_spec(s, (nx, ny), (w, w), (d, d), c))


def _traced(p):
    return build_machine(_spec(), **dict(zip(NAMES, p)))


def _rails(scale):
    """Rails with spline errors in both planes, ``scale`` × a 3 µm coefficient scatter."""
    c = scale * np.random.default_rng(7).normal(scale=3e-6, size=4 * N)
    r1 = SplineRail(-0.6, 0.1, c[:N], c[N:2 * N])
    return r1, SplineRail(-0.6, 0.1, c[2 * N:3 * N], c[3 * N:])


def _objective(machine, rails):
    """Σ (EYX² + EZX²) (µm²) + Σ (EAX² + EBX² + ECX²) (µrad²) over the points and positions."""
    e = joint_errors(machine, rails, POSITIONS).errors * 1e6
    return jnp.sum(e[:, :, 1:] ** 2)


def _table_arrays(machine):
    t = machine.table
    return [t.K, t.f, t.R, t.r0, t.ref_points, t.nodes, machine.carriage_x]


def _assert_same_machine(a, b):
    for x, y in zip(_table_arrays(a), _table_arrays(b)):
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12 * float(jnp.max(jnp.abs(y))))


def test_overrides_at_their_nominal_give_the_plain_build():
    _assert_same_machine(_traced(jnp.asarray(NOMINAL)), _rebuilt(NOMINAL))


@pytest.mark.parametrize("k, delta", [(0, 0.01), (0, -0.04), (1, -0.01), (2, 0.01), (5, 0.1)])
def test_moved_layout_is_the_rebuilt_mesh(k, delta):
    p = NOMINAL.copy()
    p[k] += delta
    _assert_same_machine(_traced(jnp.asarray(p)), _rebuilt(p))


#: the objective's gradient w.r.t. all six variables (reverse mode, as a design loop takes it),
#: one traced program (the rails an argument)
_gradient = eqx.filter_jit(jax.grad(lambda p, rails: _objective(_traced(p), rails)))


def test_apply_layout_writes_the_overrides_into_the_positions():
    moved = with_overrides(_spec(), rail_spacing=0.33, nut_x=0.02, nut_y=0.005,
                           carriage_spacing=0.33)
    plain = apply_layout(moved)
    assert plain.guideway.rail_y == pytest.approx((-0.165, 0.165), abs=1e-15)
    assert plain.guideway.carriage_x == pytest.approx((-0.165, 0.165), abs=1e-15)
    assert plain.screw.nut_xy == (0.02, 0.005)
    assert plain.guideway.rail_spacing is None and plain.screw.nut_x is None
    _assert_same_machine(build_machine(moved), build_machine(plain))


def _gradient_against_rebuilt(p0, rails, steps):
    """jax.grad of the objective w.r.t. all six variables and central differences of rebuilt
    machines, each step ``steps[i]`` (m); and the objective's value."""
    grad = np.asarray(_gradient(jnp.asarray(p0), rails))
    fd = []
    for i, h in enumerate(steps):
        up, down = p0.copy(), p0.copy()
        up[i] += h
        down[i] -= h
        fd.append((float(_objective(_rebuilt(up), rails))
                   - float(_objective(_rebuilt(down), rails))) / (2 * h))
    return grad, np.array(fd), float(_objective(_rebuilt(p0), rails))


def test_gradient_is_the_derivative_of_rebuilt_machines():
    rails = _rails(1.0)
    grad, fd, value = _gradient_against_rebuilt(NOMINAL, rails, [1e-5] * 6)
    assert np.all(np.abs(fd) > 1e-4 * value)  # every variable matters (per m of it)
    np.testing.assert_allclose(grad, fd, rtol=1e-4)


def test_gradient_through_lift_off_near_the_bounds():
    # rails 8x rougher: rows unload; the rails 1 mm inside their upper bound (rail 2's
    # footprint edge at y = 0.194 + Δs/2 meets P1's line y = 0.2 at 0.352 m), the nut 1 mm from
    # the centre lines it may not cross, the carriages' inner edges (x = ±0.13 m at 0.32 m)
    # 0.5 mm from the uniform lines x = ±0.125 m
    rails = _rails(8.0)
    p0 = np.array([0.351, 0.001, 0.001, 0.004, 0.2, 0.311])
    forces = np.asarray(equilibrium(_rebuilt(p0), rails, POSITIONS).forces)
    median = np.median(forces)
    assert np.mean(forces < 0.05 * median) > 0.25  # measured: 34 % of the elements nearly unloaded
    # steps (m) where the differences' truncation and noise (the solves' tolerance) both stay
    # below ~1e-5 of the derivative (measured over 1e-5 .. 3e-7 m)
    grad, fd, _ = _gradient_against_rebuilt(p0, rails, [3e-6, 1e-5, 1e-5, 1e-6, 1e-5, 1e-6])
    assert np.all(np.isfinite(grad))
    np.testing.assert_allclose(grad, fd, rtol=1e-4)


def test_out_of_range_layout_is_refused_naming_the_range():
    # rail 2's footprint edge at y = 0.194 m meets P1's line y = 0.2 m at spacing 0.352 m,
    # its inner edge (0.146 m) the uniform line y = 0.125 m at 0.298 m
    with pytest.raises(GeometryRangeError, match=r"rail_spacing within \(0\.298, 0\.352\) m"):
        build_machine(_spec(), rail_spacing=0.46)
    with pytest.raises(ValueError, match="nut_x"):
        build_machine(_spec(), nut_x=-0.02)  # its edge at x = -0.013 would cross x = 0


def test_traced_layout_at_its_nominal_is_the_plain_build_and_refused_out_of_range():
    traced = eqx.filter_jit(lambda s: _table_arrays(build_machine(_spec(), rail_spacing=s)))
    plain = _table_arrays(build_machine(_spec()))
    for x, y in zip(traced(jnp.asarray(0.34)), plain):
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12 * float(jnp.max(jnp.abs(y))))
    with pytest.raises(RuntimeError, match=r"rail_spacing.*within \(0\.298, 0\.352\) m"):
        jax.block_until_ready(traced(jnp.asarray(0.46)))


def test_layout_ranges_are_the_gaps_to_the_next_grid_lines():
    # nx = 8, ny = 4: uniform lines every 125 mm; P1..P4 put lines at x = ±0.45, y = ±0.2 m;
    # carriage edges at x = ±0.13, ±0.19 m, rail footprint edges at y = ±0.146, ±0.194 m, the
    # nut's at x = -0.013, 0.037 m (centre 0.012), y = -0.012, 0.038 m (centre 0.013)
    ranges = layout_ranges(_spec())
    expected = {
        "carriage_spacing": (2 * (0.125 + 0.03), 2 * (0.25 - 0.03)),  # inner edge to ±0.125
        "rail_spacing": (2 * (0.125 + 0.024), 2 * (0.2 - 0.024)),  # to y = ±0.125, P1's 0.2
        "nut_x": (0.0, 0.025),  # its centre line to x = 0 (P5), its lower edge to x = 0
        "nut_y": (0.0, 0.025),
    }
    assert ranges.keys() == expected.keys()
    for name, (lo, hi) in expected.items():
        assert ranges[name] == pytest.approx((lo, hi), abs=1e-12), name
    spec = _spec()
    edge = dataclasses.replace(spec, screw=dataclasses.replace(spec.screw, nut_xy=(0.475, 0.0)))
    assert layout_ranges(edge)["nut_x"] is None  # the nut flange on the table's end


def test_a_table_condensed_elsewhere_refuses_a_traced_layout():
    table = build_machine(_spec()).table  # its interfaces where the plain layout puts them
    machine_from_table(_spec(), table)
    with pytest.raises(ValueError, match="nut_y: a table condensed elsewhere"):
        machine_from_table(with_overrides(_spec(), nut_y=0.014), table)


def test_rib_sizes_need_ribs_and_a_plausible_size():
    with pytest.raises(ValueError, match="no ribs"):
        with_overrides(majda2012_spec(), rib_depth=0.05)
    with pytest.raises(ValueError, match=r"rib_width\[1\].*\[0\.001, 1\] m"):
        with_overrides(_spec(), rib_width=(0.02, 3.0))


@pytest.mark.slow  # a second-order program: ~2-3 min to compile on two cores
def test_hessian_vector_product_is_the_derivative_of_the_gradient():
    # Newton or trust-region design steps take curvature: the forward derivative of the
    # (reverse-mode) gradient along a layout direction against central differences of that
    # gradient, itself checked against rebuilt machines above
    rails = _rails(1.0)
    p0 = jnp.asarray(NOMINAL)
    v = jnp.zeros(6).at[0].set(1.0)  # rail spacing
    hv = np.asarray(eqx.filter_jit(lambda p: jax.jvp(lambda q: _gradient(q, rails), (p,),
                                                     (v,))[1])(p0))
    h = 1e-5
    fd = (np.asarray(_gradient(p0 + h * v, rails)) - np.asarray(_gradient(p0 - h * v, rails)))
    fd /= 2 * h
    np.testing.assert_allclose(hv, fd, rtol=1e-4, atol=1e-5 * np.max(np.abs(fd)))
