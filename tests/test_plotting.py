"""Plotting functions: ``ax=`` accepted, the Axes returned, layout rules of the CLI figures."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from diffguide.plotting import figure_of  # noqa: E402
from diffguide.plotting.errors import plot_error_field, plot_joint_errors  # noqa: E402
from diffguide.plotting.fit import plot_curves, plot_profiles  # noqa: E402
from diffguide.plotting.guideway import plot_static_characteristic  # noqa: E402

S = np.linspace(-0.5, 0.5, 41)
PROFILE = (np.ones((2, 2, 41)) * 1e-6, np.full((2, 2, 41), 0.1e-6))


def _channels(n):
    x = np.linspace(-350, 350, 8)
    return [
        (f"c{i}", "µm/m", x, np.sin(x / 200), np.full(8, 0.3), np.sin(x / 200), None)
        for i in range(n)
    ]


def test_every_function_draws_into_given_axes_and_returns_them():
    fig, axes = plt.subplots(2, 3)
    got = plot_joint_errors(np.arange(4.0), np.zeros((4, 2, 6)), ["A", "B"], ax=axes)
    assert got.shape == (2, 3) and got[0, 0] is axes[0, 0] and figure_of(got) is fig
    fig, ax = plt.subplots()
    assert plot_static_characteristic({"down": (np.arange(3.0), np.arange(3.0))}, ax=ax) is ax
    fig, axes = plt.subplots(1, 3)
    xy = np.random.default_rng(0).uniform(-0.1, 0.1, (30, 2))
    assert plot_error_field(xy, np.ones((30, 6)) * xy[:, :1], ax=axes)[0, 2] is axes[2]
    fig, axes = plt.subplots(2, 1)
    assert list(plot_profiles(S, {"e": PROFILE}, ax=axes)) == list(axes)
    plt.close("all")


def test_curves_keep_x_labels_with_an_odd_channel_count():
    axes = plot_curves(_channels(5))
    labelled = [a for a in axes.ravel() if a.get_visible() and a.get_xlabel()]
    assert len(labelled) == 2  # the lowest visible panel of each column
    assert axes[1, 1].get_xlabel() and axes[1, 1].xaxis.get_tick_params()["labelbottom"]
    plt.close("all")


def test_profiles_legend_outside_and_every_fit_has_its_band():
    axes = plot_profiles(S, {"elastic": PROFILE, "rigid table": PROFILE})
    fig = figure_of(axes)
    fig.canvas.draw()
    for ax in axes:
        legend = ax.get_legend()
        box, frame = legend.get_window_extent(), ax.get_window_extent()
        assert box.x0 >= frame.x1  # right of the plotting area: covers no curve
        labels = [t.get_text() for t in legend.get_texts()]
        assert "rail 1 rigid table ±2σ" in labels and "rail 2 elastic ±2σ" in labels
    plt.close("all")


def test_bare_figures_are_not_pyplots():
    """Inside ``bare_figures()`` a new figure is a bare Figure (nothing registered with pyplot,
    nothing to close: the command line's files); outside it is pyplot's (a notebook shows it)."""
    import matplotlib.pyplot as plt

    from diffguide.plotting import bare_figures
    from diffguide.plotting.guideway import plot_static_characteristic

    curves = {"down": (np.array([0.0, 1e3]), np.array([0.0, 2.0]))}
    before = set(plt.get_fignums())
    with bare_figures():
        ax = plot_static_characteristic(curves)
    assert set(plt.get_fignums()) == before
    assert ax.figure.get_size_inches().tolist() == [6.0, 4.2]
    ax2 = plot_static_characteristic(curves)
    try:
        assert plt.fignum_exists(ax2.figure.number)
    finally:
        plt.close(ax2.figure)
