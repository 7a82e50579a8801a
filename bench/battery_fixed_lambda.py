"""The identification battery (tests/battery) fitted with a fixed smoothness weight: does
Levenberg–Marquardt converge on every case when λ is given (``fit_rails(lam=...)``, the CLI's
``--lambda``) instead of chosen?

Per case and λ: converged or not, the LM steps, χ²/dof, the thickness estimate and the fit's
message, as one markdown row. The cases' data are their own (seed, layout, structure); the fit is
the battery's (``cases.run_fit``'s machine and priors, the case's stated joints). From 3 s to
about 10 min a fit on 2 cores (λ = 1e-5 is the slower). Run:

    python bench/battery_fixed_lambda.py [CASE ...] [--lam 1e-5,1e-3]
"""

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import numpy as np  # noqa: E402
from battery.cases import CASES, command_line, fit_machine, measurements, simulate_errors  # noqa: E402,E501

from diffguide.inverse import fit_rails  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lam", default="1e-5,1e-3", help="fixed weights, comma-separated")
    args, names = command_line(ap)
    lams = [float(v) for v in args.lam.split(",")]
    print(f"<!-- jax {jax.__version__} on {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, float64 -->")
    print("| case | λ | converged | LM steps | χ²/dof | thickness (mm) | s | message |")
    print("|---|---|---|---|---|---|---|---|")
    bad = 0
    for name in names:
        case = CASES[name]()
        meas = measurements(case, simulate_errors(case))
        points = dict(zip(meas.point_names, map(tuple, np.asarray(meas.points_xy, float))))
        for lam in lams:
            t0 = time.perf_counter()
            fit = fit_rails(fit_machine(points), meas, lam=lam,
                            joints=np.asarray(case.joints_mm) * 1e-3)
            t = (fit.structure or {}).get("thickness")
            thick = f"{t['value'] * 1e3:.1f} ± {t['sigma'] * 1e3:.1f}" if t else "—"
            bad += not fit.converged
            print(f"| {name} | {lam:g} | {'yes' if fit.converged else '**no**'} | {fit.steps} "
                  f"| {fit.chi2_dof:.2f} | {thick} | {time.perf_counter() - t0:.0f} "
                  f"| {fit.message.split(';')[0][:60]} |", flush=True)
    print(f"\n{bad} fit(s) not converged of {len(names) * len(lams)}")


if __name__ == "__main__":
    main()
