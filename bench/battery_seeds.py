"""The identification battery (tests/battery) over noise seeds: how often the σ bands hold.

Each case of the battery is one noise draw (its own seed); this runs each case again with
seeds ``--first``..``--last`` (the truth, layout and fit unchanged; the noise — and a case's
drift and outliers — drawn anew) and prints one markdown row per case:

- how many seeds meet the battery's coverage bound (truth inside ±2σ at ≥ 85 % of the points,
  ≥ 70 % on every profile; gauge removed, 10 % trimmed at each end),
- the overall coverage (lowest and median) and the lowest worst-profile coverage,
- the RMS error over the RMS σ (median and largest: about 1 where the bands are honest, below
  1 where they are wide),
- the thickness' z-score ``ln(t̂/t)/σ_ln t`` (RMS and largest |z|: about 1 where its σ is
  honest) and on how many seeds the preload came back "determined", with their z-scores.

With ``--layout planned`` every case is measured with ``cases.PLANNED`` instead of its own
layout (the bundled layout plus what ``diffguide plan`` adds for 8 more levels and 2 more
interferometers). A second table gives each case's worst-profile error (% of that profile's
truth RMS: median, largest, and on how many seeds it is within the wrong-structure cases' 15 %).

Records go to a JSON-lines file as they come (``--jsonl``; an existing file is resumed: the
case/seed pairs in it are not run again). About 2–30 s a fit on 2 cores (the 141-position case
is the slowest). Run:

    python bench/battery_seeds.py [CASE ...] [--first 1] [--last 20] [--jsonl FILE]
        [--layout own|planned]
"""

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import numpy as np  # noqa: E402
from battery.cases import CASES, FIT_PRIORS, command_line, planned, run_case  # noqa: E402


def record(name: str, seed: int, layout: str = "own") -> dict:
    """Run case ``name`` with noise seed ``seed`` and its own or the planned layout; the
    numbers of one row of the JSON lines."""
    case = dataclasses.replace(CASES[name](), seed=seed)
    if layout == "planned":
        case = planned(case)
    t0 = time.perf_counter()
    res = run_case(case)
    out = {"name": name, "seed": seed, "layout": layout}
    if res.fit is None:
        out["error"] = res.error
    else:
        s, st = res.score, res.fit.structure or {}
        out.update(cov=s.overall_coverage, worst=s.worst_coverage, rel=s.overall_rel,
                   worst_rel=s.worst_rel, ratio=s.overall_rms_um / s.overall_sigma_rms_um,
                   chi2=float(res.fit.chi2_dof), converged=bool(res.fit.converged),
                   truth={"thickness": case.thickness or FIT_PRIORS[0][0],
                          "preload": case.preload or FIT_PRIORS[1][0]})
        for key, v in st.items():
            out[key] = {"value": v["value"], "sigma_log": float(v["sigma_log"]),
                        "determined": bool(v["determined"])}
    out["seconds"] = time.perf_counter() - t0
    return out


def _z(r: dict, key: str) -> float:
    return float(np.log(r[key]["value"] / r["truth"][key]) / r[key]["sigma_log"])


def table(records: list[dict]) -> str:
    """The markdown table of ``records`` (one row per case, in the order of :data:`CASES`)."""
    lines = [
        "| case | seeds | coverage bound met | overall coverage, lowest / median | worst profile, "
        "lowest | RMS error / RMS σ, median (largest) | thickness z, RMS (largest) | "
        "preload determined (z) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name in CASES:
        rs = [r for r in records if r["name"] == name and "cov" in r]
        raised = sum(1 for r in records if r["name"] == name and "error" in r)
        if not rs:
            if raised:
                lines.append(f"| {name} | {raised} raised | — | — | — | — | — | — |")
            continue
        cov = np.array([r["cov"] for r in rs])
        worst = np.array([r["worst"] for r in rs])
        ratio = np.array([r["ratio"] for r in rs])
        met = int(np.sum((cov >= 0.85) & (worst >= 0.70)))
        z = np.array([_z(r, "thickness") for r in rs if "thickness" in r])
        det = [_z(r, "preload") for r in rs if r.get("preload", {}).get("determined")]
        det_txt = f"{len(det)}/{len(rs)}"
        if len(det) > 4:
            det_txt += (f" ({min(det):+.1f} to {max(det):+.1f}, RMS "
                        f"{np.sqrt(np.mean(np.square(det))):.2f})")
        elif det:
            det_txt += f" ({', '.join(f'{v:+.1f}' for v in sorted(det))})"
        lines.append(
            f"| {name} | {len(rs)}{f' (+{raised} raised)' if raised else ''} | {met}/{len(rs)} | "
            f"{100 * cov.min():.0f} / {100 * np.median(cov):.0f} % | {100 * worst.min():.0f} % | "
            f"{np.median(ratio):.2f} ({ratio.max():.2f}) | "
            + (f"{np.sqrt(np.mean(z**2)):.2f} ({np.abs(z).max():.1f}) | " if z.size else "— | ")
            + f"{det_txt} |"
        )
    return "\n".join(lines)


def error_table(records: list[dict]) -> str:
    """Markdown: each case's worst-profile error over the seeds (% of the profile's truth RMS)."""
    lines = ["| case | seeds | worst profile error, median (largest) | within 15 % |",
             "|---|---|---|---|"]
    for name in CASES:
        rel = np.array([r["worst_rel"] for r in records if r["name"] == name and "cov" in r])
        if rel.size:
            lines.append(f"| {name} | {rel.size} | {100 * np.median(rel):.0f} % "
                         f"({100 * rel.max():.0f} %) | {int(np.sum(rel <= 0.15))}/{rel.size} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--first", type=int, default=1, help="first seed (default 1)")
    ap.add_argument("--last", type=int, default=20, help="last seed (default 20)")
    ap.add_argument("--jsonl", help="JSON-lines file of the records (appended; resumed)")
    ap.add_argument("--layout", choices=("own", "planned"), default="own",
                    help="each case's own layout (default) or cases.PLANNED")
    args, names = command_line(ap)
    records = []
    if args.jsonl and Path(args.jsonl).exists():
        records = [json.loads(line) for line in Path(args.jsonl).read_text().splitlines() if line]
    records = [r for r in records if r.get("layout", "own") == args.layout]
    done = {(r["name"], r["seed"]) for r in records}
    sink = open(args.jsonl, "a") if args.jsonl else None  # noqa: SIM115 — appended as it goes
    try:
        for name in names:
            for seed in range(args.first, args.last + 1):
                if (name, seed) in done:
                    continue
                r = record(name, seed, args.layout)
                records.append(r)
                print(f"{name} seed {seed}: " + (
                    f"coverage {100 * r['cov']:.0f} % / worst {100 * r['worst']:.0f} %"
                    if "cov" in r else "raised") + f", {r['seconds']:.0f} s",
                    file=sys.stderr, flush=True)
                if sink:
                    sink.write(json.dumps(r) + "\n")
                    sink.flush()
    finally:
        if sink:
            sink.close()
    print(f"<!-- seeds {args.first}-{args.last}, layout {args.layout}; jax {jax.__version__} -->")
    chosen = [r for r in records if r["name"] in names and args.first <= r["seed"] <= args.last]
    print(table(chosen))
    print()
    print(error_table(chosen))


if __name__ == "__main__":
    main()
