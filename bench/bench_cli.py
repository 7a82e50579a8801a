"""End-to-end and steady-state speed of diffguide, in one run (issue 14).

Prints, with the machine, the JAX version and the load average (``os.getloadavg()``) before and
after:

- ``python -c "import diffguide"`` and ``diffguide --help``;
- ``diffguide fit`` on the bundled data and ``diffguide simulate`` (the majda2012 preset, 141
  positions) end to end, wall clock, each in ``--repeats`` fresh processes: the first run on an
  empty cache folder (``--cache-dir``: compilation cache and condensed tables), the second run
  on the same folder; medians (and min, max); after each fit, ``diffguide predict`` from it
  (2 points x 71 positions, ``--z-mm 150``) on its cache folder, first and warm (5 warm runs
  in all);
- ``diffguide fit`` called four times in one process (the first call, then the next three);
- the prediction in one process (2 new points, the fit's sweep kept) and the 21 x 11 error map
  (``bench/bench_predict.py``);
- with ``--suite-log LOG`` (a ``pytest --durations=0`` log), the battery's seconds per case;
- the table condensation at 20 × 10, 60 × 30 and 100 × 50 elements: first call in a fresh
  process and steady state (median of the next calls, thicknesses varied so that nothing is
  reused), no table cache; concrete inputs, so NumPy (``condense(backend="auto")``: no
  tracing or compilation; the compiled JAX program serves traced inputs);
- the 141-position majda2012 sweep (``joint_errors``), steady state (median of 15 calls).

Run: ``python bench/bench_cli.py [--repeats 3] [--skip-cli] [--skip-steady] [--suite-log LOG]``
from the repository root. Timings depend on the load: other jobs on the same cores slow
everything 2-3×; run it on an idle machine and quote the load it prints.
"""

import argparse
import json
import os
import platform
import shutil
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


#: ``diffguide predict`` from the fit made by ``COMMANDS["fit"]`` in the same folder: 2 points
#: x 71 positions (the measured range), at the tool's height
PREDICT = lambda out: [  # noqa: E731
    "predict",
    "--fit",
    str(out / "fit"),
    "--point",
    "Q1:300,100",
    "--point",
    "Q2:-300,-100",
    "--z-mm",
    "150",
    "--out",
    str(out / "p.csv"),
    "--quiet",
]


