"""What a solve of the fit returns: the estimate, how the solve ended, and the solver's last
state — the shape of optimistix's ``Solution``, for the host-side solvers of :mod:`.lm` and
:mod:`.trust_region`.

``result`` is a :class:`~diffguide._core.result.RESULTS` code (``successful``,
``nonlinear_max_steps_reached``, ``stagnation``, ``nonfinite``); ``message`` says the same in
words, with the numbers of this solve (the fit's report quotes it).
"""

from typing import Any

import equinox as eqx
import numpy as np

from .._core.result import RESULTS


class Solution(eqx.Module):
    """The outcome of a solve.

    Attributes:
        value: the estimate (the best point found, also when the solve did not converge).
        result: how it ended (:class:`~diffguide._core.result.RESULTS`).
        state: the solver's state at ``value`` (its own module: :class:`.lm.LMState`,
            :class:`.trust_region.TrustRegionState`).
        stats: counts of the solve (a dict; which keys, the solver's docstring says).
        steps: the steps (iterations) taken.
        message: ``"converged"`` or what stopped the solve, in words.
    """

    value: np.ndarray
    result: RESULTS
    state: Any
    stats: dict
    steps: int = eqx.field(static=True)
    message: str = eqx.field(static=True)

    @property
    def converged(self) -> bool:
        """Whether the solve met its tolerance (``result`` is ``RESULTS.successful``)."""
        return self.ended(RESULTS.successful)

    def ended(self, code: RESULTS) -> bool:
        """Whether ``result`` is ``code``, as a Python bool: compared on the host by its
        message (``result == code`` is a JAX array, and a small compilation the first time)."""
        return RESULTS[self.result] == RESULTS[code]


def finish(value, result: RESULTS, state, steps: int, message: str, stats: dict | None = None,
           *, throw: bool = False) -> Solution:
    """The :class:`Solution`; with ``throw``, ``RuntimeError(message)`` unless successful."""
    if throw and RESULTS[result] != RESULTS[RESULTS.successful]:
        raise RuntimeError(message)
    return Solution(value, result, state, {} if stats is None else stats, int(steps), message)
