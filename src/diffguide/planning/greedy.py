"""The greedy search of a measurement plan: add placements one at a time, each the one that
lowers the criterion most given those before (rank-``r`` updates, :mod:`.design`)."""

import dataclasses
import logging
from collections.abc import Callable, Sequence

import numpy as np

from .design import (
    CRITERIA,
    Evaluation,
    check_placements,
    criterion_value,
    evaluation,
    posterior,
    trial,
    user_value,
    variances,
)
from .instruments import Placement

_log = logging.getLogger("diffguide")


@dataclasses.dataclass(frozen=True)
class Step:
    """One greedy step: the placement added and what it bought (criterion in user units)."""

    placement: Placement
    xy: tuple[float, float]
    quantities: tuple[str, ...]
    before: float
    after: float
    worst: float
    rms: float
    logdet: float


def _best_trial(planner, S, var, var_w, budget, chosen, criterion):
    """The placement whose trial gives the smallest criterion: ``(value, placement, X, log det
    K)``, or None when no placement is left."""
    best = None
    for p, R in planner.blocks.items():
        if (
            budget.get(p[0], 0) <= 0
            or p in chosen
            or R.shape[1] == 0
            or p[1] not in planner.candidates
        ):
            continue
        value, X, ldk = trial(planner, S, var, var_w, R, criterion)
        if best is None or value < best[0] - 1e-12 * abs(best[0]):
            best = (value, p, X, ldk)
    return best


def greedy(
    planner,
    budget: dict[str, int] | None = None,
    criterion: str = "worst",
    start: Sequence[Placement] = (),
    progress: Callable[[str], None] | None = None,
) -> tuple[tuple[Step, ...], Evaluation]:
    """Add placements one at a time, each the best for ``criterion`` given those before.

    Arguments:
        planner: the :class:`~.planner.Planner`.
        budget: placements per instrument kind (default each instrument's ``count``).
        criterion: one of :data:`~.design.CRITERIA`. start: placements already decided.
        progress: called with a line per step.
    Returns the steps and the final plan's :class:`~.design.Evaluation`.
    """
    if criterion not in CRITERIA:
        raise ValueError(f"criterion must be one of {CRITERIA}, got {criterion!r}")
    if criterion == "work" and planner.W_work is None:
        raise ValueError("the 'work' criterion needs a work point")
    budget = dict({i.kind: i.count for i in planner.instruments} if budget is None else budget)
    chosen = list(check_placements(planner, start))
    S, logdet = posterior(planner, chosen)  # log det Cov, per draw
    total = sum(budget.values())
    steps = []
    for k in range(total):
        var, var_w = variances(planner, S)
        before = user_value(criterion, criterion_value(criterion, var, var_w, logdet))
        best = _best_trial(planner, S, var, var_w, budget, chosen, criterion)
        if best is None:
            break
        _, p, X, ldk = best
        S = S - np.swapaxes(X, 1, 2) @ X  # Woodbury: S − U K⁻¹ Uᵀ
        S = 0.5 * (S + np.swapaxes(S, 1, 2))
        logdet = logdet - ldk
        chosen.append(p)
        budget[p[0]] -= 1
        ev = evaluation(planner, tuple(chosen), S, logdet)
        after = ev.criterion(criterion)
        xy = planner.sites[p[1]]
        quantities = planner.instrument[p[0]].quantities
        steps.append(Step(p, xy, quantities, before, after, ev.worst, ev.rms, ev.logdet))
        line = (
            f"plan: step {k + 1}/{total}: {p[0]} at {p[1]} "
            f"({xy[0] * 1e3:.0f}, {xy[1] * 1e3:.0f}) mm: "
            f"{criterion} {before:.4g} -> {after:.4g}"
        )
        _log.info(line)
        if progress is not None:
            progress(line)
    return tuple(steps), evaluation(planner, tuple(chosen), S, logdet)
