"""The convergence figure of a design study (:func:`diffguide.studies.design.design`)."""

import numpy as np

from . import axes_grid


def plot_design_convergence(result, title: str = "", *, ax=None):
    """Two panels over the evaluations: the objective (user unit) with its 95 % sampling
    interval on the optimisation samples; each variable's place within its bounds (0 = lower,
    1 = upper bound).

    Arguments:
        result: a :class:`~diffguide.studies.design.DesignResult`. title: figure title.
        ax: two Axes to draw into (default: a new 1 × 2 figure).
    Returns:
        the (1, 2) array of Axes.
    """
    from matplotlib.ticker import MaxNLocator

    fig, axes = axes_grid(ax, 1, 2, figsize=(11, 4), constrained_layout=True)
    h = result.history
    k = np.arange(1, len(h) + 1)
    f = np.array([r["objective"] for r in h]) * 1e6
    lo, hi = (np.array([r["interval"][i] for r in h]) * 1e6 for i in (0, 1))
    a = axes[0, 0]
    a.fill_between(k, lo, hi, color="C0", alpha=0.2, label="95 % interval (samples)")
    a.plot(k, f, "o-", color="C0", label=result.objective.text())
    a.set_xlabel("evaluation")
    a.set_ylabel(result.unit)
    a.set_title("objective", fontsize=10)
    a.legend(fontsize=8)
    a.grid(alpha=0.3)
    a = axes[0, 1]
    for j, (name, unit, s) in enumerate(zip(result.variables, result.units, result.scales)):
        b0, b1 = result.bounds[j]
        u = (np.array([r["x"][j] for r in h]) - b0) / (b1 - b0)
        a.plot(k, u, "o-", label=f"{name} ({b0 / s:.4g} .. {b1 / s:.4g} {unit})")
    a.set_ylim(-0.05, 1.05)
    a.set_xlabel("evaluation")
    a.set_ylabel("place within bounds")
    a.set_title("variables", fontsize=10)
    a.legend(fontsize=8)
    a.grid(alpha=0.3)
    for a in axes.flat:
        a.xaxis.set_major_locator(MaxNLocator(integer=True))
    if title:
        fig.suptitle(title, fontsize=10)
    return axes
