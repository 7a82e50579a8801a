"""The battery's prediction at points no instrument stood at, as a markdown table.

Per case (tests/battery): the case's fit (``tests/battery/cases.result``, the same fit as
bench/battery_table.py) predicts the six joint errors with σ
(:func:`diffguide.inverse.predict.predict`) at ``cases.UNMEASURED`` — (±300, ±100) mm — over the
case's positions; the truth's errors there come from the truth machine (40 × 20 mesh, the case's
structure) with the truth rails in the fit's gauge (EXX with the case's lead error). Printed per
case: the fraction of (position, point, quantity) inside the predicted ±2σ (all, and the worst
quantity), the relative error per quantity (RMS error over the truth's RMS, the four points and
all positions together) and the seconds of the prediction; then the median over the cases. A
case whose fit raised is a row with the exception. Run:

    python bench/battery_predict.py [CASE ...] [--json FILE]
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
from battery.cases import QUANTITIES, command_line, prediction_score, result  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", help="also write the numbers per case to this JSON file")
    args, names = command_line(ap)
    print(
        f"<!-- jax {jax.__version__} on {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}, float64 -->"
    )
    print("| case | ±2σ coverage: all / worst quantity | "
          + " | ".join(f"{q} rel. error" for q in QUANTITIES) + " | s |")
    print("|---|---|" + "---|" * len(QUANTITIES) + "---|")
    out, rels = [], []
    for name in names:
        res = result(name)
        if res.fit is None:
            print(f"| {name} | fit raised: `{res.error.splitlines()[0][:80]}` |"
                  + " — |" * len(QUANTITIES) + " — |", flush=True)
            out.append({"name": name, "error": res.error})
            continue
        try:
            s = prediction_score(name)
        except Exception as exc:  # noqa: BLE001 — a row, not the end of the table
            print(f"| {name} | prediction raised: `{type(exc).__name__}: {exc}`"[:140] + " |"
                  + " — |" * len(QUANTITIES) + " — |", flush=True)
            out.append({"name": name, "error": f"{type(exc).__name__}: {exc}"})
            continue
        k = int(np.argmin(s.coverage_q))
        rels.append(s.rel_q)
        print(f"| {name} | {100 * s.coverage:.0f} % / {100 * s.coverage_q[k]:.0f} % "
              f"({QUANTITIES[k]}) | " + " | ".join(f"{100 * r:.0f} %" for r in s.rel_q)
              + f" | {s.seconds:.0f} |", flush=True)
        out.append({"name": name, "coverage": s.coverage, "coverage_q": s.coverage_q.tolist(),
                    "rel_q": s.rel_q.tolist(), "rms_um": s.rms_um.tolist(),
                    "sigma_um": s.sigma_um.tolist(), "seconds": s.seconds})
    if rels:
        med = np.median(np.array(rels), axis=0)
        print("| **median over the cases** | | " + " | ".join(f"{100 * r:.0f} %" for r in med)
              + " | |")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
