"""Figures of a rail fit: profiles with ±2σ bands, measured vs fitted curves (matplotlib; never
imported by the core)."""

import matplotlib.pyplot as plt
import numpy as np  # noqa: E402

_PLANES = ("vertical", "horizontal")


def plot_profiles(s_m, profiles, *, truth=None, title: str = ""):
    """Rail profiles with ±2σ bands: one panel per plane, both rails.

    Args:
        s_m: rail coordinate (m), shape ``(n,)``.
        profiles: ``{label: (values, sigma)}``, each ``(2 rails, 2 planes, n)`` in m (e.g.
            ``{"elastic": fit.profiles(s), "rigid table": rigid.profiles(s)}``); the first entry
            gets the σ bands.
        truth: optional ``(2, 2, n)`` (m), gauge-fixed, drawn dashed.
        title: figure title.
    """
    s_mm = np.asarray(s_m) * 1e3
    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    colours = ("tab:blue", "tab:red")
    styles = ("-", ":", "-.")
    for p, ax in enumerate(axes):
        for j, (label, (val, sig)) in enumerate(profiles.items()):
            for r in range(2):
                v = np.asarray(val)[r, p] * 1e6
                ax.plot(s_mm, v, styles[j % 3], color=colours[r], lw=1.6 if j == 0 else 1.0,
                        label=f"rail {r + 1} {label}")
                if j == 0:
                    sg = np.asarray(sig)[r, p] * 1e6
                    ax.fill_between(s_mm, v - 2 * sg, v + 2 * sg, color=colours[r], alpha=0.2,
                                    lw=0, label=f"rail {r + 1} ±2σ")
        if truth is not None:
            for r in range(2):
                ax.plot(s_mm, np.asarray(truth)[r, p] * 1e6, "--", color="k", lw=0.9,
                        label="truth" if r == 0 else None)
        ax.set_ylabel(f"{_PLANES[p]} deviation (µm)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=3)
    axes[-1].set_xlabel("rail coordinate s (mm)")
    fig.suptitle(title or "rail straightness profiles (gauge: zero mean, zero common slope)")
    fig.tight_layout()
    return fig


def plot_curves(channels, *, title: str = ""):
    """Measured (with ±σ) and fitted error curves, one panel per channel.

    Args:
        channels: list of ``(label, unit, position_mm, measured, sigma, fitted, fitted_rigid)``
            (values in ``unit``; ``fitted_rigid`` may be None).
    """
    n = len(channels)
    cols = min(n, 2)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(6 * cols, 2.6 * rows), squeeze=False,
                             sharex=True)
    for ax, (label, unit, x, y, sig, fit, rigid) in zip(axes.ravel(), channels):
        order = np.argsort(x)
        x, y, sig, fit = (np.asarray(a)[order] for a in (x, y, sig, fit))
        ax.errorbar(x, y, yerr=sig, fmt=".", ms=3, color="0.3", lw=0.8, label="measured")
        ax.plot(x, fit, "-", color="tab:blue", label="fitted (elastic)")
        if rigid is not None:
            ax.plot(x, np.asarray(rigid)[order], ":", color="tab:red", label="fitted (rigid table)")
        ax.set_title(label, fontsize=9)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("table position x (mm)")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(title or "measured vs fitted joint errors")
    fig.tight_layout()
    return fig
