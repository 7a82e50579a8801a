"""Figures for one carriage: the static characteristic (Majda 2012, Fig. 3)."""

from . import new_figure


def plot_static_characteristic(curves: dict, title: str = "", *, ax=None):
    """Deflection (µm) against load (kN), one line per direction.

    Arguments:
        curves: ``{direction: (loads_N, deflections_um)}``. ax: Axes to draw into (default: a
            new figure).
    Returns:
        the Axes.
    """
    if ax is None:
        ax = new_figure(figsize=(6, 4.2), constrained_layout=True).subplots()
    styles = {"down": "-", "up": "--", "lateral": ":"}
    for name, (loads, defl) in curves.items():
        ax.plot(loads / 1e3, defl, styles.get(name, "-"), lw=2, label=name)
    ax.set_xlabel("load (kN)")
    ax.set_ylabel("deflection along the load (µm)")
    ax.grid(alpha=0.3)
    ax.legend(title="load direction")
    if title:
        ax.set_title(title)
    return ax
