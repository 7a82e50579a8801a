"""Benchmark: ``diffguide fit`` on the bundled data, whole process and stage by stage (not a
test; issue 40's figures).

1. Whole process: ``diffguide fit --preset majda2012 --measurements
   data/majda2012_measurements.csv --out DIR --cache-dir C`` in fresh processes, each round a
   cold run (empty cache folder) then a warm one (the same folder); medians of ``--cli-repeat``
   rounds (targets, idle 2-core machine: warm <= 2 s, cold <= 10 s).
2. Stage by stage: a fresh process on a warm cache folder runs the command in-process
   (``diffguide.cli.main``) with each stage's function wrapped by a timer (wall and CPU
   seconds; no profiler): the imports, reading and merging, the machine family (cached
   tables), the fit (Levenberg-Marquardt, the structure stage with its Laplace widening, the
   posterior), the outputs (report.json's sections, the straightness draws, waiting for the
   figures' processes, report.html); medians of ``--stage-repeat`` processes. The same process
   then runs the command a second time on new data of the same layout (each value moved by
   ±0.2 in its unit; target <= 0.5 s).
3. With ``--library``: ``fit_rails`` alone, first call and steady state (median of
   ``--repeat``), elastic and rigid-table.

Timings depend on the load: the load average is printed before and after; quote it.

    python bench/bench_fit.py [--cli-repeat 5] [--stage-repeat 3] [--library]
"""

import argparse
import csv
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"
#: (label, module, attribute) of the wrapped stages, in the order of a run.
STAGES = (
    ("read and merge", "diffguide.jobs.fit", "_read"),
    ("machine family (cached tables)", "diffguide.inverse.structure", "MachineFamily.build"),
    ("fit: all of fit_rails", "diffguide.jobs.fit", "_fit_all"),
    ("  structure stage", "diffguide.inverse.solve", "structure_stage"),
    ("    Newton search", "diffguide.inverse.structure_stage", "maximise_marginal"),
    ("    Laplace at the stated sigma", "diffguide.inverse.structure_stage", "laplace"),
    ("  linearisations (all)", "diffguide.inverse.problem", "FitProblem.linearise"),
    ("  posterior and bands", "diffguide.inverse.fit", "posterior"),
    ("outputs: all", "diffguide.jobs.fit", "_outputs"),
    ("  fit_report (identifiability, validity)", "diffguide.jobs.fit_summary", "fit_report"),
    ("  straightness draws", "diffguide.studies.straightness", "uncertain_straightness"),
    ("  waiting for the figures", "diffguide.plotting.render", "FigureWorker.wait"),
    ("  report.html", "diffguide.jobs.fit_report", "html_text"),
)


def _fit_cmd(out: Path, cache: Path, data: Path = DATA) -> list[str]:
    return ["fit", "--preset", "majda2012", "--measurements", str(data), "--out", str(out),
            "--cache-dir", str(cache), "--quiet"]


def _load() -> str:
    return "/".join(f"{v:.2f}" for v in os.getloadavg())


def _wrap(module: str, attr: str, wall: dict, cpu: dict, label: str) -> None:
    """Replace ``module.attr`` (a function, or ``Class.method``) by a timed call of it."""
    import importlib

    owner = importlib.import_module(module)
    *path, name = attr.split(".")
    for p in path:
        owner = getattr(owner, p)
    fn = getattr(owner, name)  # a classmethod comes bound: the wrapper calls it as it is

    def timed(*a, **k):
        t, c = time.perf_counter(), time.process_time()
        try:
            return fn(*a, **k)
        finally:
            wall[label] = wall.get(label, 0.0) + time.perf_counter() - t
            cpu[label] = cpu.get(label, 0.0) + time.process_time() - c

    setattr(owner, name, timed)


def _perturbed(path: Path, out: Path, step: float = 0.2) -> None:
    """``path`` with every value moved by ``±step`` in its unit, alternately (the bundled data:
    a twentieth of the levels' σ): a new data set of the same layout."""
    rows = list(csv.reader(path.open(encoding="utf-8")))
    head = next(r for r in rows if r and not r[0].startswith("#"))
    iv, k = head.index("value"), 0
    with out.open("w", encoding="utf-8", newline="") as f:
        w = csv.writer(f)
        for r in rows:
            if r and not r[0].startswith("#") and r is not head:
                r[iv] = repr(float(r[iv]) + (step if k % 2 else -step))
                k += 1
            w.writerow(r)


