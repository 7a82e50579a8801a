"""Figures of ``report.html`` (matplotlib, bare ``Figure`` objects with fixed margins; never
imported by the core): each rail's deviations from its straightness reference line with the
straightness and its interval, and the fit's residuals per channel."""

import numpy as np

from . import axes_grid

_PLANES = ("vertical", "horizontal")
_COLOURS = ("tab:blue", "tab:red")


def _rail_title(row: dict) -> str:
    side = f", {row['side']} side (y = {row['y_mm']:g} mm)" if row.get("side") else ""
    return f"rail {row['rail']}{side}: {row['plane']}"


def plot_straightness(s_mm, dev_um, sig_um, rows, *, reference: str = "least-squares",
                      ax=None):
    """Per rail (columns) and plane (rows) the fitted profile's deviations from its
    ``reference`` line (µm) over ``s_mm`` (mm) with their ±2σ posterior band, the peak and the
    valley marked, and the straightness, its 95 % interval and the verdict of ``rows``
    (report.json's ``straightness.rails``) in the title. ``dev_um``, ``sig_um``:
    ``(2, 2, len(s))`` (µm). ``ax``: 2 × 2 Axes to draw into (default: a new figure). Returns
    the (2, 2) Axes."""
    fig, axes = axes_grid(ax, 2, 2, figsize=(12, 6.4), sharex=True)
    s = np.asarray(s_mm, float)
    for row in rows:
        r, p = row["rail"] - 1, _PLANES.index(row["plane"])
        ax = axes[p, r]
        d, sg = np.asarray(dev_um)[r, p], np.asarray(sig_um)[r, p]
        ax.fill_between(s, d - 2 * sg, d + 2 * sg, color=_COLOURS[r], alpha=0.2, lw=0,
                        label="±2σ (k = 2) posterior band")
        ax.plot(s, d, color=_COLOURS[r], lw=1.5, label="deviation from the reference line")
        ax.axhline(0.0, color="0.4", lw=0.8, ls="--", label=f"{reference} reference line")
        for i, mark in ((int(np.argmax(d)), "^"), (int(np.argmin(d)), "v")):
            ax.plot(s[i], d[i], mark, color="k", ms=6)
        verdict = f", {row['verdict']}" if row.get("verdict") else ""
        lo, hi = row["interval_95_um"]
        ax.set_title(f"{_rail_title(row)}\nstraightness {row['straightness_um']:.3g} µm "
                     f"(95 %: {lo:.3g} … {hi:.3g} µm){verdict}", fontsize=9)
        ax.set_ylabel("deviation (µm)")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("rail coordinate s (mm)")
    axes[0, 0].legend(fontsize=7, loc="best")
    fig.suptitle(f"rail straightness (ISO 230-1, {reference} reference line; ▲ peak, ▼ valley;"
                 " band ±2σ of the fit's posterior)", fontsize=10)
    return axes


def straightness_figure(s_mm, dev_um, sig_um, rows, *, reference: str = "least-squares"):
    """:func:`plot_straightness` on a new bare ``Figure`` with fixed margins (for files)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 6.4))
    axes = fig.subplots(2, 2, sharex=True)
    fig.subplots_adjust(left=0.07, right=0.99, top=0.86, bottom=0.09, hspace=0.32, wspace=0.18)
    plot_straightness(s_mm, dev_um, sig_um, rows, reference=reference, ax=axes)
    return fig


def _grid(n: int) -> tuple[int, int]:
    cols = min(max(n, 1), 2)
    return (max(n, 1) + cols - 1) // cols, cols


def plot_residuals(channels, *, ax=None):
    """The fit's residuals (measured − fitted) per channel against the table position, with
    ±1σ error bars (the standard uncertainty of each merged value, as the fit weighs it).

    ``channels``: list of ``(label, unit, position_mm, residual, sigma)`` (residual and σ in
    ``unit``; the label as given, e.g. ``"EBX (pitch) at P1 (level)"``:
    :func:`diffguide.io.report_html.named`). ``ax``: rows × 2 Axes (one column for a single
    channel) to draw into (default: a new figure). Returns the (rows, cols) Axes."""
    rows, cols = _grid(len(channels))
    fig, grid = axes_grid(ax, rows, cols, figsize=(6 * cols, 2.2 * rows + 0.9), sharex=True)
    axes = grid.ravel()
    for ax, (label, unit, x, res, sig) in zip(axes, channels):
        order = np.argsort(x)
        x, res, sig = (np.asarray(a, float)[order] for a in (x, res, sig))
        ax.errorbar(x, res, yerr=sig, fmt=".", ms=3, color="0.25", lw=0.8)
        ax.axhline(0.0, color="tab:blue", lw=0.8)
        ax.set_title(label, fontsize=9)
        ax.set_ylabel(f"residual ({unit})")
        ax.grid(alpha=0.3)
    for ax in axes[len(channels):]:
        ax.set_visible(False)
    for ax in axes[max(len(channels) - cols, 0):len(channels)]:
        ax.set_xlabel("table position x (mm)")
        ax.tick_params(labelbottom=True)
    fig.suptitle("residuals, measured − fitted (error bars: ±1σ, the standard uncertainty of "
                 "each merged value)", fontsize=10)
    return grid


def residuals_figure(channels):
    """:func:`plot_residuals` on a new bare ``Figure`` with fixed margins (in inches: the
    panels keep their size whatever the number of channels)."""
    from matplotlib.figure import Figure

    rows, cols = _grid(len(channels))
    height = 2.2 * rows + 0.9
    fig = Figure(figsize=(6 * cols, height))
    axes = fig.subplots(rows, cols, squeeze=False, sharex=True)
    fig.subplots_adjust(left=0.08 * 2 / cols, right=1 - 0.015 * 2 / cols, top=1 - 0.7 / height,
                        bottom=0.5 / height, hspace=0.35, wspace=0.18)
    plot_residuals(channels, ax=axes)
    return fig


def measured_fitted_figure(channels):
    """Measured (±1σ) and fitted joint errors per channel
    (:func:`diffguide.plotting.fit.curves_figure`; ``channels`` as there, labels as given)."""
    from .fit import curves_figure

    return curves_figure(channels, title="measured (error bars ±1σ) and fitted joint errors")
