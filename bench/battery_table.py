"""The identification battery (tests/battery, issue 11) as a markdown table for the README.

Runs every case (or those named) one after the other — simulate on the fine truth machine, write
the readings as CSV text, parse and merge, fit with ``tests/battery/cases.run_fit``, score — and
prints one row per case: what it stresses, χ²/dof, the profile RMS error (µm, and % of the
truth's RMS; all four profiles, gauge removed, 10 % trimmed at each end), the RMS of the fit's σ
(100 % coverage under a huge σ says nothing), the ±2σ coverage
(overall and the worst profile), the ±2σ coverage per plane (vertical / horizontal, both rails'
profiles together), LM convergence and the seconds from readings to score (machine
builds and compiles included where a case is the first to need them; noisy on a shared CPU).
A fit that raises is a row too, with the exception. Run:

    python bench/battery_table.py [CASE ...] [--json FILE]
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

from battery.cases import command_line, result  # noqa: E402


def _row(res) -> tuple[str, dict]:
    c = res.case
    if res.fit is None:
        msg = res.error.splitlines()[0]
        msg = msg if len(msg) <= 90 else msg[:87] + "..."
        row = (f"| {c.name} | {c.stresses} | — | raised: `{msg}` | — | — | — | — | — | "
               f"{res.seconds:.0f} |")
        return row, {"name": c.name, "error": res.error, "seconds": res.seconds}
    s = res.score
    r, p = divmod(int(s.coverage.argmin()), 2)
    row = (
        f"| {c.name} | {c.stresses} | {res.fit.chi2_dof:.2f} | {s.overall_rms_um:.3g} µm "
        f"({100 * s.overall_rel:.0f} %; worst {100 * s.worst_rel:.0f} %) | "
        f"{s.overall_sigma_rms_um:.3g} µm | "
        f"{100 * s.overall_coverage:.0f} % / {100 * s.worst_coverage:.0f} % "
        f"({s.label(r, p)}) | {_per_plane(s)} | {_structure(res)} | "
        f"{'yes' if res.fit.converged else '**no**'} | {res.seconds:.0f} |"
    )
    data = {
        "name": c.name,
        "chi2_dof": float(res.fit.chi2_dof),
        "converged": bool(res.fit.converged),
        "seconds": res.seconds,
        "overall_rms_um": s.overall_rms_um,
        "overall_rel": s.overall_rel,
        "overall_sigma_rms_um": s.overall_sigma_rms_um,
        "overall_coverage": s.overall_coverage,
        "rms_um": s.rms_um.tolist(),
        "rel": s.rel.tolist(),
        "coverage": s.coverage.tolist(),
        "plane_coverage": plane_coverage(s).tolist(),
        "truth_rms_um": s.truth_rms_um.tolist(),
        "sigma_rms_um": s.sigma_rms_um.tolist(),
    }
    return row, data


def plane_coverage(score):
    """±2σ coverage per plane ``(vertical, horizontal)``: the two rails' profiles together (they
    are scored on the same points)."""
    return score.coverage.mean(axis=0)


def _per_plane(score) -> str:
    v, h = plane_coverage(score)
    return f"{100 * v:.0f} % / {100 * h:.0f} %"


def _structure(res) -> str:
    """Estimated thickness and preload with σ, and the truth in brackets."""
    st = getattr(res.fit, "structure", {}) or {}
    c = res.case
    out = []
    if "thickness" in st:
        v = st["thickness"]
        true = (c.thickness or 0.05) * 1e3
        sig = v["sigma"] * 1e3
        out.append(f"t {v['value'] * 1e3:.0f} ± {sig:.{1 if sig < 1.5 else 0}f} mm ({true:.0f})"
                   + ("" if v["determined"] else " prior"))
    if "preload" in st:
        v = st["preload"]
        true = (c.preload or 0.08) * 100
        out.append(f"P {v['value'] * 100:.1f} ± {v['sigma'] * 100:.1f} % ({true:.0f})"
                   + ("" if v["determined"] else " prior"))
    return "; ".join(out) or "—"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", help="also write the numbers per case to this JSON file")
    args, names = command_line(ap)
    print(
        f"<!-- jax {jax.__version__} on {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}, float64 -->"
    )
    print(
        "| case | what it stresses | χ²/dof | profile RMS error (% of truth) | σ RMS | "
        "±2σ coverage: all / worst profile | ±2σ coverage V / H | structure (truth) | "
        "converged | s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    out = []
    for name in names:
        row, data = _row(result(name))
        print(row, flush=True)
        out.append(data)
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
