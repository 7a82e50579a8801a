"""Regenerate the benchmark table in docs/benchmarks.md (between its BENCH-TABLE markers).

    python bench/make_table.py            # bench_cli.py's figures, 3 fresh processes each
    python bench/make_table.py --quick    # 1 process each, no 100 × 50 condensation (~1 min idle)

Runs the benchmarks of ``bench/bench_cli.py`` (end-to-end ``diffguide fit`` and ``simulate``,
first and second run; table condensation; the 141-position sweep) and writes the table with the
machine (CPU model, ``os.cpu_count()``, system), the versions, the date and the load average
before and after, so that every figure is quoted with what it was measured on.
"""

import argparse
import datetime
import os
import platform
import re
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PAGE = ROOT / "docs" / "benchmarks.md"
BEGIN, END = "<!-- BENCH-TABLE -->", "<!-- /BENCH-TABLE -->"

sys.path.insert(0, str(HERE))
import bench_cli  # noqa: E402


def cpu_model() -> str:
    """The CPU's model name (Linux ``/proc/cpuinfo``), else ``platform.processor()``."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


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
        "quick mode (`--quick`: one fresh process per command-line figure, no 100 × 50 "
        "condensation)"
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
    a = p.parse_args(argv)
    repeats = 1 if a.quick else a.repeats
    meshes = bench_cli.MESHES[:2] if a.quick else bench_cli.MESHES
    load0 = bench_cli._load()
    startup = bench_cli.bench_startup(max(repeats, 5))
    cli = bench_cli.bench_cli(repeats)
    st = bench_cli.bench_steady(meshes)
    table = render(
        bench_cli.table_rows(cli, st, startup),
        quick=a.quick,
        repeats=repeats,
        load0=load0,
        load1=bench_cli._load(),
    )
    text = a.page.read_text(encoding="utf-8")
    pattern = re.compile(re.escape(BEGIN) + ".*?" + re.escape(END), re.S)
    if not pattern.search(text):
        sys.exit(f"{a.page}: no {BEGIN} ... {END} markers")
    a.page.write_text(pattern.sub(lambda _: table, text), encoding="utf-8")
    print(table)


if __name__ == "__main__":
    main()
