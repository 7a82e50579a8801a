"""``diffguide table``: the table mesh and its sag under gravity on four rigid carriages."""

import argparse
import sys

from ._common import add_machine_arguments, machine_spec


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "table",
        help="table FE model: mesh and deflection under gravity on the four carriages",
        description="Build the preset table (MITC4 shells, cast iron), condense it onto the "
        "carriage footprints (rigid patches on the underside), hold the four carriages fixed and "
        "report the sag under gravity. Units: mm for geometry, µm / µrad for deflections.",
    )
    add_machine_arguments(p)
    p.add_argument(
        "--plot",
        metavar="FILE.png",
        default=None,
        help="write the mesh and the magnified deflected shape (colour: uz in µm)",
    )
    p.add_argument(
        "--out",
        metavar="FILE.csv",
        default=None,
        help="write node deflections: x, y in mm; ux, uy, uz in µm; rx, ry, rz in µrad",
    )
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    import numpy as np

    from ..io.atomic import atomic_write_text
    from ..machine.build import table_from_spec, with_overrides
    from ._common import machine_config

    say = (lambda *a: None) if args.quiet else print
    src = machine_config(args).get("table_source")
    if src:
        raise ValueError(f"{args.config}: the table is imported from {src['given']} (source = "
                         '"superelement"): the table command solves diffguide\'s plate, which '
                         "this machine does not use")
    spec = with_overrides(machine_spec(args), nx=args.nx, ny=args.ny)
    model = table_from_spec(spec, nut=False)
    cond = model.condense()
    u = np.asarray(cond.node_u0)  # the four carriage reference points held at u = 0
    pts = np.asarray(cond.r0).reshape(-1, 6)
    mesh = model.mesh
    sag = -u[:, 2].min() * 1e6
    machine_name = args.config or args.preset
    say(
        f"table {machine_name}: {len(mesh.xs) - 1} x {len(mesh.ys) - 1} shells, "
        f"{mesh.n_nodes} nodes, {mesh.n_dof} DOF; carriages fixed, gravity "
        f"{model.gravity} m/s²"
    )
    say(f"max sag under gravity: {sag:.3f} µm")
    for name, row in zip(model.point_names, pts):
        say(
            f"  {name}: uz = {row[2] * 1e6:+.3f} µm, rx = {row[3] * 1e6:+.3f} µrad, "
            f"ry = {row[4] * 1e6:+.3f} µrad"
        )
    if args.out:
        lines = ["node,x_mm,y_mm,ux_um,uy_um,uz_um,rx_urad,ry_urad,rz_urad"]
        for k, (p, d) in enumerate(zip(mesh.nodes, u)):
            vals = [p[0] * 1e3, p[1] * 1e3, *(d * 1e6)]
            lines.append(f"{k}," + ",".join(f"{v:.6g}" for v in vals))
        atomic_write_text(args.out, "\n".join(lines) + "\n")
        say(f"wrote {args.out}")
    if args.plot:
        from ..io.atomic import atomic_savefig
        from ..plotting import figure_of
        from ..plotting.table import plot_table

        fig = figure_of(
            plot_table(
                model,
                u,
                title=f"{machine_name}: sag under gravity on four carriages, max {sag:.2f} µm",
            )
        )
        atomic_savefig(fig, args.plot, dpi=120)
        say(f"wrote {args.plot}")
    sys.stdout.flush()
    return 0
