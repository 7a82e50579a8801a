"""The straightness interval's coverage on the identification battery (tests/battery, issue 39).

Per case (``tests/battery/cases.result``: the same fit as bench/battery_table.py) and per rail and
plane: the truth's straightness (least-squares reference line, ISO 230-1) over the grid of
``rails.csv`` (``profile_grid`` of the fit's basis) against the fit's straightness as
``report.json`` reports it (:func:`diffguide.studies.straightness.uncertain_straightness`, the
same draws and seeds): the **percentile** interval ``[q_lo, q_hi]`` of the draws (GUM S1, the
verdict's) and the **basic** bootstrap interval ``[2t(ĉ) − q_hi, 2t(ĉ) − q_lo]`` (reported beside
it), each with "covered?" (and, in the summary, their **envelope**, the smallest interval holding
both). Then the
coverage fraction of each rule over the rows, and for tolerances ``T = f × truth`` the count of
"pass" where the truth exceeds ``T`` (a false pass; ISO 14253-1 on each interval, never "pass"
where the data are not informative).

The fits are slow (minutes per case on a loaded CPU): ``--save DIR`` keeps each case's posterior
(per profile: coefficients, covariance, prior covariance; the grid, the basis matrix, the
truth's straightness) in ``DIR/<case>.npz``, and a later run with the same ``--save DIR`` reads
it instead of fitting again (``--fit-only``: fit and save, no table). Run:

    python bench/battery_straightness.py [CASE ...] [--save DIR] [--fit-only] [--json FILE]
"""

import argparse
import json
import os
import platform
import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import numpy as np  # noqa: E402
from battery.cases import command_line, result, truth_profiles  # noqa: E402

from diffguide.inverse.basis import PROFILES  # noqa: E402
from diffguide.io.fit_files import profile_grid  # noqa: E402
from diffguide.studies.straightness import (  # noqa: E402
    N_SAMPLES,
    decide,
    prior_cov,
    straightness,
)

#: Tolerances of the false-pass count, as fractions of each row's truth.
TOLERANCE_FACTORS = (0.8, 0.9, 1.0, 1.1, 1.2)
RULES = ("percentile", "basic", "envelope")


def posterior(name: str) -> dict:
    """Case ``name`` fitted (``cases.result``): per profile (the order of ``PROFILES``) the
    coefficients, their covariance and prior covariance (m, m²), the grid ``s`` (m), the basis
    matrix, the truth's straightness (m), the fit's χ²/dof; ``{"error": ...}`` if it raised."""
    res = result(name)
    if res.fit is None:
        return {"error": np.array(res.error)}
    fit = res.fit
    s = profile_grid(fit.basis)
    n = fit.basis.per_profile
    prior = prior_cov(fit)
    truth = truth_profiles(res.case, s)
    blocks = [slice(k * n, (k + 1) * n) for k in range(4)]
    return {
        "s": s, "B": fit.basis.matrix(s),
        "mean": np.array([fit.coeffs[r, 0 if p == "vertical" else 1] for r, p in PROFILES]),
        "cov": np.array([fit.cov[b, b] for b in blocks]),
        "prior": (np.array([prior[b, b] for b in blocks]) if prior is not None
                  else np.zeros((0,))),
        "truth": np.array([straightness(s, truth[r, 0 if p == "vertical" else 1])
                           for r, p in PROFILES]),
        "chi2_dof": np.array(float(fit.chi2_dof)),
    }


def load_or_fit(name: str, save: Path | None) -> dict:
    path = None if save is None else save / f"{name}.npz"
    if path is not None and path.exists():
        with np.load(path) as z:
            return dict(z)
    post = posterior(name)
    if path is not None:
        save.mkdir(parents=True, exist_ok=True)
        np.savez(path, **post)
    return post


