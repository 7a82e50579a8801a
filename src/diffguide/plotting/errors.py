"""Figures of joint kinematic errors against table position (the paper's Figs. 7–9)."""

import matplotlib
import numpy as np

from ..machine.errors import ERROR_LABELS
from . import axes_grid


def plot_joint_errors(positions_mm, errors_user, point_names, title="", compare=None, *, ax=None):
    """Six panels (EXX … ECX) against position, one line per control point.

    Arguments:
        positions_mm: (n_pos,) table positions (mm).
        errors_user: (n_pos, n_points, 6) errors in µm / µrad.
        point_names: names of the points.
        compare: optional second set of errors (same shape), drawn dashed (e.g. rigid table).
        ax: six Axes to draw into (default: a new 2 × 3 figure).
    Returns:
        the (2, 3) array of Axes.
    """
    fig, axes = axes_grid(ax, 2, 3, figsize=(13, 6.5), sharex=True, constrained_layout=True)
    colors = matplotlib.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, ax in enumerate(axes.flat):
        name, unit, what = ERROR_LABELS[k]
        for j, pname in enumerate(point_names):
            c = colors[j % len(colors)]
            ax.plot(positions_mm, errors_user[:, j, k], color=c, lw=1.6, label=pname)
            if compare is not None:
                ax.plot(positions_mm, compare[:, j, k], color=c, lw=1.0, ls="--")
        ax.set_title(f"{name}: {what}", fontsize=10)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        if k >= 3:
            ax.set_xlabel("table position x (mm)")
    axes.flat[0].legend(fontsize=8, ncol=2)
    if compare is not None:
        axes.flat[1].plot([], [], "k-", label="elastic table")
        axes.flat[1].plot([], [], "k--", label="rigid table")
        axes.flat[1].legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return axes


def error_ranges(errors_user) -> np.ndarray:
    """Peak-to-peak range of each error at each point, (n_points, 6)."""
    return np.ptp(errors_user, axis=0)


def plot_error_field(xy, field_user, title="", components=(2, 3, 4), *, ax=None):
    """Maps of error components over the table top (µm / µrad), one panel each.

    Arguments:
        xy: (n_nodes, 2) node positions (m). field_user: (n_nodes, 6) errors in µm / µrad
            (:func:`diffguide.machine.kinematics.error_field` scaled). components: indices into
            EXX … ECX (default EZX, roll, pitch). ax: one Axes per component (default: a
            new figure).
    Returns:
        the (1, n) array of Axes.
    """
    xy = np.asarray(xy) * 1e3
    fig, axes = axes_grid(
        ax, 1, len(components), figsize=(4.6 * len(components), 3.2), constrained_layout=True
    )
    for ax, k in zip(axes[0], components):
        name, unit, what = ERROR_LABELS[k]
        tc = ax.tricontourf(xy[:, 0], xy[:, 1], field_user[:, k], levels=16, cmap="RdBu_r")
        fig.colorbar(tc, ax=ax, label=unit)
        ax.set_title(f"{name} ({what})", fontsize=10)
        ax.set_xlabel("x on the table (mm)")
        ax.set_aspect("equal")
    axes[0, 0].set_ylabel("y (mm)")
    if title:
        fig.suptitle(title)
    return axes


def plot_error_map(xy, shape, errors_user, sigma_user, title="", *, ax=None):
    """The six errors (top row) and their σ (bottom row) over a grid on the table top at one
    position, µm / µrad.

    Arguments:
        xy: ``(NX·NY, 2)`` grid points (m), x-major (:func:`diffguide.inverse.error_map
            .grid_points`). shape: ``(NX, NY)``. errors_user, sigma_user: ``(NX·NY, 6)`` in µm
            and µrad. title: figure title. ax: twelve Axes (default: a new figure).
    Returns:
        the (2, 6) array of Axes.
    """
    nx, ny = shape
    X, Y = (np.asarray(xy)[:, k].reshape(nx, ny) * 1e3 for k in (0, 1))
    fig, axes = axes_grid(ax, 2, 6, figsize=(24, 5.4), constrained_layout=True)
    for row, values, cmap in ((0, errors_user, "RdBu_r"), (1, sigma_user, "viridis")):
        for k, ax_ in enumerate(axes[row]):
            name, unit, what = ERROR_LABELS[k]
            pc = ax_.pcolormesh(X, Y, np.asarray(values)[:, k].reshape(nx, ny),
                                shading="gouraud", cmap=cmap)
            fig.colorbar(pc, ax=ax_, label=unit, shrink=0.8)
            ax_.set_title(f"{'σ ' if row else ''}{name} ({what})", fontsize=9)
            ax_.set_aspect("equal")
            ax_.set_xlabel("x (mm)")
        axes[row, 0].set_ylabel("y (mm)")
    if title:
        fig.suptitle(title)
    return axes
