"""Figures (matplotlib; never imported by the core). Every function takes ``ax=`` (an Axes, or
a sequence of Axes for multi-panel figures) to draw into, and returns the Axes it drew on (an
array for multi-panel figures); :func:`figure_of` gives their Figure, for saving."""

import numpy as np


def figure_of(axes):
    """The Figure of an Axes or of an array/sequence of Axes."""
    first = np.asarray(axes, dtype=object).reshape(-1)[0]
    return first.figure


def axes_grid(ax, nrows: int, ncols: int, **subplots_kw):
    """``(Figure, Axes array (nrows, ncols))``: new, or the given ``ax`` (any sequence of
    ``nrows·ncols`` Axes) reshaped."""
    import matplotlib.pyplot as plt

    if ax is None:
        fig, axes = plt.subplots(nrows, ncols, squeeze=False, **subplots_kw)
        return fig, axes
    arr = np.empty(nrows * ncols, dtype=object)
    given = list(np.asarray(ax, dtype=object).reshape(-1))
    if len(given) != nrows * ncols:
        raise ValueError(f"ax: need {nrows * ncols} Axes, got {len(given)}")
    arr[:] = given
    return given[0].figure, arr.reshape(nrows, ncols)
