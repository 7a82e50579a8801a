r"""The predicted posterior of a measurement plan and the criteria that rank plans.

For a set ``𝒫`` of placements, at every prior rail draw ``d`` (:mod:`.plan`),
``H_d = P + Σ_{b∈𝒫} R_{bd}ᵀR_{bd}`` and ``Cov_d = H_d⁻¹``; the gauge-fixed profiles' variances
are ``diag(W Cov_d Wᵀ)`` averaged over the draws. A trial placement is a rank-``r`` Woodbury
update of ``S = H⁻¹``:

.. math::  S' = S - U K^{-1} U^T,\quad U = SR^T,\quad K = I + R S R^T,\qquad
           \log\det H' = \log\det H + \log\det K.

The functions take a :class:`~.planner.Planner` (its ``P``, ``blocks``, ``W``, ``W_work``,
``draws``, ``s``).
"""

import dataclasses
from collections.abc import Sequence

import numpy as np

from .instruments import Placement

_UM = 1e-6
CRITERIA = ("worst", "A", "D", "work")
#: Profile samples per profile over the visited rail length (for σ and the criteria).
N_S = 121


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """The predicted posterior of one plan.

    Attributes:
        placements: the plan, ``(kind, site)`` pairs.
        s: rail coordinate of the samples (m). sigma: ``(2 rails, 2 planes, len(s))`` σ of the
            gauge-fixed profiles (m), planes (vertical, horizontal).
        worst: largest profile σ (m). rms: RMS profile σ (m). logdet: ``log det Cov`` of all
            unknowns (whitened units). work: largest σ of the work point's predicted errors
            over the stroke (m or rad; NaN without a work point).
        structure_ratio: per structural unknown, posterior σ / prior σ (1: the plan says
            nothing about it).
    """

    placements: tuple[Placement, ...]
    s: np.ndarray
    sigma: np.ndarray
    worst: float
    rms: float
    logdet: float
    work: float
    structure_ratio: dict

    def criterion(self, name: str) -> float:
        """The value of criterion ``name`` (:data:`CRITERIA`; µm, µm/m or nats)."""
        return {
            "worst": self.worst / _UM,
            "A": self.rms / _UM,
            "D": self.logdet,
            "work": self.work / _UM,
        }[name]


def check_placements(planner, placements: Sequence[Placement]) -> tuple[Placement, ...]:
    """``placements`` as ``(kind, site)`` string pairs, each one the planner knows."""
    out = []
    for p in placements:
        p = (str(p[0]), str(p[1]))
        if p not in planner.blocks:
            kinds = ", ".join(planner.instrument)
            raise ValueError(
                f"placement {p}: the instrument kind must be one of {kinds} "
                "and the site a point of the machine "
                f"({', '.join(planner.sites)})"
            )
        out.append(p)
    return tuple(out)


def information(planner, placements: Sequence[Placement]) -> np.ndarray:
    """``H_d = P + Σ_b R_bdᵀR_bd`` of a plan at every draw, ``(n_draws, n_x, n_x)``."""
    H = np.repeat(planner.P[None], len(planner.draws), axis=0)
    for p in check_placements(planner, placements):
        R = planner.blocks[p]
        H += np.einsum("dri,drj->dij", R, R)
    return H


def posterior(planner, placements: Sequence[Placement]):
    """``S_d = H_d⁻¹`` (symmetrised) and ``log det S_d`` of a plan at every draw."""
    H = information(planner, placements)
    S = np.linalg.inv(H)
    S = 0.5 * (S + np.swapaxes(S, 1, 2))
    return S, -np.linalg.slogdet(H)[1]


def evaluate(planner, placements: Sequence[Placement] = ()) -> Evaluation:
    """The predicted posterior of a plan, computed directly (no updates)."""
    placements = check_placements(planner, placements)
    S, logdet = posterior(planner, placements)
    return evaluation(planner, placements, S, logdet)


def variances(planner, S):
    """Profile and work-point variances averaged over the draws (µm², user units²)."""
    W = planner.W
    var = np.maximum(np.einsum("ij,djk,ik->i", W, S, W) / len(S), 0.0)
    var_w = None
    if planner.W_work is not None:
        Ww = planner.W_work
        var_w = np.einsum("ij,djk,ik->i", Ww, S, Ww) / len(S) / _UM**2
    return var, var_w


def evaluation(planner, placements, S, logdet) -> Evaluation:
    """The :class:`Evaluation` of posterior covariances ``S`` (per draw) and their ``logdet``."""
    var, var_w = variances(planner, S)
    sig = np.sqrt(var) * _UM
    work = float("nan") if var_w is None else float(np.sqrt(max(var_w.max(), 0.0))) * _UM
    n_th = planner.n_theta
    ratio = {
        n: float(np.sqrt(max(np.mean(S[:, n_th + i, n_th + i]), 0.0)))
        for i, n in enumerate(planner.family.names)
    }
    return Evaluation(
        tuple(placements),
        planner.s,
        sig.reshape(2, 2, N_S),
        float(sig.max()),
        float(np.sqrt(np.mean(sig**2))),
        float(np.mean(logdet)),
        work,
        ratio,
    )


def trial(planner, S, var, var_w, R, criterion):
    """Criterion after adding the factors ``R`` (one per draw) to ``H_d = S_d⁻¹``
    (Woodbury), and the pieces of the update: ``X`` (``U K⁻¹ Uᵀ = XᵀX``) and ``log det K``."""
    U = S @ np.swapaxes(R, 1, 2)  # (d, n_x, r)
    K = np.eye(R.shape[1]) + R @ U
    Lk = np.linalg.cholesky(0.5 * (K + np.swapaxes(K, 1, 2)))
    logdet_k = 2.0 * np.sum(np.log(np.diagonal(Lk, axis1=1, axis2=2)), axis=1)
    X = np.linalg.solve(Lk, np.swapaxes(U, 1, 2))  # (d, r, n_x): U K⁻¹ Uᵀ = XᵀX
    if criterion == "D":
        return -float(np.mean(logdet_k)), X, logdet_k
    if criterion == "work":
        dv = np.sum(np.einsum("ij,drj->dri", planner.W_work, X) ** 2, axis=(0, 1))
        return float(np.max(var_w - dv / len(S) / _UM**2)), X, logdet_k
    dv = np.sum(np.einsum("ij,drj->dri", planner.W, X) ** 2, axis=(0, 1)) / len(S)
    v = np.maximum(var - dv, 0.0)
    value = float(np.max(v)) if criterion == "worst" else float(np.mean(v))
    return value, X, logdet_k


def criterion_value(criterion, var, var_w, logdet) -> float:
    """The criterion from the variances (µm², user units²) or ``log det`` (nats), as
    :func:`trial` compares them."""
    if criterion == "worst":
        return float(np.max(var))
    if criterion == "A":
        return float(np.mean(var))
    if criterion == "work":
        return float(np.max(var_w))
    return float(np.mean(logdet))


def user_value(criterion, value) -> float:
    """A :func:`criterion_value` in the criterion's user units (µm, µm/m; nats for D)."""
    return float(value) if criterion == "D" else float(np.sqrt(max(value, 0.0)))
