"""Figures of a measurement plan: the table top with the candidate and chosen sites, and the
predicted profile σ along the rails (matplotlib; never imported by the core)."""

import numpy as np

from . import axes_grid

_MARKERS = {
    "level": ("^", "tab:blue"),
    "interferometer": ("s", "tab:red"),
    "straightness": ("D", "tab:green"),
}
_PLANES = ("vertical", "horizontal")


def plot_plan_sites(
    sites,
    candidates,
    placements,
    *,
    compare=(),
    table_mm=None,
    rails_y_mm=None,
    carriages_x_mm=None,
    title: str = "",
    ax=None,
):
    """The table top seen from above: candidate sites, the plan's placements numbered in the
    order they were chosen, and a user's plan.

    Args:
        sites: ``{name: (x, y)}`` (m). candidates: names of the candidate sites.
        placements: the plan, ``(kind, site)`` in order of choice.
        compare: a user's plan, ``(kind, site)``, drawn as open markers.
        table_mm: ``(length, width)`` (mm) of the table outline (optional).
        rails_y_mm: Y of the rails (mm), drawn dashed (optional). carriages_x_mm: X of the
            carriages (mm), drawn on the rails (optional).
        ax: an Axes (default: a new figure).
    Returns:
        the Axes.
    """
    fig, axes = axes_grid(ax, 1, 1, figsize=(9, 5.4), constrained_layout=True)
    ax = axes[0, 0]
    if table_mm is not None:
        L, W = table_mm
        ax.add_patch(
            __import__("matplotlib.patches", fromlist=["Rectangle"]).Rectangle(
                (-L / 2, -W / 2), L, W, facecolor="0.96", edgecolor="0.3", lw=1.2, zorder=0
            )
        )
        ax.set_xlim(-L / 2 - 0.06 * L, L / 2 + 0.06 * L)
        ax.set_ylim(-W / 2 - 0.16 * W, W / 2 + 0.16 * W)
    if rails_y_mm is not None:
        for r, y in enumerate(rails_y_mm):
            ax.axhline(y, color="0.55", ls="--", lw=1.0, zorder=1)
            ax.annotate(
                f"rail {r + 1}",
                (ax.get_xlim()[0], y),
                xytext=(4, 3),
                textcoords="offset points",
                color="0.4",
                fontsize=9,
            )
            if carriages_x_mm is not None:
                for x in carriages_x_mm:
                    ax.plot(
                        [x - 35, x + 35],
                        [y, y],
                        color="0.45",
                        lw=5,
                        alpha=0.5,
                        solid_capstyle="butt",
                        zorder=1,
                    )
    xy = np.array([sites[n] for n in candidates]) * 1e3
    ax.plot(xy[:, 0], xy[:, 1], "o", ms=4, color="0.6", zorder=2, label="candidate site")
    seen = set()
    for kind, site in compare:
        m, c = _MARKERS[kind]
        x, y = np.asarray(sites[site]) * 1e3
        label = f"your plan: {kind}" if ("cmp", kind) not in seen else None
        seen.add(("cmp", kind))
        ax.plot(x, y, m, ms=17, mfc="none", mec="k", mew=1.4, zorder=3, label=label)
    count: dict = {}
    for k, (kind, site) in enumerate(placements):
        m, c = _MARKERS[kind]
        x, y = np.asarray(sites[site]) * 1e3
        n = count.get(site, 0)
        count[site] = n + 1
        dx = 9.0 * n  # a second instrument on one site: shifted so that both show
        label = f"plan: {kind}" if ("plan", kind) not in seen else None
        seen.add(("plan", kind))
        ax.plot(x + dx, y + dx, m, ms=11, color=c, mec="k", mew=0.6, zorder=4, label=label)
        ax.annotate(
            str(k + 1),
            (x + dx, y + dx),
            xytext=(7, 6),
            textcoords="offset points",
            fontsize=10,
            fontweight="bold",
            color=c,
            zorder=5,
        )
    ax.set_aspect("equal")
    ax.set_xlabel("x on the table (mm, along the rails)")
    ax.set_ylabel("y (mm)")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9, frameon=False)
    ax.set_title(title or "measurement plan (numbers: order of choice)")
    return ax


def plot_plan_sigma(s_m, sigmas, *, background=(), title: str = "", ax=None):
    """Predicted posterior σ of the gauge-fixed rail profiles along the rails, one panel per
    (plane, rail), one line per plan.

    Args:
        s_m: rail coordinate (m). sigmas: ``{label: sigma}``, each ``(2 rails, 2 planes, n)``
            (m). background: labels drawn thin and grey and left out of the y-scale (e.g. the
            prior alone, which would flatten the others). ax: four Axes (default: a new figure).
    Returns:
        the (2, 2) array of Axes (rows: vertical, horizontal; columns: rail 1, rail 2).
    """
    s_mm = np.asarray(s_m) * 1e3
    fig, axes = axes_grid(
        ax, 2, 2, figsize=(11, 6.5), sharex=True, sharey="row", constrained_layout=True
    )
    styles = ("-", "--", "-.", ":")
    colours = ("tab:blue", "k", "tab:orange", "tab:green")
    for p in range(2):
        top = 0.0
        for r in range(2):
            a = axes[p, r]
            j = 0
            for label, sig in sigmas.items():
                v = np.asarray(sig)[r, p] * 1e6
                text = f"{label} (max {v.max():.2f} µm)"
                if label in background:
                    a.plot(s_mm, v, ":", color="0.55", lw=1.2, label=text)
                    continue
                a.plot(s_mm, v, styles[j % 4], color=colours[j % 4], lw=1.6, label=text)
                top = max(top, float(v.max()))
                j += 1
            a.set_title(f"rail {r + 1}, {_PLANES[p]}", fontsize=10)
            a.grid(alpha=0.3)
            a.legend(fontsize=8, loc="upper center")
            if r == 0:
                a.set_ylabel("profile σ (µm)")
            if p == 1:
                a.set_xlabel("s along the rail (mm)")
        axes[p, 0].set_ylim(0, 1.45 * top if top > 0 else None)
    if title:
        fig.suptitle(title)
    return axes
