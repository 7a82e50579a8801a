"""From a typed machine specification (:class:`~diffguide.machine.spec.MachineSpec`, SI) to a
:class:`~diffguide.machine.equilibrium.Machine`: the table condensed onto its carriages and nut,
the runner block, the screw.

Parameters that studies differentiate are fields of the specification that may hold traced
arrays (``spec.table.thickness``, ``spec.table.material.E``, ``spec.carriage.preload_fraction``,
``spec.guideway.carriage_spacing``); replace them with ``eqx.tree_at``.

Layout. The carriage X positions enter twice: where the rails are sampled
(``Machine.carriage_x``) and where the carriages are bolted to the table (the footprint patches
and the mesh lines at their edges); the rail Y positions and the nut position enter only through
the table (its patches and mesh lines). A ``carriage_spacing``, ``rail_spacing``, ``nut_x`` or
``nut_y`` keeps the specification's mesh topology and moves the grid lines of each footprint
(its edges and centre line) with it, together with the patch reference point; the other grid
lines stay (:mod:`~diffguide.machine.morph`). The moved mesh is then exactly the mesh a rebuild
with the new positions gives (as long as no footprint line passes another grid line), so the
derivative w.r.t. the layout is the derivative of the rebuilt model.

Ribs. A rib's ``width`` and ``depth`` are section constants of its beam elements (the rib runs
along a grid line, which neither changes), so ``rib_width`` and ``rib_depth`` are traced as they
are, like the plate thickness.
"""

import dataclasses

import equinox as eqx
import jax
import numpy as np

from .._core.checks import length
from ..fe.condense import CondensedTable
from ..fe.table import TableModel, table_model
from ..guideway.carriage import carriage_from_spec
from .equilibrium import Machine
from .morph import layout_ranges as _layout_ranges
from .morph import layout_variables, morph_layout
from .paper import majda2012_spec
from .spec import MachineSpec

#: Rib sizes (m) a traced ``rib_width`` / ``rib_depth`` may take when concrete: the machine
#: file's ranges (width 1 mm .. 1 m, depth 1 mm .. 2 m).
RIB_WIDTH_RANGE = (1e-3, 1.0)
RIB_DEPTH_RANGE = (1e-3, 2.0)


def table_from_spec(spec: MachineSpec, *, nut: bool = True) -> TableModel:
    """The :class:`~diffguide.fe.table.TableModel` of a machine: its plate on the carriage
    footprints (and the nut's flange with ``nut``), with its control points and ribs."""
    t, g, s = spec.table, spec.guideway, spec.screw
    return table_model(
        length=t.length,
        width=t.width,
        thickness=t.thickness,
        material=t.material,
        nx=t.nx,
        ny=t.ny,
        rail_y=g.rail_y,
        carriage_x=g.carriage_x,
        footprint=g.footprint,
        points=spec.point_dict,
        nut_xy=s.nut_xy if nut else None,
        nut_half=(0.5 * s.nut_footprint[0], 0.5 * s.nut_footprint[1]),
        ribs=spec.ribs,
        gravity=spec.gravity,
    )


