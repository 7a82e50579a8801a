"""End-to-end and steady-state speed of diffguide, in one run (issue 14).

Prints, with the machine, the JAX version and the load average (``os.getloadavg()``) before and
after:

- ``diffguide fit`` on the bundled data and ``diffguide simulate`` (the majda2012 preset, 141
  positions) end to end, wall clock, each in ``--repeats`` fresh processes: the first run on an
  empty cache folder (``--cache-dir``: compilation cache and condensed tables), the second run
  on the same folder; medians (and min, max);
- the table condensation at 20 × 10, 60 × 30 and 100 × 50 elements: first call in a fresh
  process and steady state (median of the next calls, thicknesses varied so that nothing is
  reused), no table cache; concrete inputs, so NumPy (``condense(backend="auto")``: no
  tracing or compilation; the compiled JAX program serves traced inputs);
- the 141-position majda2012 sweep (``joint_errors``), steady state (median of 15 calls).

Run: ``python bench/bench_cli.py [--repeats 3] [--skip-cli] [--skip-steady]`` from the repository
root. Timings depend on the load: other jobs on the same cores slow everything 2-3×; run it on
an idle machine and quote the load it prints.
"""

import argparse
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


def _cli() -> list[str]:
    exe = Path(sys.executable).with_name("diffguide")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "diffguide.cli"]


def _run(args: list[str]) -> float:
    env = dict(os.environ)
    env.pop("DIFFGUIDE_CACHE_DIR", None)
    t = time.perf_counter()
    out = subprocess.run(_cli() + args, capture_output=True, text=True, env=env, cwd=ROOT)
    wall = time.perf_counter() - t
    if out.returncode not in (0, 3):
        sys.exit(f"{' '.join(args)} failed ({out.returncode}):\n{out.stderr[-3000:]}")
    return wall


def _load() -> str:
    return "/".join(f"{v:.2f}" for v in os.getloadavg())


COMMANDS = {
    "fit": lambda out: [
        "fit",
        "--preset",
        "majda2012",
        "--measurements",
        str(DATA),
        "--out",
        str(out / "fit"),
        "--quiet",
    ],
    "simulate": lambda out: [
        "simulate",
        "--preset",
        "majda2012",
        "--positions",
        "-350:350:141",
        "--out",
        str(out / "sim.csv"),
        "--quiet",
    ],
}


def bench_cli(repeats: int) -> dict:
    res = {}
    for name, argv in COMMANDS.items():
        first, second = [], []
        for _ in range(repeats):
            with tempfile.TemporaryDirectory(prefix="dg-bench-") as tmp:
                tmp = Path(tmp)
                cache = ["--cache-dir", str(tmp / "cache")]
                first.append(_run(argv(tmp) + cache))
                second.append(_run(argv(tmp) + cache))
            print(
                f"  {name}: first {first[-1]:.1f} s, second {second[-1]:.1f} s (load {_load()})",
                flush=True,
            )
        res[name] = {"first": first, "second": second}
    return res


def bench_startup(repeats: int) -> dict:
    """Wall clock of ``python -c "import diffguide"`` and ``diffguide --help`` in fresh
    processes (``repeats`` each, after one unmeasured run that fills the OS's file cache)."""
    res = {}
    for name, argv in (("import", [sys.executable, "-c", "import diffguide"]),
                       ("help", _cli() + ["--help"])):
        subprocess.run(argv, capture_output=True, cwd=ROOT)
        times = []
        for _ in range(repeats):
            t = time.perf_counter()
            subprocess.run(argv, capture_output=True, cwd=ROOT, check=True)
            times.append(time.perf_counter() - t)
        res[name] = times
        print(f"  {name}: median {statistics.median(times):.3f} s (load {_load()})", flush=True)
    return res


_CONDENSE = r"""
import json, sys, time
import jax
jax.config.update("jax_enable_x64", True)
from diffguide.machine.build import table_from_spec, with_overrides
from diffguide.presets import majda2012
nx, ny = int(sys.argv[1]), int(sys.argv[2])
spec = majda2012()
def once(t):
    m = table_from_spec(with_overrides(spec, nx=nx, ny=ny, thickness=t))
    t0 = time.perf_counter(); tab = m.condense(); jax.block_until_ready(tab.K)
    return time.perf_counter() - t0
first = once(0.05)
steady = [once(0.05 + 1e-3 * (k + 1)) for k in range(3)]
print(json.dumps({"first": first, "steady": steady}))
"""