def stages(cache: str) -> None:
    """One fresh process: the stages of a warm run, then a second call on new data (JSON)."""
    t0, c0 = time.perf_counter(), time.process_time()
    from diffguide.cli import main
    import diffguide.cli.fit  # noqa: F401
    import diffguide.jobs.fit  # noqa: F401
    import diffguide.inverse  # noqa: F401 - what the command imports when it runs
    import diffguide.jobs.fit_summary  # noqa: F401
    import jax  # noqa: F401

    wall = {"imports": time.perf_counter() - t0}
    cpu = {"imports": time.process_time() - c0}
    for label, module, attr in STAGES:
        _wrap(module, attr, wall, cpu, label)
    with tempfile.TemporaryDirectory() as tmp:
        t, c = time.perf_counter(), time.process_time()
        main(_fit_cmd(Path(tmp) / "out", Path(cache)))
        wall["command (in-process)"] = time.perf_counter() - t
        cpu["command (in-process)"] = time.process_time() - c
        wall, cpu = dict(wall), dict(cpu)  # the first call's (the second adds to the originals)
        data = Path(tmp) / "new.csv"
        _perturbed(DATA, data)
        t = time.perf_counter()
        main(_fit_cmd(Path(tmp) / "out2", Path(cache), data))
        second = time.perf_counter() - t
    print(json.dumps({"wall": wall, "cpu": cpu, "second_call": second}))


def _cli() -> list[str]:
    return [sys.executable, "-m", "diffguide.cli"]


def _timed_run(args: list[str]) -> float:
    env = {k: v for k, v in os.environ.items() if k != "DIFFGUIDE_CACHE_DIR"}
    t = time.perf_counter()
    out = subprocess.run(_cli() + args, capture_output=True, text=True, env=env, cwd=ROOT)
    if out.returncode not in (0, 3):
        sys.exit(f"{' '.join(args)} failed ({out.returncode}):\n{out.stderr[-3000:]}")
    return time.perf_counter() - t


def _summary(values: list[float]) -> str:
    return (f"median {statistics.median(values):.2f} s (min {min(values):.2f}, max "
            f"{max(values):.2f}, n={len(values)})")


def library(repeat: int) -> None:
    import jax

    jax.config.update("jax_enable_x64", True)
    from diffguide.inverse import fit_rails
    from diffguide.io.measurements import read_measurements
    from diffguide.machine.majda2012 import majda2012_machine

    meas = read_measurements(DATA)
    points = {n: tuple(map(float, xy)) for n, xy in zip(meas.point_names, meas.points_xy)}
    machine = majda2012_machine(points=points)
    for label, m, method in (("elastic LM", machine, "lm"),
                             ("rigid-table linear", machine.with_rigid_table(), "linear")):
        t = time.perf_counter()
        fit = fit_rails(m, meas, method=method)
        first = time.perf_counter() - t
        times = []
        for _ in range(repeat):
            t = time.perf_counter()
            fit_rails(m, meas, method=method)
            times.append(time.perf_counter() - t)
        print(f"fit_rails {label:>18}: first call {first:.2f} s; steady {_summary(times)}; "
              f"LM steps {fit.steps}, chi2/dof {fit.chi2_dof:.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cli-repeat", type=int, default=5)
    ap.add_argument("--stage-repeat", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--library", action="store_true")
    ap.add_argument("--stages", metavar="CACHE", help=argparse.SUPPRESS)  # the helper process
    args = ap.parse_args()
    if args.stages:
        return stages(args.stages)
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, load "
          f"average {_load()}")
    cold, warm = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.cli_repeat):
            cache = Path(tmp) / f"cache{i}"
            cold.append(_timed_run(_fit_cmd(Path(tmp) / "out", cache)))
            warm.append(_timed_run(_fit_cmd(Path(tmp) / "out", cache)))
        print(f"diffguide fit, whole process: warm {_summary(warm)}; cold {_summary(cold)}")
        runs = []
        for _ in range(args.stage_repeat):
            out = subprocess.run([sys.executable, __file__, "--stages", str(Path(tmp) / "cache0")],
                                 capture_output=True, text=True, cwd=ROOT, check=True)
            runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    labels = ["imports", *(s[0] for s in STAGES), "command (in-process)"]
    print(f"stages of a warm run (medians of {len(runs)} processes): wall s, CPU s")
    for label in labels:
        w = [r["wall"].get(label, 0.0) for r in runs]
        c = [r["cpu"].get(label, 0.0) for r in runs]
        print(f"  {label:<42} {statistics.median(w):6.2f} {statistics.median(c):6.2f}")
    print(f"the command in-process, second call on new data of the same layout: "
          f"{_summary([r['second_call'] for r in runs])}")
    if args.library:
        library(args.repeat)
    print(f"load average now {_load()}")


if __name__ == "__main__":
    main()
