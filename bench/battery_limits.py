"""What the battery's wrong-structure data hold at best: each case fitted with the machine that made
its data (tests/battery/cases.truth_model_fit — the 40 × 20 mesh, the truth's thickness and
preload given), and then the horizontal half-difference's prior scale chosen *in hindsight*.

The 15 % per-profile bound of the wrong-structure cases fails on the horizontal profiles, and
the miss is one combination of the rails, the horizontal half-difference ``(e₂ − e₁)/2``. This
prints, per case:

1. the truth-model fit's profile errors (% of each profile's truth RMS, gauge removed, 10 %
   trimmed), and per combination of the rails (both planes' mean and half-difference) its error
   and the fit's own posterior σ, both in % of the plane's truth RMS;
2. the same fit re-solved on its linearisation (exact here: the model is linear in µm-sized
   rails to ~1e-3) with the half-difference's prior precision scaled by ``f`` over five decades,
   every other combination's kept — and the worst profile error at the best ``f``, which only a
   fit that knew the truth could choose.

If the worst profile stays above 15 % there, no fit of these data reaches the bound, whatever
its model, its structure estimate or its prior's scale. Run:

    python bench/battery_limits.py [CASE ...]
"""

import argparse
import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import numpy as np  # noqa: E402
from battery.cases import CASES, measurements, result, truth_model_fit, truth_profiles  # noqa: E402
from battery.score import combination_sigma_rel, score_fit, score_profiles  # noqa: E402

from diffguide.inverse.weight import project_out  # noqa: E402

FACTORS = (1e-3, 1e-2, 0.1, 0.3, 1.0, 3.0, 10.0, 100.0)


def _combination(n: int, plane: int, half_difference: bool) -> np.ndarray:
    """``T`` with ``T c`` the combination's coefficients (profile order of ``c``: rail 1 v,
    rail 1 h, rail 2 v, rail 2 h)."""
    T = np.zeros((n, 4 * n))
    T[:, plane * n:(plane + 1) * n] = (-0.5 if half_difference else 0.5) * np.eye(n)
    T[:, (2 + plane) * n:(3 + plane) * n] = 0.5 * np.eye(n)
    return T


def rescaled(fit, meas, truth, factor: float):
    """Score of ``fit`` re-solved on its linearisation with the horizontal half-difference's
    prior precision times ``factor`` (``factor = 1``: the fit itself)."""
    basis, Z, n = fit.basis, fit.Z, fit.basis.n_coeffs
    sigma = np.asarray(meas.sigma)
    w = np.ones(meas.n)
    w[np.asarray(fit.outliers, int)] = 0.0
    r = -w * np.asarray(fit.residual) / sigma  # whitened residual at the solution
    nt, nq = fit.n_theta, len(fit.structure)
    J_theta, J_nuis = fit.jacobian[:, :nt], fit.jacobian[:, nt + nq:]
    theta = Z.T @ (fit.coeffs.reshape(-1) * 1e6)  # Z orthonormal, c in its range
    Jp, yp, _ = project_out(J_nuis, J_theta, J_theta @ theta - r)
    G2 = basis.penalty_factor()[:, :n][: 2 * (n - 3)]
    G0 = basis.amplitude_factor()[:, :n][: 3 * (n - 3)]
    W = G2.T @ G2 + fit.weight.kappa * G0.T @ G0  # one profile's prior precision (λ aside)
    P = np.zeros((nt, nt))
    for plane in (0, 1):
        for hd in (False, True):
            T = _combination(n, plane, hd)
            scale = factor if (plane, hd) == (1, True) else 1.0
            P += scale * fit.lam * Z.T @ (2.0 * T.T @ W @ T) @ Z  # Σ profiles = 2 Σ combos
    H = Jp.T @ Jp + P
    c = (Z @ np.linalg.solve(H, Jp.T @ yp)).reshape(2, 2, n) * 1e-6
    cov = Z @ np.linalg.inv(H) @ Z.T * 1e-12 * fit.sigma_scale**2
    s = np.linspace(basis.start, basis.end, 401)
    B = basis.matrix(s)
    val = np.einsum("sk,rpk->rps", B, c)
    sig = np.zeros_like(val)
    for k in range(4):
        blk = cov[k * n:(k + 1) * n, k * n:(k + 1) * n]
        sig[divmod(k, 2)] = np.sqrt(np.maximum(np.einsum("sk,kl,sl->s", B, blk, B), 0.0))
    return score_profiles(basis, fit.fix_slope, val, sig, truth(s), s)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    wrong = [n for n, make in CASES.items() if make().wrong_structure]
    ap.add_argument("cases", nargs="*", help=f"default: {', '.join(wrong)}")
    args = ap.parse_args()
    names = args.cases or wrong
    unknown = [n for n in names if n not in CASES]
    if unknown:
        ap.error(f"unknown case(s) {', '.join(unknown)} (allowed {', '.join(CASES)})")
    pct = lambda a: "/".join(f"{100 * v:.0f}" for v in np.ravel(a))  # noqa: E731
    for name in names:
        case = result(name).case
        truth = lambda s, case=case: truth_profiles(case, s)  # noqa: E731
        fit = truth_model_fit(name)
        sc = score_fit(fit, truth)
        sig = combination_sigma_rel(fit, truth)
        print(f"{name}: with the truth's machine, profile errors {pct(sc.rel)} % (rail 1 v/h, "
              f"rail 2 v/h), coverage {100 * sc.overall_coverage:.0f} % / "
              f"{100 * sc.worst_coverage:.0f} %")
        for p, plane in enumerate(("vertical", "horizontal")):
            print(f"  {plane}: mean error {100 * sc.combination_rel[p, 0]:.1f} % "
                  f"(σ {100 * sig[p, 0]:.1f} %), half-difference error "
                  f"{100 * sc.combination_rel[p, 1]:.1f} % (σ {100 * sig[p, 1]:.1f} %) "
                  "of the plane's truth RMS")
        meas = measurements(case)
        rows = [(f, rescaled(fit, meas, truth, f)) for f in FACTORS]
        for f, s in rows:
            print(f"  half-difference prior × {f:g}: profile errors {pct(s.rel)} %, "
                  f"coverage {100 * s.overall_coverage:.0f} % / {100 * s.worst_coverage:.0f} %")
        f_best, best = min(rows, key=lambda fs: fs[1].worst_rel)
        print(f"  best in hindsight (× {f_best:g}): worst profile {100 * best.worst_rel:.1f} %",
              flush=True)


if __name__ == "__main__":
    main()