_SWEEP = r"""
import json, time
import jax
jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp
from diffguide.machine.kinematics import joint_errors
from diffguide.machine.majda2012 import majda2012_machine, paper_variant
m = majda2012_machine()
x = jnp.linspace(-0.35, 0.35, 141)
f = jax.jit(lambda m, p: joint_errors(m, paper_variant(3), p).errors)
t0 = time.perf_counter(); jax.block_until_ready(f(m, x)); first = time.perf_counter() - t0
ts = []
for _ in range(15):
    t0 = time.perf_counter(); jax.block_until_ready(f(m, x)); ts.append(time.perf_counter() - t0)
print(json.dumps({"first": first, "steady": ts}))
"""


def _python(code: str, *args) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, cwd=ROOT
    )
    if out.returncode:
        sys.exit(f"benchmark script failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


MESHES = ((20, 10), (60, 30), (100, 50))


def bench_steady(meshes=MESHES) -> dict:
    res = {}
    for nx, ny in meshes:
        r = _python(_CONDENSE, nx, ny)
        res[f"condense {nx}x{ny}"] = r
        print(
            f"  condensation {nx} x {ny}: first {r['first']:.2f} s, steady "
            f"{statistics.median(r['steady']):.2f} s (load {_load()})",
            flush=True,
        )
    r = _python(_SWEEP)
    res["sweep 141"] = r
    print(
        f"  141-position sweep: steady {1e3 * statistics.median(r['steady']):.2f} ms, first "
        f"{r['first']:.2f} s (load {_load()})",
        flush=True,
    )
    return res


def _fmt(v, unit="s", scale=1.0):
    med = statistics.median(v) * scale
    if len(v) == 1:
        return f"{med:.3g} {unit}"
    return f"{med:.3g} {unit} ({min(v) * scale:.3g}–{max(v) * scale:.3g})"


def machine_line() -> str:
    """The machine and the stack, in one line."""
    import jax

    return (
        f"{platform.machine()}, {os.cpu_count()} CPUs, {platform.system()}; "
        f"Python {platform.python_version()}, jax {jax.__version__}"
    )


def table_rows(cli: dict | None, st: dict | None,
               startup: dict | None = None) -> list[tuple[str, str, str]]:
    """(benchmark, figure, target) rows from :func:`bench_cli`, :func:`bench_steady` and
    :func:`bench_startup`."""
    rows = []
    if startup:
        rows.append(("`python -c \"import diffguide\"`", _fmt(startup["import"]), "≤ 0.3 s"))
        rows.append(("`diffguide --help`", _fmt(startup["help"]), "≤ 0.3 s"))
    if cli:
        targets = (("fit", "≤ 10 s", "≤ 2 s"), ("simulate", "≤ 5 s", "≤ 5 s"))
        for name, target1, target2 in targets:
            rows.append(
                (f"`diffguide {name}` end to end, empty cache", _fmt(cli[name]["first"]), target1)
            )
            rows.append(
                (f"`diffguide {name}` end to end, second run", _fmt(cli[name]["second"]), target2)
            )
    if st:
        targets = {"20x10": "", "60x30": "≤ 2 s", "100x50": "≤ 10 s"}
        for key, r in st.items():
            if key.startswith("condense"):
                mesh = key.split()[1]
                rows.append(
                    (
                        f"condensation {mesh.replace('x', ' × ')}, steady / first call",
                        f"{_fmt(r['steady'])} / {r['first']:.2f} s",
                        targets[mesh],
                    )
                )
        r = st["sweep 141"]
        rows.append(
            (
                "141-position sweep, steady state",
                _fmt(r["steady"], "ms", 1e3) + f" (first call {r['first']:.2f} s)",
                "≤ 5 ms",
            )
        )
    return rows


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=3, help="fresh processes per CLI figure")
    p.add_argument("--skip-cli", action="store_true")
    p.add_argument("--skip-steady", action="store_true")
    a = p.parse_args()
    load0 = _load()
    print(f"machine: {machine_line()}; load average (1/5/15 min) at start {load0}", flush=True)
    startup = bench_startup(max(a.repeats, 5))
    cli = None if a.skip_cli else bench_cli(a.repeats)
    st = None if a.skip_steady else bench_steady()
    print(
        f"\nload average at the end {_load()} (start {load0}); medians (min–max) of "
        f"{a.repeats} fresh processes for the CLI\n"
    )
    print("| benchmark | figure | target |\n|---|---|---|")
    for r in table_rows(cli, st, startup):
        print(f"| {r[0]} | {r[1]} | {r[2]} |")


if __name__ == "__main__":
    main()
