"""Regenerate the benchmark table in docs/benchmarks.md (between its BENCH-TABLE markers).

    python bench/make_table.py                       # 3 fresh processes per figure (~4 min idle)
    python bench/make_table.py --quick               # 1 each, no 100 × 50 condensation (~2 min)
    python bench/make_table.py --suite-log suite.log # with the battery's seconds per case

Runs the benchmarks of ``bench/bench_cli.py`` (:func:`bench_cli.measure`): ``import diffguide``
and ``diffguide --help``; end-to-end ``diffguide fit`` and ``simulate``, first and second run;
``diffguide predict`` from the fit (2 points x 71 positions), first and warm (5 warm runs in
all); ``diffguide fit`` called again in one process; the prediction and the 21 x 11 error map
in one process (``bench/bench_predict.py``); the battery's median case (from a suite log's
``--durations=0``); table condensation; the 141-position sweep. Each row carries its target
(:data:`bench_cli.TARGETS`). The table is written with the machine (CPU model,
``os.cpu_count()``, system), the versions, the date and the load average before and after, so
that every figure is quoted with what it was measured on.
"""

import argparse
import datetime
import os
import platform
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PAGE = ROOT / "docs" / "benchmarks.md"
BEGIN, END = "<!-- BENCH-TABLE -->", "<!-- /BENCH-TABLE -->"

sys.path.insert(0, str(HERE))
import bench_cli  # noqa: E402
from pages import cpu_model, write_between  # noqa: E402


def versions() -> str:
    from importlib.metadata import PackageNotFoundError, version

    out = []
    for name in ("diffguide", "jax", "jaxlib", "equinox", "numpy"):
        try:
            out.append(f"{name} {version(name)}")
        except PackageNotFoundError:
            if name == "diffguide":
                import diffguide

                out.append(f"diffguide {diffguide.__version__}")
    return ", ".join(out)


def render(rows, *, quick: bool, repeats: int, load0: str, load1: str) -> str:
    mode = (
        "quick mode (`--quick`: one fresh process per command-line figure, 5 warm predictions, "
        "no 100 × 50 condensation)"
        if quick
        else f"medians (min–max) of {repeats} fresh processes per command-line figure"
    )
    lines = [
        BEGIN,
        f"Measured on {datetime.date.today().isoformat()} by `bench/make_table.py`, {mode}.",
        "",
        f"- machine: {cpu_model()}, {os.cpu_count()} CPUs (`os.cpu_count()`), "
        f"{platform.system()} {platform.release()}",
        f"- Python {platform.python_version()}; {versions()}",
        f"- load average (1/5/15 min) at the start {load0}, at the end {load1}",
        "",
        "| benchmark | figure | target |",
        "|---|---|---|",
        *(f"| {a} | {b} | {c} |" for a, b, c in rows),
        END,
    ]
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="one process per figure, small meshes")
    p.add_argument("--repeats", type=int, default=3, help="fresh processes per CLI figure")
    p.add_argument("--page", type=Path, default=PAGE, help="the Markdown page to update")
    p.add_argument("--suite-log", type=Path,
                   help="a 'pytest --durations=0' log of the suite: the battery's seconds per "
                   "case (its row is left out without it)")
    a = p.parse_args(argv)
    repeats = 1 if a.quick else a.repeats
    meshes = bench_cli.MESHES[:2] if a.quick else bench_cli.MESHES
    load0 = bench_cli._load()
    figures = bench_cli.measure(repeats, meshes, a.suite_log)
    table = render(
        bench_cli.table_rows(*figures),
        quick=a.quick,
        repeats=repeats,
        load0=load0,
        load1=bench_cli._load(),
    )
    write_between(a.page, BEGIN, END, table)
    print(table)


if __name__ == "__main__":
    main()
