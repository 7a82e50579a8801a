"""Figures of a Monte Carlo tolerance study: error ranges and corner roll differences."""

import numpy as np

from ..machine.errors import ERROR_LABELS as _LABELS
from . import axes_grid


def plot_monte_carlo(result, title: str = "", quantile: float = 0.95, *, ax=None):
    """Distributions over the samples (converged samples only).

    Six panels: the range of each joint error at each control point (box: 25–75 %, whiskers:
    5–95 %, dot: median); one panel of histograms of the roll difference between corner pairs;
    one of the empirical distribution of the largest corner roll difference with its
    ``quantile`` marked.

    Arguments:
        result: a :class:`diffguide.studies.montecarlo.MonteCarloResult`.
        title: figure title. quantile: marked on the last panel (0.95). ax: eight Axes to draw
            into (default: a new 2 × 4 figure).
    Returns:
        the (2, 4) array of Axes.
    """
    ok = np.asarray(result.converged, dtype=bool)
    ranges = result.ranges[ok] * 1e6
    rd = result.roll_difference[ok] * 1e6
    names = result.point_names
    fig, axes = axes_grid(ax, 2, 4, figsize=(16, 7), constrained_layout=True)
    flat = list(axes.flat)
    for k, ax in enumerate(flat[:6]):
        name, unit, what = _LABELS[k]
        data = [ranges[:, j, k] for j in range(len(names))]
        if ranges.shape[0]:
            ax.boxplot(data, whis=(5, 95), showfliers=False, medianprops={"color": "C1"})
            ax.set_xticks(range(1, len(names) + 1), names)
        ax.set_title(f"{name} range: {what}", fontsize=10)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3, axis="y")
    ax = flat[6]
    if rd.shape[1] and rd.shape[0]:
        bins = np.linspace(0.0, max(np.percentile(rd, 99.5), 1e-9), 40)
        for q, (a, b) in enumerate(result.pairs):
            ax.hist(rd[:, q], bins=bins, histtype="step", lw=1.3, label=f"{a}–{b}")
        ax.legend(fontsize=7, ncol=2)
    ax.set_title("roll difference between corners, max over x", fontsize=10)
    ax.set_xlabel("µrad")
    ax.set_ylabel("samples")
    ax.grid(alpha=0.3)
    ax = flat[7]
    if rd.shape[1] and rd.shape[0]:
        worst = np.sort(rd.max(axis=1))
        p = np.arange(1, worst.size + 1) / worst.size
        ax.plot(worst, p, lw=1.6)
        qv = np.quantile(worst, quantile)
        ax.axhline(quantile, color="0.5", lw=0.8, ls="--")
        ax.axvline(qv, color="C3", lw=1.0, ls="--", label=f"{quantile:.0%}: {qv:.3g} µrad")
        ax.legend(fontsize=8, loc="lower right")
    ax.set_title("largest corner roll difference", fontsize=10)
    ax.set_xlabel("µrad")
    ax.set_ylabel("fraction of samples ≤")
    ax.grid(alpha=0.3)
    n_bad = int((~ok).sum())
    sub = f"{ok.sum()} samples" + (f" ({n_bad} not converged, left out)" if n_bad else "")
    fig.suptitle(f"{title}\n{sub}" if title else sub)
    return axes
