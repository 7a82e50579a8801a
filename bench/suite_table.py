"""The test suite's time per module, from pytest's ``--durations=0`` report, into
docs/benchmarks.md (between its SUITE-TABLE markers).

    python -m pytest -q --durations=0 > suite.log; python bench/suite_table.py suite.log
    python bench/suite_table.py suite.log --print    # the table only, the page unchanged

Sums every test's setup, call and teardown per module (pytest's own figures: wall clock inside
the test process, collection and start-up excluded) and writes the table, slowest first, with
the summary line pytest printed (the counts and the whole wall time), the machine and the load
average now (``os.getloadavg()``: the load while the log was made is not in it, so quote a log
made on an idle machine, or say it was not).
"""

import argparse
import collections
import datetime
import os
import re
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
PAGE = HERE.parent / "docs" / "benchmarks.md"
BEGIN, END = "<!-- SUITE-TABLE -->", "<!-- /SUITE-TABLE -->"
#: one line of pytest's durations report: ``12.34s call     tests/test_x.py::test_y[a]``
_LINE = re.compile(r"^\s*([0-9.]+)s\s+(setup|call|teardown)\s+(tests/[^:\s]+)::")
_SUMMARY = re.compile(r"^=*\s*(\d+ (passed|failed).* in [0-9.]+s.*?)\s*=*$")


def per_module(log: str) -> tuple[dict[str, float], str]:
    """``({module path: seconds}, pytest's summary line)`` from a ``--durations=0`` log."""
    seconds: dict[str, float] = collections.defaultdict(float)
    summary = ""
    for line in log.splitlines():
        m = _LINE.match(line)
        if m:
            seconds[m.group(3)] += float(m.group(1))
        s = _SUMMARY.match(line.strip())
        if s:
            summary = s.group(1)
    if not seconds:
        raise ValueError("no '--durations=0' lines in the log (run pytest with --durations=0)")
    return dict(seconds), summary


#: a battery test's line: ``12.3s call  tests/test_battery.py::test_case_returns_a_fit[baseline]``
_BATTERY = re.compile(r"^\s*([0-9.]+)s\s+(?:setup|call|teardown)\s+tests/test_battery\.py::"
                      r"\w+\[(\w+)\]")


def per_battery_case(log: str) -> dict[str, float]:
    """``{case: seconds}`` from a ``--durations=0`` log: every ``tests/test_battery.py`` test of
    a case (parametrised by its name), setup, call and teardown summed (the case's simulation
    and fit, made by the first of its tests, and its prediction and checks)."""
    seconds: dict[str, float] = collections.defaultdict(float)
    for line in log.splitlines():
        m = _BATTERY.match(line)
        if m:
            seconds[m.group(2)] += float(m.group(1))
    return dict(seconds)


def render(seconds: dict[str, float], summary: str, source: str) -> str:
    from pages import cpu_model

    total = sum(seconds.values())
    rows = sorted(seconds.items(), key=lambda kv: -kv[1])
    load = "/".join(f"{v:.2f}" for v in os.getloadavg())
    lines = [
        BEGIN,
        f"Written on {datetime.date.today().isoformat()} by `bench/suite_table.py` from "
        f"`{source}`: pytest's summary `{summary or 'not found'}`; "
        f"{cpu_model()}, {os.cpu_count()} CPUs; load average when the table was written "
        f"{load}.",
        "",
        "| module | seconds | share |",
        "|---|---|---|",
        *(f"| `{name}` | {s:.1f} | {100 * s / total:.1f} % |" for name, s in rows),
        f"| all ({len(rows)} modules) | {total:.1f} | 100 % |",
        END,
    ]
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("log", type=Path, help="pytest's output with --durations=0")
    p.add_argument("--page", type=Path, default=PAGE, help="the Markdown page to update")
    p.add_argument("--print", action="store_true", help="print the table, leave the page")
    a = p.parse_args(argv)
    seconds, summary = per_module(a.log.read_text(encoding="utf-8", errors="replace"))
    table = render(seconds, summary, a.log.name)
    if not a.print:
        from pages import write_between

        write_between(a.page, BEGIN, END, table)
    print(table)


if __name__ == "__main__":
    sys.path.insert(0, str(HERE))
    main()
