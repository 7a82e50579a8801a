"""Figures (matplotlib; never imported by the core). Every function takes ``ax=`` (an Axes, or
a sequence of Axes for multi-panel figures) to draw into, and returns the Axes it drew on (an
array for multi-panel figures); :func:`figure_of` gives their Figure, for saving.

Without ``ax`` a function makes a new figure: pyplot's (shown in a notebook, closed with
``plt.close``), or inside :func:`bare_figures` a bare ``matplotlib.figure.Figure`` — for files:
no backend, nothing registered with pyplot, nothing to close (the command line draws so).
"""

import contextlib
import contextvars

import numpy as np

_BARE = contextvars.ContextVar("diffguide_bare_figures", default=False)
#: keyword arguments of ``plt.subplots`` that belong to the figure (the rest go to ``subplots``)
_FIGURE_KW = ("figsize", "dpi", "constrained_layout", "layout", "facecolor")


@contextlib.contextmanager
def bare_figures():
    """Inside, new figures are bare ``Figure`` objects, not pyplot's (see the module doc)."""
    token = _BARE.set(True)
    try:
        yield
    finally:
        _BARE.reset(token)


def new_figure(**figure_kw):
    """A new Figure: pyplot's, or a bare one inside :func:`bare_figures`."""
    if _BARE.get():
        from matplotlib.figure import Figure

        return Figure(**figure_kw)
    import matplotlib.pyplot as plt

    return plt.figure(**figure_kw)


def figure_of(axes):
    """The Figure of an Axes or of an array/sequence of Axes."""
    first = np.asarray(axes, dtype=object).reshape(-1)[0]
    return first.figure


def axes_grid(ax, nrows: int, ncols: int, **subplots_kw):
    """``(Figure, Axes array (nrows, ncols))``: new, or the given ``ax`` (any sequence of
    ``nrows·ncols`` Axes) reshaped."""
    if ax is None:
        fig = new_figure(**{k: v for k, v in subplots_kw.items() if k in _FIGURE_KW})
        rest = {k: v for k, v in subplots_kw.items() if k not in _FIGURE_KW}
        return fig, fig.subplots(nrows, ncols, squeeze=False, **rest)
    arr = np.empty(nrows * ncols, dtype=object)
    given = list(np.asarray(ax, dtype=object).reshape(-1))
    if len(given) != nrows * ncols:
        raise ValueError(f"ax: need {nrows * ncols} Axes, got {len(given)}")
    arr[:] = given
    return given[0].figure, arr.reshape(nrows, ncols)
