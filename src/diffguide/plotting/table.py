"""Figure of the table mesh and its deflected shape (matplotlib; never imported by the core)."""

import numpy as np
from matplotlib import cm, colors
from matplotlib.patches import Rectangle
from matplotlib.ticker import MaxNLocator

from . import new_figure


def plot_table(model, node_u, *, scale: float | None = None, title: str = "", ax=None):
    """Plan view of the mesh (footprints, ribs, control points) and the exaggerated deflection.

    Args:
        model: a :class:`diffguide.fe.TableModel`.
        node_u: node DOF (n_nodes, 6) in m / rad (e.g. ``CondensedTable.node_u0``).
        scale: deflection magnification for the 3-D view (default: max deflection → 8 % of
            the table length).
        title: figure title.
        ax: two Axes to draw into, a 2-D one (plan) and a 3-D one (``projection="3d"``);
            default: a new figure.

    Returns:
        The two Axes (plan view, colour map uz in µm; 3-D view).
    """
    mesh = model.mesh
    xs, ys = np.asarray(mesh.xs), np.asarray(mesh.ys)
    u = np.asarray(node_u).reshape(len(xs), len(ys), 6)
    uz_um = u[:, :, 2] * 1e6
    if ax is None:
        fig = new_figure(figsize=(13, 5.2))
        ax, ax3 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2, projection="3d")
    else:
        ax, ax3 = ax
        fig = ax.figure
    X, Y = np.meshgrid(xs * 1e3, ys * 1e3, indexing="ij")
    norm = colors.Normalize(vmin=uz_um.min(), vmax=max(uz_um.max(), uz_um.min() + 1e-9))
    pc = ax.pcolormesh(X, Y, uz_um, shading="gouraud", cmap="viridis", norm=norm)
    for x in xs:
        ax.plot([x * 1e3] * 2, [ys[0] * 1e3, ys[-1] * 1e3], color="0.3", lw=0.4)
    for y in ys:
        ax.plot([xs[0] * 1e3, xs[-1] * 1e3], [y * 1e3] * 2, color="0.3", lw=0.4)
    for p in model.patches:
        x0, x1, y0, y1 = (v * 1e3 for v in p.box)
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="tab:red", lw=1.5))
        ax.annotate(
            p.name, (p.x * 1e3, p.y * 1e3), color="tab:red", ha="center", va="center", fontsize=7
        )
    for a, b in np.asarray(mesh.beams):
        pa, pb = mesh.nodes[a] * 1e3, mesh.nodes[b] * 1e3
        ax.plot([pa[0], pb[0]], [pa[1], pb[1]], color="tab:orange", lw=2.5)
    for (x, y), name in zip(model.points, model.point_names):
        ax.plot(x * 1e3, y * 1e3, "k^", ms=6)
        ax.annotate(name, (x * 1e3, y * 1e3), xytext=(4, 4), textcoords="offset points", fontsize=8)
    ax.set_aspect("equal")
    ax.set_xlabel("x along the rails (mm)")
    ax.set_ylabel("y across (mm)")
    ax.set_title("mesh, footprints (red), control points; colour: uz (µm)", fontsize=10)
    fig.colorbar(pc, ax=ax, shrink=0.8, label="uz (µm)")

    L = xs[-1] - xs[0]
    umax = np.abs(u[:, :, :3]).max()
    scale = (0.08 * L / umax if umax > 0 else 1.0) if scale is None else scale
    Xd = (X / 1e3 + scale * u[:, :, 0]) * 1e3
    Yd = (Y / 1e3 + scale * u[:, :, 1]) * 1e3
    Zd = scale * u[:, :, 2] * 1e3
    ax3.plot_surface(
        Xd,
        Yd,
        Zd,
        facecolors=cm.viridis(norm(uz_um)),
        rstride=1,
        cstride=1,
        linewidth=0.2,
        edgecolor="0.2",
        shade=False,
    )
    ax3.set_xlabel("x (mm)")
    ax3.set_ylabel("y (mm)")
    ax3.zaxis.set_major_locator(MaxNLocator(3))  # a flat box: few z ticks, or they overlap
    ax3.tick_params(axis="z", pad=6, labelsize=8)
    ax3.set_zlabel(f"uz × {scale:.3g} (mm)", labelpad=10)
    ax3.set_box_aspect((np.ptp(xs), np.ptp(ys), 0.35 * np.ptp(ys)))
    ax3.set_title(f"deflected mid-surface, magnified × {scale:.3g}")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return np.array([ax, ax3], dtype=object)
