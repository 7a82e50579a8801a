"""Result codes of the equilibrium solves: one code per solve (per position in a batch).

A code is an :class:`equinox.Enumeration` item: it passes through ``jit``/``vmap`` as a small
integer array, compares only with codes of its own kind (``result == RESULTS.successful``, an
array of booleans in a batch), and ``RESULTS[result]`` is its message. The names and messages
follow optimistix's ``RESULTS``, which the solves used before, so that code written against
them reads the same.
"""

import equinox as eqx


class RESULTS(eqx.Enumeration):
    """How a solve ended: ``successful``, ``nonlinear_max_steps_reached`` (the Newton step
    limit was hit before the step fell below the tolerance), ``nonfinite`` (an iterate
    became inf or NaN) or ``stagnation`` (no step decreased the objective further: the fit's
    Levenberg–Marquardt and structure searches, :mod:`diffguide.inverse.solution`)."""

    successful = ""
    nonlinear_max_steps_reached = (
        "The maximum number of steps was reached in the nonlinear solver. The problem may not "
        "be solvable (e.g. an unloaded, unconstrained body), or you may need to increase "
        "`max_steps`."
    )
    nonfinite = "Nonfinite (inf or nan) values detected during solve."
    stagnation = (
        "No step decreased the objective further before the tolerance was met; the best "
        "estimate so far is returned."
    )
