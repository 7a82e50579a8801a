"""The battery's tables from the scores a test run logged, without fitting anything again.

``DIFFGUIDE_BATTERY_LOG=FILE pytest tests/test_battery.py`` (or the whole suite) appends every
case's fit score and prediction score to FILE as JSON lines (``tests/battery/cases.py``); this
prints, per case, the fit (χ²/dof, knots, profile error and ±2σ coverage) and the prediction at
the points no instrument stood at (coverage inside ±2σ, relative error per quantity), then the
median relative error over the cases. Run:

    python bench/battery_from_log.py FILE
"""

import json
import sys

import numpy as np

QUANTITIES = ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX")


def main(path: str) -> None:
    rows = [json.loads(line) for line in open(path, encoding="utf-8") if line.strip()]
    fits = {r["name"]: r for r in rows if r["kind"] == "fit"}
    preds = {r["name"]: r for r in rows if r["kind"] == "prediction"}
    print("| case | χ²/dof | knots (mm) | profile error, all (worst) | ±2σ coverage all / worst | "
          "prediction ±2σ coverage (worst quantity) | "
          + " | ".join(f"{q} rel. error" for q in QUANTITIES) + " |")
    print("|---|---|---|---|---|---|" + "---|" * len(QUANTITIES))
    rels = []
    for name, f in fits.items():
        if f.get("error"):
            print(f"| {name} | fit raised: {f['error'][:60]} |" + " — |" * (4 + len(QUANTITIES)))
            continue
        cov = np.asarray(f["coverage"])
        p = preds.get(name)
        pred = "—"
        cells = ["—"] * len(QUANTITIES)
        if p:
            cq = np.asarray(p["coverage_q"])
            k = int(np.argmin(cq))
            pred = f"{100 * p['coverage']:.1f} % ({QUANTITIES[k]} {100 * cq[k]:.0f} %)"
            cells = [f"{100 * v:.0f} %" for v in p["rel_q"]]
            rels.append(p["rel_q"])
        print(f"| {name} | {f['chi2_dof']:.2f} | {1e3 * f['knot_spacing']:.0f} | "
              f"{100 * f['overall_rel']:.0f} % ({100 * max(np.ravel(f['rel'])):.0f} %) | "
              f"{100 * f['overall_coverage']:.0f} / {100 * cov.min():.0f} % | {pred} | "
              + " | ".join(cells) + " |")
    if rels:
        med = np.median(np.asarray(rels), axis=0)
        print(f"| **median over {len(rels)} cases** | | | | | | "
              + " | ".join(f"{100 * v:.0f} %" for v in med) + " |")


if __name__ == "__main__":
    main(sys.argv[1])