def bench_cli(repeats: int, warm_predicts: int = 5, keep_fit: Path | None = None) -> dict:
    """Each command of :data:`COMMANDS` in fresh processes, ``repeats`` times: a first run on an
    empty cache folder and a second on the same folder. After each fit, :data:`PREDICT` from
    it on the fit's cache folder: a first run (the fit's programs and tables there, not yet
    the prediction's) and then warm runs, ``warm_predicts`` in all over the repeats.
    ``keep_fit``: where to copy the first fit's output folder (for the in-process figures)."""
    res = {}
    per_repeat = -(-warm_predicts // repeats)
    for name, argv in COMMANDS.items():
        first, second = [], []
        for k in range(repeats):
            with tempfile.TemporaryDirectory(prefix="dg-bench-") as tmp:
                tmp = Path(tmp)
                cache = ["--cache-dir", str(tmp / "cache")]
                first.append(_run(argv(tmp) + cache))
                second.append(_run(argv(tmp) + cache))
                line = f"  {name}: first {first[-1]:.1f} s, second {second[-1]:.1f} s"
                if name == "fit":
                    pred = res.setdefault("predict", {"first": [], "second": []})
                    pred["first"].append(_run(PREDICT(tmp) + cache))
                    pred["second"] += [_run(PREDICT(tmp) + cache) for _ in range(per_repeat)]
                    line += (f"; predict from it: first {pred['first'][-1]:.2f} s, warm "
                             f"{statistics.median(pred['second'][-per_repeat:]):.2f} s")
                    if keep_fit is not None and k == 0:
                        shutil.copytree(tmp / "fit", keep_fit)
            print(f"{line} (load {_load()})", flush=True)
        res[name] = {"first": first, "second": second}
    return res


_FIT_IN_PROCESS = r"""
import json, statistics, sys, time
from diffguide.cli import main
data, out, cache = sys.argv[1:4]
argv = ["fit", "--preset", "majda2012", "--measurements", data, "--out", out, "--quiet",
        "--cache-dir", cache]
times = []
for _ in range(4):
    t0 = time.perf_counter()
    code = main(argv)
    times.append(time.perf_counter() - t0)
    if code not in (0, 3):
        sys.exit(f"fit failed ({code})")
print(json.dumps({"first": times[0], "steady": times[1:]}))
"""


def bench_fit_in_process() -> dict:
    """``diffguide fit`` run four times in one process (``diffguide.cli.main``, plots included,
    on an empty cache folder): the first call and the next three."""
    with tempfile.TemporaryDirectory(prefix="dg-bench-") as tmp:
        r = _python(_FIT_IN_PROCESS, DATA, Path(tmp) / "fit", Path(tmp) / "cache")
    print(f"  fit in one process: first {r['first']:.1f} s, next "
          f"{statistics.median(r['steady']):.2f} s (load {_load()})", flush=True)
    return r


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


#: the targets (issue 40's acceptance, an idle 2-core machine), by figure
TARGETS = {
    "import": "≤ 0.3 s",
    "help": "≤ 0.3 s",
    "fit first": "≤ 10 s",
    "fit second": "≤ 2 s",
    "fit in-process": "≤ 0.5 s",
    "simulate first": "≤ 5 s",
    "simulate second": "≤ 5 s",
    "predict first": "",
    "predict second": "≤ 1.5 s",
    "predict in-process": "≤ 50 ms",
    "grid in-process": "≤ 2 s",
    "battery case": "≤ 5 s",
    "condense 60x30": "≤ 2 s",
    "condense 100x50": "≤ 10 s",
    "sweep 141": "≤ 5 ms",
}


def table_rows(cli: dict | None, st: dict | None, startup: dict | None = None,
               extra: dict | None = None) -> list[tuple[str, str, str]]:
    """(benchmark, figure, target) rows from :func:`bench_cli`, :func:`bench_steady`,
    :func:`bench_startup` and ``extra``: ``"fit in-process"`` (:func:`bench_fit_in_process`),
    ``"predict in-process"`` (``bench/bench_predict.py --json``'s ``points`` and ``grid``),
    ``"battery"`` (seconds per battery case)."""
    rows = []
    extra = extra or {}
    if startup:
        rows.append(("`python -c \"import diffguide\"`", _fmt(startup["import"]),
                     TARGETS["import"]))
        rows.append(("`diffguide --help`", _fmt(startup["help"]), TARGETS["help"]))
    if cli:
        for name in ("fit", "simulate"):
            rows.append((f"`diffguide {name}` end to end, empty cache",
                         _fmt(cli[name]["first"]), TARGETS[f"{name} first"]))
            rows.append((f"`diffguide {name}` end to end, second run",
                         _fmt(cli[name]["second"]), TARGETS[f"{name} second"]))
    if "fit in-process" in extra:
        r = extra["fit in-process"]
        rows.append(("`diffguide fit` in one process (`diffguide.cli.main`), second call",
                     f"{_fmt(r['steady'])} (first call {r['first']:.1f} s)",
                     TARGETS["fit in-process"]))
    if cli and "predict" in cli:
        rows.append(("`diffguide predict` 2 points × 71 positions, `--z-mm 150`, first run on "
                     "the fit's cache folder", _fmt(cli["predict"]["first"]),
                     TARGETS["predict first"]))
        rows.append(("`diffguide predict` the same, warm (same `--cache-dir`)",
                     _fmt(cli["predict"]["second"]), TARGETS["predict second"]))
    if "predict in-process" in extra:
        r = extra["predict in-process"]
        rows.append(("prediction in one process, 2 new points × 71 positions (fit's sweep "
                     "kept)", _fmt(r["points"], "ms", 1e3), TARGETS["predict in-process"]))
        rows.append(("error map in one process, 21 × 11 grid × 71 positions with σ",
                     _fmt(r["grid"]), TARGETS["grid in-process"]))
    if "battery" in extra:
        r = extra["battery"]
        rows.append((f"battery case (fit and prediction), median of {len(r['seconds'])} "
                     f"({r['source']})", _fmt(r["seconds"]), TARGETS["battery case"]))
    if st:
        for key, r in st.items():
            if key.startswith("condense"):
                mesh = key.split()[1]
                rows.append(
                    (
                        f"condensation {mesh.replace('x', ' × ')}, steady / first call",
                        f"{_fmt(r['steady'])} / {r['first']:.2f} s",
                        TARGETS.get(f"condense {mesh}", ""),
                    )
                )
        r = st["sweep 141"]
        rows.append(
            (
                "141-position sweep, steady state",
                _fmt(r["steady"], "ms", 1e3) + f" (first call {r['first']:.2f} s)",
                TARGETS["sweep 141"],
            )
        )
    return rows


def bench_predict_in_process(fit_dir: Path, repeat: int = 5) -> dict:
    """``bench/bench_predict.py --fit fit_dir --skip-former``'s times (s): ``points`` (2 new
    points x 71 positions, the fit's sweep kept) and ``grid`` (21 x 11 x 71 with σ)."""
    with tempfile.TemporaryDirectory(prefix="dg-bench-") as tmp:
        out = Path(tmp) / "times.json"
        proc = subprocess.run(
            [sys.executable, str(ROOT / "bench" / "bench_predict.py"), "--fit", str(fit_dir),
             "--repeat", str(repeat), "--skip-former", "--json", str(out)],
            capture_output=True, text=True, cwd=ROOT,
        )
        if proc.returncode or not out.exists():
            sys.exit(f"bench_predict.py failed:\n{(proc.stdout + proc.stderr)[-3000:]}")
        r = json.loads(out.read_text(encoding="utf-8"))
    print(f"  in one process: 2 points {1e3 * statistics.median(r['points']):.1f} ms, 21 x 11 "
          f"grid {statistics.median(r['grid']):.2f} s (load {_load()})", flush=True)
    return r


def battery_from_log(log: Path) -> dict:
    """The seconds per battery case in a ``pytest --durations=0`` log
    (:func:`suite_table.per_battery_case`)."""
    sys.path.insert(0, str(ROOT / "bench"))
    from suite_table import per_battery_case

    seconds = per_battery_case(log.read_text(encoding="utf-8", errors="replace"))
    if not seconds:
        sys.exit(f"{log}: no tests/test_battery.py durations (pytest --durations=0)")
    return {"seconds": sorted(seconds.values()), "source": f"cases of `{log.name}`"}


def measure(repeats: int, meshes=MESHES, suite_log: Path | None = None, cli: bool = True,
            steady: bool = True) -> tuple:
    """Every figure: ``(cli, steady, startup, extra)`` for :func:`table_rows`."""
    startup = bench_startup(max(repeats, 5))
    res_cli, st, extra = None, None, {}
    if cli:
        with tempfile.TemporaryDirectory(prefix="dg-bench-") as tmp:
            fit_dir = Path(tmp) / "fit"
            res_cli = bench_cli(repeats, keep_fit=fit_dir)
            extra["predict in-process"] = bench_predict_in_process(fit_dir)
        extra["fit in-process"] = bench_fit_in_process()
    if suite_log is not None:
        extra["battery"] = battery_from_log(suite_log)
    if steady:
        st = bench_steady(meshes)
    return res_cli, st, startup, extra


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=3, help="fresh processes per CLI figure")
    p.add_argument("--skip-cli", action="store_true")
    p.add_argument("--skip-steady", action="store_true")
    p.add_argument("--suite-log", type=Path,
                   help="a 'pytest --durations=0' log: the battery's seconds per case")
    a = p.parse_args()
    load0 = _load()
    print(f"machine: {machine_line()}; load average (1/5/15 min) at start {load0}", flush=True)
    figures = measure(a.repeats, suite_log=a.suite_log, cli=not a.skip_cli,
                      steady=not a.skip_steady)
    print(
        f"\nload average at the end {_load()} (start {load0}); medians (min–max) of "
        f"{a.repeats} fresh processes for the CLI\n"
    )
    print("| benchmark | figure | target |\n|---|---|---|")
    for r in table_rows(*figures):
        print(f"| {r[0]} | {r[1]} | {r[2]} |")


if __name__ == "__main__":
    main()