def with_overrides(
    spec: MachineSpec,
    *,
    thickness=None,
    E=None,
    preload_fraction=None,
    carriage_spacing=None,
    rail_spacing=None,
    nut_x=None,
    nut_y=None,
    rib_width=None,
    rib_depth=None,
    nx: int | None = None,
    ny: int | None = None,
    points: dict[str, tuple[float, float]] | None = None,
) -> MachineSpec:
    """``spec`` with the given fields replaced (``None``: kept); SI units. The array fields
    (thickness, E, preload fraction, carriage and rail spacing, nut X and Y, rib width and
    depth) may be traced; ``nx``, ``ny`` and the control ``points`` ``{name: (x, y)}`` (m) may
    not: they fix the mesh (a point puts grid lines through itself), so a traced point
    coordinate is refused (``TypeError``). ``rib_width`` and ``rib_depth`` (m, within
    :data:`RIB_WIDTH_RANGE`, :data:`RIB_DEPTH_RANGE`) are one value for every rib or a
    sequence with one per rib of ``spec.ribs``."""
    if thickness is not None:
        spec = eqx.tree_at(lambda m: m.table.thickness, spec, thickness)
    if E is not None:
        spec = eqx.tree_at(lambda m: m.table.material.E, spec, E)
    if preload_fraction is not None:
        spec = eqx.tree_at(lambda m: m.carriage.preload_fraction, spec, preload_fraction)
    if carriage_spacing is not None:
        spec = eqx.tree_at(
            lambda m: m.guideway.carriage_spacing,
            spec,
            carriage_spacing,
            is_leaf=lambda x: x is None,
        )
    if rail_spacing is not None:
        spec = eqx.tree_at(lambda m: m.guideway.rail_spacing, spec, rail_spacing,
                           is_leaf=lambda x: x is None)
    for name, value in (("nut_x", nut_x), ("nut_y", nut_y)):
        if value is not None:
            spec = eqx.tree_at(lambda m, n=name: getattr(m.screw, n), spec, value,
                               is_leaf=lambda x: x is None)
    for name, value, bounds in (("width", rib_width, RIB_WIDTH_RANGE),
                                ("depth", rib_depth, RIB_DEPTH_RANGE)):
        if value is not None:
            spec = _with_rib_size(spec, name, value, bounds)
    if nx is not None or ny is not None:
        table = dataclasses.replace(
            spec.table,
            nx=spec.table.nx if nx is None else nx,
            ny=spec.table.ny if ny is None else ny,
        )
        spec = eqx.tree_at(lambda m: m.table, spec, table)
    if points is not None:
        traced = [n for n, xy in dict(points).items()
                  if any(isinstance(v, jax.core.Tracer) for v in jax.tree_util.tree_leaves(xy))]
        if traced:
            raise TypeError(
                f"control point {traced[0]!r} is traced (jax.grad/jacfwd/vmap over its "
                "position): points set the mesh lines and must be concrete numbers; for the "
                "effect of moving a point use error_field (the errors at every node) or a "
                "finite difference over rebuilt machines")
        spec = dataclasses.replace(spec, points=points)
    return spec


def _with_rib_size(spec, name, value, bounds):
    """``spec`` with every rib's ``name`` (``width`` or ``depth``) set to ``value`` (m; one
    value, or one per rib)."""
    n = len(spec.ribs)
    if n == 0:
        raise ValueError(f"rib_{name}: this machine has no ribs (spec.ribs is empty); add a "
                         "[[ribs]] table to the machine file")
    values = list(value) if isinstance(value, (list, tuple)) else (
        [value] * n if np.ndim(value) == 0 else list(value))
    if len(values) != n:
        raise ValueError(f"rib_{name}: one value or one per rib ({n}), got {len(values)}")
    for k, v in enumerate(values):
        length(f"rib_{name}[{k}]", v, *bounds)
    return eqx.tree_at(lambda m: [getattr(r, name) for r in m.ribs], spec, values)


def build_machine(spec: MachineSpec | None = None, **overrides) -> Machine:
    """Build (and condense) the machine of a specification; default: ``majda2012``.

    Arguments:
        spec: a :class:`~diffguide.machine.spec.MachineSpec` (default
            :func:`~diffguide.machine.paper.majda2012_spec`); a machine file's configuration
            (user units) becomes one with :func:`diffguide.io.config.spec_from_config`.
        overrides: ``thickness``, ``E``, ``preload_fraction``, ``carriage_spacing``,
            ``rail_spacing``, ``nut_x``, ``nut_y``, ``rib_width``, ``rib_depth``, ``nx``,
            ``ny``, ``points``: shorthands for replacing those fields of ``spec``
            (:func:`with_overrides`; SI: m, Pa). All but ``nx``, ``ny`` and ``points`` may be
            traced (differentiated); ``nx``, ``ny`` and ``points``
            (control points ``{name: (x, y)}``, m) must be concrete: they set the mesh lines, so
            a point's position is not differentiable (a traced coordinate is refused,
            ``TypeError``; use a finite difference over rebuilt machines, or
            :func:`~diffguide.machine.kinematics.error_field` for the errors at every node).
            ``carriage_spacing`` (the distance between the two carriages on each rail),
            ``rail_spacing`` (between the two rails) and ``nut_x``, ``nut_y`` (the nut's
            position) keep the mesh topology with the footprint lines moved (module
            docstring), valid while no footprint line passes another grid line: a value
            outside that range is refused with the range in m
            (:class:`~diffguide.machine.morph.GeometryRangeError`). ``rib_width`` and
            ``rib_depth`` (m) are one value for all ribs or one per rib.
    """
    if spec is None:
        spec = majda2012_spec()
    elif not isinstance(spec, MachineSpec):
        raise TypeError(
            "build_machine: spec must be a MachineSpec, got "
            f"{type(spec).__name__}; for a configuration dictionary pass "
            "diffguide.io.config.spec_from_config(cfg), for the paper's machine "
            "diffguide.presets.majda2012()"
        )
    spec = with_overrides(spec, **overrides)
    model = table_from_spec(spec)
    rail_y = spec.guideway.rail_y
    carriage_x, carriage_rail = [], []
    for patch in model.patches[:-1]:  # carriages, then the nut
        carriage_x.append(patch.x)
        carriage_rail.append(int(np.argmin([abs(patch.y - ry) for ry in rail_y])))
    carriage_x = np.asarray(carriage_x)
    variables = layout_variables(spec, model.patches)
    if not variables:
        table = model.condense()
    else:
        nodes, ref_xy, carriage_x = morph_layout(model, variables)
        table = model.condense(nodes=nodes, ref_xy=ref_xy)
    return _assemble(spec, table, carriage_x, carriage_rail, model.point_names, model.points)


