"""A battery of hidden-style identification cases (issue 11, part 4).

Each case's data are made by a *different* model than the fit uses — the ``majda2012`` table on a
finer mesh (40 × 20 instead of 20 × 10), for the wrong-structure cases another plate thickness or
preload — from rail shapes that are not splines (sinusoids, polynomials, a rail-joint step,
content at the blind wavelengths), written as a long-format measurement CSV text and read back
through :func:`diffguide.io.measurements.parse_readings` and
:func:`~diffguide.io.measurements.merge_readings`, so the whole input path is exercised.

:mod:`.cases` defines the cases, simulates their readings and fits them (:func:`.cases.run_fit`,
the one place that calls the fit); :mod:`.score` compares a fit with its truth.
"""
