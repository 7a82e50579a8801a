r"""ISO 230-2:2014 positioning figures of a bidirectional test (targets × runs × directions).

For target positions :math:`P_i` (i = 1..m), runs j = 1..n and the two approach directions ↑
(forward, +X) and ↓ (backward), with the deviations :math:`x_{ij}↑`, :math:`x_{ij}↓` (ISO 230-2
clause 3 notation; its Annex gives the same arithmetic for a worked example):

- mean unidirectional positional deviation :math:`\bar x_i↑ = \frac1n \sum_j x_{ij}↑` (↓ alike);
- mean bidirectional positional deviation :math:`\bar x_i = (\bar x_i↑ + \bar x_i↓)/2`;
- reversal value :math:`B_i = \bar x_i↑ - \bar x_i↓`; of the axis :math:`B = \max_i |B_i|`;
  mean reversal value :math:`\bar B = \frac1m \sum_i B_i`;
- estimator of the unidirectional standard uncertainty of positioning
  :math:`s_i↑ = \sqrt{\frac{1}{n-1}\sum_j (x_{ij}↑ - \bar x_i↑)^2}` (↓ alike);
- unidirectional repeatability :math:`R_i↑ = 4 s_i↑` (an expanded uncertainty with coverage
  factor k = 2: 2 × 2s), :math:`R_i↓ = 4 s_i↓`; bidirectional
  :math:`R_i = \max(2s_i↑ + 2s_i↓ + |B_i|,\ R_i↑,\ R_i↓)`; of the axis
  :math:`R↑ = \max_i R_i↑`, :math:`R↓ = \max_i R_i↓`, :math:`R = \max_i R_i`;
- unidirectional systematic positional deviation
  :math:`E↑ = \max_i \bar x_i↑ - \min_i \bar x_i↑` (↓ alike); bidirectional
  :math:`E = \max_i(\bar x_i↑, \bar x_i↓) - \min_i(\bar x_i↑, \bar x_i↓)`;
- range of the mean bidirectional positional deviation
  :math:`M = \max_i \bar x_i - \min_i \bar x_i`;
- unidirectional accuracy :math:`A↑ = \max_i(\bar x_i↑ + 2s_i↑) - \min_i(\bar x_i↑ - 2s_i↑)`
  (↓ alike); bidirectional
  :math:`A = \max_i(\bar x_i↑ + 2s_i↑,\ \bar x_i↓ + 2s_i↓)
  - \min_i(\bar x_i↑ - 2s_i↑,\ \bar x_i↓ - 2s_i↓)`.

The standard defines them for positioning (EXX); :func:`channel_figures` applies the same
arithmetic to every measured channel with at least two runs in each direction at every target
(straightness and angular channels: the same statistics, labelled with the channel's quantity).
The readings a channel's figures use are those the merge used (gross outliers set aside).
"""

from collections import defaultdict

import numpy as np

MIN_RUNS = 2


def positioning_figures(up: np.ndarray, down: np.ndarray) -> dict:
    """ISO 230-2 figures from ``up`` and ``down``, ``(m, n)`` deviations (targets × runs; the
    run counts of the two directions may differ, each ≥ 2). Same unit as the input."""
    up, down = np.atleast_2d(np.asarray(up, float)), np.atleast_2d(np.asarray(down, float))
    if up.shape[0] != down.shape[0] or min(up.shape[1], down.shape[1]) < MIN_RUNS:
        raise ValueError("need the same targets in both directions and >= 2 runs in each")
    mu, md = up.mean(1), down.mean(1)
    su, sd = up.std(1, ddof=1), down.std(1, ddof=1)
    b = mu - md
    ru, rd = 4 * su, 4 * sd
    r = np.maximum(2 * su + 2 * sd + np.abs(b), np.maximum(ru, rd))
    both = np.concatenate([mu, md])
    return {
        "targets": int(up.shape[0]),
        "runs_forward": int(up.shape[1]),
        "runs_backward": int(down.shape[1]),
        "mean_bidirectional_deviation": ((mu + md) / 2).tolist(),
        "reversal_per_target": b.tolist(),
        "B": float(np.max(np.abs(b))),
        "B_mean": float(np.mean(b)),
        "R_up": float(ru.max()),
        "R_down": float(rd.max()),
        "R": float(r.max()),
        "E_up": float(np.ptp(mu)),
        "E_down": float(np.ptp(md)),
        "E": float(np.ptp(both)),
        "M": float(np.ptp((mu + md) / 2)),
        "A_up": float(np.max(mu + 2 * su) - np.min(mu - 2 * su)),
        "A_down": float(np.max(md + 2 * sd) - np.min(md - 2 * sd)),
        "A": float(
            max(np.max(mu + 2 * su), np.max(md + 2 * sd))
            - min(np.min(mu - 2 * su), np.min(md - 2 * sd))
        ),
    }


def channel_figures(meas, scale: float = 1e6) -> list[dict]:
    """ISO 230-2 figures of every channel of merged measurements ``meas`` whose readings allow
    them (each target read in both directions by ≥ 2 runs; runs matched by label), in user
    units (``scale``: 1e6 gives µm and µrad from SI). Channels that do not qualify are left out.
    """
    from ..inverse.data import QUANTITIES

    per = defaultdict(lambda: defaultdict(lambda: {"forward": [], "backward": []}))
    for r, k in zip(meas.readings, meas.row_of_reading):
        if k < 0:
            continue
        key = (r.point, r.quantity, r.instrument)
        per[key][round(r.position * 1e6)][r.direction].append(r.value)
    out = []
    for (point, quantity, inst), targets in per.items():
        pos = sorted(targets)
        ups = [targets[p]["forward"] for p in pos]
        downs = [targets[p]["backward"] for p in pos]
        nu, nd = {len(u) for u in ups}, {len(d) for d in downs}
        if len(nu) != 1 or len(nd) != 1 or min(*nu, *nd) < MIN_RUNS or len(pos) < 2:
            continue
        fig = positioning_figures(np.array(ups) * scale, np.array(downs) * scale)
        fig = {
            "point": point,
            "quantity": quantity,
            "instrument": inst,
            "unit": "µm" if quantity in QUANTITIES[:3] else "µrad",
            "positions_mm": [p * 1e-3 for p in pos],
            **fig,
        }
        out.append(fig)
    return out
