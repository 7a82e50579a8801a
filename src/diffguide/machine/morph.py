"""Traced layout: the table mesh morphed with the carriage spacing, rail spacing and nut position.

The carriages and the nut are rigid patches whose footprints hold whole elements: a rebuild puts
grid lines at every footprint's edges and centre (:func:`~diffguide.fe.condense.patch_lines`).
A traced layout variable keeps the mesh topology of the specification and moves those grid lines
(and the patch reference points) with the footprints; every other grid line stays. Each variable
moves the patches linearly, ``Δx_p = a_p Δv``, ``Δy_p = b_p Δv`` (``Δv`` the value minus its
nominal in the specification):

- ``carriage_spacing`` (nominal ``carriage_x[1] − carriage_x[0]``): each rail's carriages in X
  about their centre, ``a = ±½``;
- ``rail_spacing`` (nominal ``rail_y[1] − rail_y[0]``): the two rails' carriages in Y about the
  rails' centre, ``b = ±½``;
- ``nut_x``, ``nut_y`` (nominal ``screw.nut_xy``): the nut patch, ``a = 1`` or ``b = 1``.

As long as no moving line reaches another grid line, the morphed mesh is the mesh a rebuild with
the new positions gives, so derivatives w.r.t. the variables are those of rebuilt machines.
The allowed range of each variable (the others at their nominal) follows from the gaps to the
neighbouring lines; a value outside it is refused (:class:`GeometryRangeError`, naming the
range). A footprint line that coincides at the nominal with another grid line (a uniform
division, a control point's line) moves that line too: the mesh then differs from a rebuild's
(which keeps both lines) by a discretisation change, and a control point on the line is
interpolated in its element. Control points stay where the specification puts them (they are
points of the table, not of a carriage); the screw's free length (``free_length_at_ref``) is
that of the specification, as in a rebuild.
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._core.checks import concrete

#: The layout variables that morph the mesh, in the order of :func:`layout_variables`.
LAYOUT_VARIABLES = ("carriage_spacing", "rail_spacing", "nut_x", "nut_y")
_TOL = 1e-9


class GeometryRangeError(ValueError, RuntimeError):
    """A layout variable outside the range where the mesh topology holds: a ``ValueError`` (a
    concrete value, refused when the machine is built) that is also a ``RuntimeError`` (what a
    traced value's refusal, ``eqx.error_if``, raises when the program runs)."""


@dataclasses.dataclass(frozen=True)
class LayoutVariable:
    """One traced layout variable: its value, its nominal and how it moves each patch.

    Attributes:
        name: one of :data:`LAYOUT_VARIABLES`. value: the value (m; may be traced).
        nominal: its value in the specification (m). rate_x, rate_y: ``∂x_p/∂v``, ``∂y_p/∂v``
            of each patch reference point (carriages, then the nut), dimensionless.
    """

    name: str
    value: object
    nominal: float
    rate_x: np.ndarray
    rate_y: np.ndarray


def layout_variables(spec, patches, every: bool = False) -> list[LayoutVariable]:
    """The layout variables ``spec`` sets (not ``None``; with ``every``, all four, those not set
    at their nominal), for the table's ``patches`` (carriages ``C{rail}{carriage}``, then the
    nut)."""
    g, s = spec.guideway, spec.screw
    n = len(patches)
    carriages = patches[:-1]
    cx, ry = np.asarray(g.carriage_x, float), np.asarray(g.rail_y, float)
    out = []

    def along(values, coords):
        s0 = float(values[-1] - values[0])
        idx = [int(np.argmin(abs(values - c))) for c in coords]
        rate = np.zeros(n)
        rate[: len(idx)] = (values[idx] - values.mean()) / s0
        return s0, rate

    nut = np.zeros(n)
    nut[-1] = 1.0
    s0x, rate_x = along(cx, [p.x for p in carriages])
    s0y, rate_y = along(ry, [p.y for p in carriages])
    table = (
        ("carriage_spacing", g.carriage_spacing, s0x, rate_x, np.zeros(n)),
        ("rail_spacing", g.rail_spacing, s0y, np.zeros(n), rate_y),
        ("nut_x", s.nut_x, float(s.nut_xy[0]), nut, np.zeros(n)),
        ("nut_y", s.nut_y, float(s.nut_xy[1]), np.zeros(n), nut),
    )
    for name, value, nominal, ax, by in table:
        if value is not None or every:
            out.append(LayoutVariable(name, nominal if value is None else value, nominal, ax, by))
    return out


def _line_rates(lines, patches, rates, axis):
    """``(n_lines, n_vars)``: ``∂line/∂v`` of each grid line; a line shared by footprints that
    move differently, or a table edge that would move, is refused (``ValueError``)."""
    out = np.zeros((len(lines), rates.shape[1]))
    owner = [None] * len(lines)
    for p, patch in enumerate(patches):
        x_lo, x_hi, y_lo, y_hi = patch.box
        own = (x_lo, patch.x, x_hi) if axis == "x" else (y_lo, patch.y, y_hi)
        on = np.flatnonzero(np.isclose(lines[:, None], own, rtol=0, atol=_TOL).any(axis=1))
        for i in on:
            if owner[i] is not None and not np.allclose(out[i], rates[p]):
                raise ValueError(
                    f"the grid line {axis} = {lines[i]:g} m is on the footprints of "
                    f"{patches[owner[i]].name} and {patch.name}, which the traced layout moves "
                    "differently; shift one of them in the specification")
            owner[i] = p
            out[i] = rates[p]
    for i in (0, len(lines) - 1):
        if np.any(out[i] != 0):
            raise ValueError(
                f"the footprint of {patches[owner[i]].name} touches the table edge "
                f"{axis} = {lines[i]:g} m: its position cannot be traced (the table would "
                "change size); move it inside the table in the specification")
    return out


def allowed_ranges(lines, line_rates, nominals) -> list[tuple[float, float]]:
    """Open interval ``(lo, hi)`` (m) of each variable, the others at their nominal, within which
    the grid ``lines`` (m) moved by ``line_rates`` stay in order."""
    gap = np.diff(lines)
    out = []
    for v, v0 in enumerate(nominals):
        dr = np.diff(line_rates[:, v])
        lo = max([-g / d for g, d in zip(gap, dr) if d > 0], default=-np.inf)
        hi = min([g / -d for g, d in zip(gap, dr) if d < 0], default=np.inf)
        out.append((v0 + lo, v0 + hi))
    return out


def _rates_and_ranges(model, variables):
    """The grid lines' rates ``∂x_i/∂v``, ``∂y_j/∂v`` and each variable's allowed range (m)."""
    xs, ys = np.asarray(model.mesh.xs, float), np.asarray(model.mesh.ys, float)
    nominals = [v.nominal for v in variables]
    rx = np.stack([v.rate_x for v in variables], axis=1)  # (n_patches, n_vars)
    ry = np.stack([v.rate_y for v in variables], axis=1)
    lrx, lry = _line_rates(xs, model.patches, rx, "x"), _line_rates(ys, model.patches, ry, "y")
    ranges = [
        (max(a[0], b[0]), min(a[1], b[1]))
        for a, b in zip(allowed_ranges(xs, lrx, nominals), allowed_ranges(ys, lry, nominals))
    ]
    return lrx, lry, ranges


def layout_ranges(model, spec) -> dict[str, tuple[float, float] | None]:
    """``{name: (lo, hi)}``: the open range (m) of each layout variable on ``model``'s mesh
    (:func:`~diffguide.machine.build.table_from_spec` of ``spec``), each with the others at
    their nominal (the specification's positions); ``None`` for one that cannot be traced there
    (its footprint on the table edge, or sharing a grid line with a footprint it does not
    move)."""
    out = {}
    for v in layout_variables(spec, model.patches, every=True):
        try:
            out[v.name] = _rates_and_ranges(model, [v])[2][0]
        except ValueError:
            out[v.name] = None
    return out


def morph_layout(model, variables: list[LayoutVariable]):
    """Node coordinates (n_nodes, 3), patch reference points (n_patches, 2) and carriage X
    (n_carriages,) (m) of ``model`` (:class:`~diffguide.fe.table.TableModel`) with the layout
    ``variables`` applied (module docstring); values outside their range are refused
    (:class:`GeometryRangeError`)."""
    patches, mesh = model.patches, model.mesh
    xs, ys = np.asarray(mesh.xs, float), np.asarray(mesh.ys, float)
    names = [v.name for v in variables]
    lrx, lry, ranges = _rates_and_ranges(model, variables)
    rx = np.stack([v.rate_x for v in variables], axis=1)  # (n_patches, n_vars)
    ry = np.stack([v.rate_y for v in variables], axis=1)
    stated = "; ".join(f"{n} within ({lo:.6g}, {hi:.6g}) m" for n, (lo, hi) in zip(names, ranges))
    why = ("moves a footprint's grid line across another grid line of the mesh (the topology is "
           f"fixed): allowed, each with the others at their nominal, {stated}; change the "
           "specification's positions (or the mesh divisions) for a larger move")
    for v, (lo, hi) in zip(variables, ranges):
        if concrete(v.value) and not lo < float(v.value) < hi:
            raise GeometryRangeError(f"{v.name} = {float(v.value):.6g} m {why}")
    dv = jnp.stack([jnp.asarray(v.value, dtype=float) - v.nominal for v in variables])
    new_xs, new_ys = xs + lrx @ dv, ys + lry @ dv
    if all(concrete(v.value) for v in variables):
        if np.any(np.diff(np.asarray(new_xs)) <= 0) or np.any(np.diff(np.asarray(new_ys)) <= 0):
            raise GeometryRangeError(f"{', '.join(names)} together {why}")
    else:
        bad = jnp.any(jnp.diff(new_xs) <= 0) | jnp.any(jnp.diff(new_ys) <= 0)
        new_xs = eqx.error_if(new_xs, bad, f"{', '.join(names)}: {why}")
    nodes = jnp.asarray(mesh.nodes, dtype=float)
    nodes = nodes.at[:, 0].set(jnp.repeat(new_xs, len(ys))).at[:, 1].set(jnp.tile(new_ys, len(xs)))
    ref0 = np.array([[p.x, p.y] for p in patches])
    ref_xy = ref0 + jnp.stack([rx @ dv, ry @ dv], axis=1)
    return nodes, ref_xy, ref_xy[:-1, 0]


def apply_layout(spec):
    """``spec`` with its layout overrides (``carriage_spacing``, ``rail_spacing``, ``nut_x``,
    ``nut_y``; concrete values) written into the positions a rebuild uses (``carriage_x``,
    ``rail_y``, ``nut_xy``, m) and cleared: e.g. an optimised layout as a plain specification
    (a machine file with :func:`diffguide.io.config_spec.config_from_spec`). ``TypeError`` for a
    traced value."""
    g, s = spec.guideway, spec.screw
    values = {"carriage_spacing": g.carriage_spacing, "rail_spacing": g.rail_spacing,
              "nut_x": s.nut_x, "nut_y": s.nut_y}
    for name, v in values.items():
        if v is not None and not concrete(v):
            raise TypeError(f"apply_layout: {name} is traced; call it on concrete values")

    def spread(pair, value):
        if value is None:
            return pair
        a, b = pair
        centre, half = 0.5 * (a + b), 0.5 * float(value)
        return (centre - half, centre + half)

    guideway = dataclasses.replace(
        g, carriage_x=spread(g.carriage_x, g.carriage_spacing),
        rail_y=spread(g.rail_y, g.rail_spacing), carriage_spacing=None, rail_spacing=None)
    nut = tuple(float(v) if v is not None else v0 for v, v0 in zip((s.nut_x, s.nut_y), s.nut_xy))
    screw = dataclasses.replace(s, nut_xy=nut, nut_x=None, nut_y=None)
    return dataclasses.replace(spec, guideway=guideway, screw=screw)
