"""From a machine configuration (:mod:`diffguide.io.config`, user units) to a
:class:`~diffguide.machine.Machine` (SI): the table condensed onto its carriages and nut, the
runner block, the screw.

Parameters that studies differentiate (plate thickness, table E, preload fraction, carriage
spacing) can be passed as (traced) SI overrides; everything else comes from the configuration.

Carriage spacing. The carriage X positions enter twice: where the rails are sampled
(``Machine.carriage_x``) and where the carriages are bolted to the table (the footprint patches
and the mesh lines at their edges). A ``carriage_spacing`` override keeps the configuration's
mesh topology and moves the grid lines of each carriage footprint (its edges and centre line)
with the carriage, together with the patch reference point; the other grid lines stay.
The moved mesh is then exactly the mesh a rebuild with the new ``carriage_x_mm`` gives (as long
as no footprint line passes another grid line), so the derivative w.r.t. the spacing is the
derivative of the rebuilt model.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..contact.laws import HertzBall, PalmgrenRoller, RivinBall
from ..fe.materials import Material
from ..fe.mesh import Rib
from ..fe.table import table_model
from ..guideway.carriage import four_row_carriage
from ..io.config import default_config
from .equilibrium import Machine


def carriage_from_config(cfg: dict, preload_fraction=None):
    """The runner block of a configuration (see ``[carriage]`` in :data:`config.SCHEMA`)."""
    c = cfg["carriage"]
    d = c["ball_diameter_mm"] * 1e-3
    E, nu = c["E_GPa"] * 1e9, c["nu"]
    if c["law"] == "hertz":
        law = HertzBall(d, c["groove_conformity"] * d, E, nu)
    elif c["law"] == "rivin":
        law = RivinBall(d, c["groove_conformity"] * d, E, nu)
    else:
        law = PalmgrenRoller(c["roller_length_mm"] * 1e-3)
    return four_row_carriage(
        law,
        n=c["elements_per_row"],
        pitch=c["pitch_mm"] * 1e-3,
        capacity=c["capacity_N"],
        preload_fraction=c["preload_fraction"] if preload_fraction is None else preload_fraction,
        upper_yz=tuple(v * 1e-3 for v in c["upper_row_yz_mm"]),
        lower_yz=tuple(v * 1e-3 for v in c["lower_row_yz_mm"]),
        contact_angle_deg=c["contact_angle_deg"],
        arrangement=c["arrangement"],
        eps_ratio=c["smoothing_fraction"],
    )


def table_from_config(cfg: dict, *, thickness=None, E=None, nx=None, ny=None, nut=True):
    """The :class:`~diffguide.fe.table.TableModel` of a configuration (SI overrides allowed)."""
    t, g, s = cfg["table"], cfg["guideway"], cfg["screw"]
    material = Material(
        E=t["E_GPa"] * 1e9 if E is None else E, nu=t["nu"], rho=t["density_kg_m3"], name="table"
    )
    return table_model(
        length=t["length_mm"] * 1e-3,
        width=t["width_mm"] * 1e-3,
        thickness=t["thickness_mm"] * 1e-3 if thickness is None else thickness,
        material=material,
        nx=t["mesh_nx"] if nx is None else nx,
        ny=t["mesh_ny"] if ny is None else ny,
        rail_y=[v * 1e-3 for v in g["rail_y_mm"]],
        carriage_x=[v * 1e-3 for v in g["carriage_x_mm"]],
        footprint=tuple(v * 1e-3 for v in g["carriage_footprint_mm"]),
        points={k: (v[0] * 1e-3, v[1] * 1e-3) for k, v in cfg["points"].items()},
        nut_xy=tuple(v * 1e-3 for v in s["nut_xy_mm"]) if nut else None,
        nut_half=tuple(0.5e-3 * v for v in s["nut_footprint_mm"]),
        ribs=[
            Rib(axis=r["axis"], position=r["position_mm"] * 1e-3, width=r["width_mm"] * 1e-3,
                depth=r["depth_mm"] * 1e-3)
            for r in cfg.get("ribs", [])
        ],
        gravity=cfg["machine"]["gravity_m_s2"],
    )


def _moved_carriages(model, carriage_x0, spacing):
    """Node coordinates, patch reference points (x, y) and carriage X (m) for a carriage
    ``spacing`` (m; may be traced): each rail's carriages spread about their centre by
    ``spacing / s₀`` (``s₀`` the configuration's spacing); the grid lines a rebuild puts at each
    footprint (its edges and centre, :func:`~diffguide.fe.condense.patch_lines`) move with their
    carriage, every other grid line stays, as in a rebuilt mesh."""
    x0 = np.asarray(carriage_x0, dtype=float)
    s0 = float(x0[-1] - x0[0])
    centre = x0.mean()
    shift_per_x = (x0 - centre) / s0  # d(carriage x)/d(spacing) for each carriage along a rail
    mesh = model.mesh
    xs = np.asarray(mesh.xs)
    carriages = model.patches[:-1]
    patch_shift, line_shift = [], jnp.zeros(len(xs))
    for patch in carriages:
        k = int(np.argmin(abs(x0 - patch.x)))
        shift = (spacing - s0) * shift_per_x[k]
        x_lo, x_hi = patch.box[:2]
        on = np.isclose(xs[:, None], [x_lo, patch.x, x_hi], rtol=0, atol=1e-9).any(axis=1)
        line_shift = jnp.where(on, shift, line_shift)  # both rails' carriages move alike
        patch_shift.append(shift)
    new_xs = xs + line_shift
    new_xs = eqx.error_if(
        new_xs,
        jnp.any(jnp.diff(new_xs) <= 0),
        "carriage_spacing moves a carriage footprint across another grid line of the mesh; "
        "change guideway.carriage_x_mm in the configuration instead (or refine less)",
    )
    ny = len(mesh.ys)
    nodes = jnp.asarray(mesh.nodes, dtype=float).at[:, 0].set(jnp.repeat(new_xs, ny))
    patch_shift = jnp.stack(patch_shift)
    ref_x = jnp.concatenate(
        [jnp.array([p.x for p in carriages]) + patch_shift, jnp.array([model.patches[-1].x])]
    )
    ref_xy = jnp.stack([ref_x, jnp.array([p.y for p in model.patches])], axis=1)
    return nodes, ref_xy, ref_x[:-1]


def build_machine(
    cfg: dict | None = None,
    *,
    thickness=None,
    E=None,
    preload_fraction=None,
    carriage_spacing=None,
    nx: int | None = None,
    ny: int | None = None,
    points: dict[str, tuple[float, float]] | None = None,
) -> Machine:
    """Build (and condense) the machine of a configuration; default: ``majda2012``.

    Arguments:
        cfg: a validated configuration (:func:`diffguide.io.config.load_config`); default preset.
        thickness: plate thickness override (m; may be traced for gradients).
        E: table Young's modulus override (Pa; may be traced).
        preload_fraction: preload override, fraction of C (may be traced).
        carriage_spacing: distance between the two carriages on each rail (m; may be traced),
            overriding ``guideway.carriage_x_mm`` about its centre; the mesh keeps the
            configuration's topology with the footprint lines moved (module docstring), valid
            while no footprint line passes another grid line (checked; an error otherwise).
        nx, ny: mesh divisions override.
        points: control points override ``{name: (x, y)}`` in m.
    """
    cfg = default_config() if cfg is None else cfg
    if points is not None:
        cfg = {**cfg, "points": {k: (v[0] * 1e3, v[1] * 1e3) for k, v in points.items()}}
    model = table_from_config(cfg, thickness=thickness, E=E, nx=nx, ny=ny)
    carriage = carriage_from_config(cfg, preload_fraction)
    rail_y = cfg["guideway"]["rail_y_mm"]
    carriage_x, carriage_rail = [], []
    for patch in model.patches[:-1]:  # carriages, then the nut
        carriage_x.append(patch.x)
        carriage_rail.append(int(np.argmin([abs(patch.y * 1e3 - ry) for ry in rail_y])))
    carriage_x = np.asarray(carriage_x)
    if carriage_spacing is None:
        table = model.condense()
    else:
        x0 = [v * 1e-3 for v in cfg["guideway"]["carriage_x_mm"]]
        nodes, ref_xy, carriage_x = _moved_carriages(model, x0, carriage_spacing)
        table = model.condense(nodes=nodes, ref_xy=ref_xy)
    s = cfg["screw"]
    d = s["core_diameter_mm"] * 1e-3
    return Machine(
        table=table,
        carriage=carriage,
        carriage_x=carriage_x,
        carriage_rail=tuple(carriage_rail),
        point_names=model.point_names,
        points_xy=np.asarray(model.points),
        screw_EA=s["E_GPa"] * 1e9 * np.pi * d**2 / 4,
        screw_length_ref=s["free_length_at_ref_mm"] * 1e-3,
    )
