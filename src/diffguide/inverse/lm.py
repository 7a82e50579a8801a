r"""Levenberg–Marquardt on a regularised least-squares objective ``‖r(x)‖² + xᵀPx``, one
linearisation per step, the damped normal equations solved in NumPy."""

import numpy as np

#: Floor of the noise scale ``ŝ²`` (objective per datum) in Levenberg–Marquardt's stop rule.
_SCALE_FLOOR = 1e-24


def spd(H):
    """``H`` symmetrised, ``(H + Hᵀ)/2``."""
    H = 0.5 * (H + H.T)
    return H


def levenberg_marquardt(x, r, J, pred, Jc, linearise, P, rtol, max_steps):
    """Minimise ``‖r(x)‖² + xᵀPx`` from ``x`` (with ``r``, ``J`` there) by Levenberg–Marquardt
    with Marquardt's diagonal scaling; one compiled linearisation per step (the model is nearly
    linear in µm-sized rail errors, so the Gauss–Newton step, μ = 0, is tried first).
    ``linearise(x)`` returns ``(r, J, pred, ok, Jc)`` (``pred`` and ``Jc`` are carried along).

    Stops when the Gauss–Newton decrement ``δᵀHδ`` (the χ² a full step would still gain) is below
    ``rtol·ŝ²`` — a change of the objective far below the noise scale means nothing
    statistically. ``ŝ²`` is the objective per datum at the start (≈ 1 when the stated σ are
    right; with σ all stated 10⁹× too large it is 10⁻¹⁸, and the rule stays the same rule),
    floored at :data:`_SCALE_FLOOR` (data that are zero to round-off stop at once).
    Returns ``(x, r, J, pred, Jc, converged, steps, reason)``.
    """
    cost = float(r @ r + x @ P @ x)
    rtol = rtol * max(cost / max(len(r), 1), _SCALE_FLOOR)
    mu = 0.0
    for step in range(1, max_steps + 1):
        H = J.T @ J + P
        g = J.T @ r + P @ x
        D = np.diag(np.diag(H))
        try:
            delta = -np.linalg.solve(H + mu * D, g)
        except np.linalg.LinAlgError:
            mu = max(mu * 10, 1e-6)
            continue
        decrement = float(-g @ delta)
        if decrement < rtol and mu == 0.0:
            return x, r, J, pred, Jc, True, step - 1, "converged"
        r_t, J_t, pred_t, ok_t, Jc_t = linearise(x + delta)
        cost_t = (float(r_t @ r_t + (x + delta) @ P @ (x + delta))
                  if ok_t and np.all(np.isfinite(J_t)) else np.inf)
        if cost_t <= cost:
            x, r, J, pred, Jc, cost = x + delta, r_t, J_t, pred_t, Jc_t, cost_t
            if decrement < rtol:
                return x, r, J, pred, Jc, True, step, "converged"
            mu = 0.0 if mu <= 1e-6 else mu / 10
        else:
            mu = max(mu * 10, 1e-6)
            if mu > 1e12:
                return x, r, J, pred, Jc, False, step, (
                    "Levenberg-Marquardt cannot decrease the objective further (the damping "
                    "reached 1e12); the best estimate so far is returned")
    return x, r, J, pred, Jc, False, max_steps, (
        f"Levenberg-Marquardt stopped after {max_steps} steps without meeting its tolerance; "
        "the best estimate so far is returned")
