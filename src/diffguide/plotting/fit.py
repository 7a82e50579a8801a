"""Figures of a rail fit: profiles with ±2σ bands, measured vs fitted curves (matplotlib; never
imported by the core)."""

import numpy as np

from . import axes_grid

_PLANES = ("vertical", "horizontal")


def plot_profiles(s_m, profiles, *, truth=None, title: str = "", ax=None):
    """Rail profiles with ±2σ bands: one panel per plane, both rails.

    Args:
        s_m: rail coordinate (m), shape ``(n,)``.
        profiles: ``{label: (values, sigma)}``, each ``(2 rails, 2 planes, n)`` in m (e.g.
            ``{"elastic": fit.profiles(s), "rigid table": rigid.profiles(s)}``); every entry
            gets its ±2σ bands (the first filled, the others hatched outlines).
        truth: optional ``(2, 2, n)`` (m), gauge-fixed, drawn dashed.
        title: figure title. ax: two Axes (vertical, horizontal) to draw into (default: a new
            figure).
    Returns:
        the (2,) array of Axes.
    """
    s_mm = np.asarray(s_m) * 1e3
    fig, axes = axes_grid(ax, 2, 1, figsize=(12, 7), sharex=True, constrained_layout=True)
    axes = axes[:, 0]
    colours = ("tab:blue", "tab:red")
    styles = ("-", ":", "-.")
    for p, ax in enumerate(axes):
        for j, (label, (val, sig)) in enumerate(profiles.items()):
            for r in range(2):
                v = np.asarray(val)[r, p] * 1e6
                ax.plot(
                    s_mm,
                    v,
                    styles[j % 3],
                    color=colours[r],
                    lw=1.6 if j == 0 else 1.0,
                    label=f"rail {r + 1} {label}",
                )
                sg = np.asarray(sig)[r, p] * 1e6
                if j == 0:
                    ax.fill_between(
                        s_mm,
                        v - 2 * sg,
                        v + 2 * sg,
                        color=colours[r],
                        alpha=0.2,
                        lw=0,
                        label=f"rail {r + 1} {label} ±2σ",
                    )
                else:  # outlined, so that the first fit's band stays readable beneath
                    ax.fill_between(
                        s_mm,
                        v - 2 * sg,
                        v + 2 * sg,
                        facecolor="none",
                        edgecolor=colours[r],
                        hatch="///",
                        alpha=0.35,
                        lw=0.6,
                        label=f"rail {r + 1} {label} ±2σ",
                    )
        if truth is not None:
            for r in range(2):
                ax.plot(
                    s_mm,
                    np.asarray(truth)[r, p] * 1e6,
                    "--",
                    color="k",
                    lw=0.9,
                    label="truth" if r == 0 else None,
                )
        ax.set_ylabel(f"{_PLANES[p]} deviation (µm)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    axes[-1].set_xlabel("rail coordinate s (mm)")
    fig.suptitle(title or "rail straightness profiles (gauge: zero mean, zero common slope)")
    return axes


def plot_curves(channels, *, title: str = "", ax=None):
    """Measured (with ±σ) and fitted error curves, one panel per channel.

    Args:
        channels: list of ``(label, unit, position_mm, measured, sigma, fitted, fitted_rigid)``
            (values in ``unit``; ``fitted_rigid`` may be None).
        title: figure title. ax: ``rows × cols`` Axes (2 columns) to draw into (default: a new
            figure).
    Returns:
        the (rows, cols) array of Axes.
    """
    n = len(channels)
    cols = min(n, 2)
    rows = (n + cols - 1) // cols
    fig, axes = axes_grid(ax, rows, cols, figsize=(6 * cols, 2.6 * rows), sharex=True)
    for ax, (label, unit, x, y, sig, fit, rigid) in zip(axes.ravel(), channels):
        order = np.argsort(x)
        x, y, sig, fit = (np.asarray(a)[order] for a in (x, y, sig, fit))
        ax.errorbar(x, y, yerr=sig, fmt=".", ms=3, color="0.3", lw=0.8, label="measured")
        ax.plot(x, fit, "-", color="tab:blue", label="fitted (elastic)")
        if rigid is not None:
            ax.plot(x, np.asarray(rigid)[order], ":", color="tab:red", label="fitted (rigid table)")
        ax.set_title(label, fontsize=9, y=1.0)  # a fixed position: no layout pass
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
    for a in axes.ravel()[n:]:
        a.set_visible(False)
    for col in range(cols):  # the lowest visible panel of each column carries the x labels
        shown = [r for r in range(rows) if r * cols + col < n]
        if shown:
            low = axes[shown[-1], col]
            low.set_xlabel("table position x (mm)")
            low.tick_params(labelbottom=True)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(title or "measured vs fitted joint errors")
    if ax is None:  # given Axes: the caller owns the layout (tight_layout costs ~1 s here)
        fig.tight_layout()
    return axes


def profiles_figure(s_m, profiles, *, truth=None, title: str = ""):
    """:func:`plot_profiles` on a new bare ``Figure`` (no pyplot: nothing to close; for files)
    with fixed margins (a layout engine costs a second or so per figure)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 7))
    ax = fig.subplots(2, 1, sharex=True)
    fig.subplots_adjust(left=0.06, right=0.845, top=0.93, bottom=0.075, hspace=0.07)
    plot_profiles(s_m, profiles, truth=truth, title=title, ax=ax)
    return fig


def curves_figure(channels, *, title: str = ""):
    """:func:`plot_curves` on a new bare ``Figure`` with fixed margins (in inches: the panels
    keep their size whatever the number of channels)."""
    from matplotlib.figure import Figure

    cols = min(len(channels), 2)
    rows = (len(channels) + cols - 1) // cols
    height = 2.6 * rows
    fig = Figure(figsize=(6 * cols, height))
    ax = fig.subplots(rows, cols, squeeze=False, sharex=True)
    fig.subplots_adjust(
        left=0.06 * 2 / cols,
        right=1 - 0.015 * 2 / cols,
        top=1 - 0.75 / height,
        bottom=0.45 / height,
        hspace=0.2,
        wspace=0.15,
    )
    plot_curves(channels, title=title, ax=ax)
    return fig