def rows_of(name: str, post: dict, n_samples: int = N_SAMPLES) -> list[dict]:
    """One row per rail and plane: truth, both intervals, covered? (µm); the same draws and
    seeds as ``rail_straightness`` (seed ``k`` for profile ``k``)."""
    from diffguide.studies.straightness import uncertain_straightness

    rows = []
    prior = post["prior"] if post["prior"].size else None
    for k, (r, plane) in enumerate(PROFILES):
        res = uncertain_straightness(post["s"], post["B"], post["mean"][k], post["cov"][k],
                                     prior=None if prior is None else prior[k],
                                     n_samples=n_samples, seed=k)
        truth = float(post["truth"][k])
        row = {"case": name, "rail": r + 1, "plane": plane, "truth_um": truth * 1e6,
               "mean_profile_um": res["mean_profile"] * 1e6, "u_um": res["u"] * 1e6,
               "informative": bool(res["informative"])}
        (blo, bhi), (plo, phi) = res["interval_95_basic"], res["interval_95"]
        for rule, (lo, hi) in (("basic", (blo, bhi)), ("percentile", (plo, phi)),
                               ("envelope", (min(blo, plo), max(bhi, phi)))):
            row[rule] = [lo * 1e6, hi * 1e6]
            row[f"{rule}_covered"] = bool(lo <= truth <= hi)
        row["estimate_um"] = res["value"] * 1e6
        rows.append(row)
    return rows


def false_passes(rows: list[dict], rule: str, factor: float) -> tuple[int, int]:
    """``(false passes, passes)`` of ``rule`` at ``T = factor × truth`` over ``rows``: a pass
    where the truth exceeds ``T`` is false (``factor < 1``)."""
    fp = n = 0
    for r in rows:
        T = factor * r["truth_um"]
        if T <= 0:
            continue
        v = decide(r[rule], T, informative=r["informative"])
        n += v == "pass"
        fp += v == "pass" and r["truth_um"] > T
    return fp, n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--save", type=Path, help="keep / reuse each case's posterior here (.npz)")
    ap.add_argument("--fit-only", action="store_true", help="fit and save; no table")
    ap.add_argument("--json", help="also write the rows to this JSON file")
    args, names = command_line(ap)
    print(
        f"<!-- jax {jax.__version__} on {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}, float64, "
        f"N = {N_SAMPLES} draws per profile -->", flush=True
    )
    if not args.fit_only:
        print("| case | rail | plane | truth (µm) | t(ĉ) | percentile 95 % (verdict's) | "
              "covered | basic 95 % | covered |")
        print("|---|---|---|---|---|---|---|---|---|")
    rows, errors = [], []
    for name in names:
        post = load_or_fit(name, args.save)
        if "error" in post:
            errors.append(name)
            print(f"| {name} | fit raised: `{str(post['error']).splitlines()[0][:80]}` |",
                  flush=True)
            continue
        if args.fit_only:
            print(f"{name}: saved (χ²/dof {float(post['chi2_dof']):.2f})", flush=True)
            continue
        for r in rows_of(name, post):
            rows.append(r)
            print(f"| {name} | {r['rail']} | {r['plane']} | {r['truth_um']:.2f} | "
                  f"{r['mean_profile_um']:.2f} | "
                  f"{r['percentile'][0]:.2f} … {r['percentile'][1]:.2f} | "
                  f"{'yes' if r['percentile_covered'] else '**no**'} | "
                  f"{r['basic'][0]:.2f} … {r['basic'][1]:.2f} | "
                  f"{'yes' if r['basic_covered'] else '**no**'} |", flush=True)
    if not rows:
        return
    print()
    for rule in RULES:
        c = sum(r[f"{rule}_covered"] for r in rows)
        below = sum(r[rule][1] < r["truth_um"] for r in rows)
        worst = min(rows, key=lambda r: r[rule][1] / r["truth_um"])
        print(f"{rule}: covers the truth in {c}/{len(rows)} rows ({100 * c / len(rows):.0f} %); "
              f"the interval below the truth in {below} (a pass for any T between its upper end "
              f"and the truth), above it in {len(rows) - c - below}; lowest upper end / truth "
              f"{worst[rule][1] / worst['truth_um']:.2f} ({worst['case']} rail {worst['rail']} "
              f"{worst['plane']})")
    print()
    print("| T / truth | " + " | ".join(f"{rule}: false passes / passes" for rule in RULES)
          + " |")
    print("|---|" + "---|" * len(RULES))
    for f in TOLERANCE_FACTORS:
        print(f"| {f:g} | " + " | ".join("{} / {}".format(*false_passes(rows, rule, f))
                                         for rule in RULES) + " |")
    if errors:
        print(f"\nfits that raised: {', '.join(errors)}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