def _assemble(spec, table, carriage_x, carriage_rail, point_names, points) -> Machine:
    s = spec.screw
    return Machine(
        table=table,
        carriage=carriage_from_spec(spec.carriage),
        carriage_x=carriage_x,
        carriage_rail=tuple(carriage_rail),
        point_names=tuple(point_names),
        points_xy=np.asarray(points, dtype=float).reshape(-1, 2),
        screw_EA=s.E * np.pi * s.core_diameter**2 / 4,
        screw_length_ref=s.free_length_at_ref,
        stroke=None if spec.stroke is None else float(spec.stroke),
    )


def layout_ranges(spec: MachineSpec) -> dict[str, tuple[float, float] | None]:
    """The open range (m) of each traced layout variable of :func:`build_machine`
    (``carriage_spacing``, ``rail_spacing``, ``nut_x``, ``nut_y``) on ``spec``'s mesh, each with
    the others at the specification's positions: within it no moved footprint line reaches
    another grid line (:mod:`~diffguide.machine.morph`); a value outside is refused. ``None``
    for a variable that cannot be traced on this layout (its footprint on the table edge).
    E.g. the bounds of a design variable (keep a margin: an element next to a bound is thin).
    """
    return _layout_ranges(table_from_spec(spec), spec)


def machine_from_table(spec: MachineSpec, table: CondensedTable) -> Machine:
    """The machine of ``spec`` on a table condensed elsewhere (e.g. imported from an FE code,
    :func:`~diffguide.machine.imported.imported_table`) in place of its plate: the carriages,
    screw and control points of ``spec``; ``table``'s interfaces must be the carriages (rail
    by rail, carriages in the order of ``guideway.carriage_x``) then the nut, its point rows
    those of ``spec.points`` in order. The table's ``[table]`` plate fields are not used."""
    g = spec.guideway
    n_c = len(g.rail_y) * len(g.carriage_x)
    moved = [name for name, v in (("carriage_spacing", g.carriage_spacing),
                                  ("rail_spacing", g.rail_spacing), ("nut_x", spec.screw.nut_x),
                                  ("nut_y", spec.screw.nut_y)) if v is not None]
    if moved:
        raise ValueError(f"{moved[0]}: a table condensed elsewhere has its interfaces where its "
                         "FE model put them; a traced layout needs the plate model "
                         "(build_machine)")
    m = np.shape(table.K)[0]
    if m != 6 * (n_c + 1):
        raise ValueError(f"the table has {m} interface DOF; this machine's {n_c} carriages and "
                         f"its nut need {6 * (n_c + 1)}")
    names = tuple(n for n, _ in spec.points)
    if np.shape(table.R)[0] != 6 * len(names):
        raise ValueError(f"the table has {np.shape(table.R)[0] // 6} control points; the "
                         f"machine has {len(names)} ({', '.join(names)})")
    carriage_x = np.asarray([cx for _ in g.rail_y for cx in g.carriage_x], dtype=float)
    carriage_rail = [r for r in range(len(g.rail_y)) for _ in g.carriage_x]
    return _assemble(spec, table, carriage_x, carriage_rail, names,
                     [xy for _, xy in spec.points])

