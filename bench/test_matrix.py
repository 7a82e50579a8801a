"""Regenerate docs/test-matrix.md's generated parts: the tests per module (between its
TEST-COUNTS markers) and the stacks the whole suite was run on (between its TEST-MATRIX markers).

    python bench/test_matrix.py                    # the counts, from pytest --collect-only -q
    python bench/test_matrix.py --log suite.log    # and this stack's row, from a whole-suite log
    python bench/test_matrix.py --python .venv-newest/bin/python --log newest.log
    python bench/test_matrix.py --print            # print both parts, leave the page

The counts come from ``pytest --collect-only -q`` (run by ``--python``, default this
interpreter, in the repository root): one line ``tests/test_x.py::test_y[...]`` per test of the
default suite (the ``slow`` ones are deselected by ``pyproject.toml``'s ``addopts`` and counted
from pytest's summary line). They hold no date or version, so that
``tests/test_test_matrix.py`` can require the committed page to match the collection (it
counts by its own parsing).

A row of the matrix is one stack (Python, jax, jaxlib, equinox, numpy of ``--python``) and the
summary line of a whole-suite run on it (``--log``: pytest's output, e.g. ``.ci/run``'s or
``python -m pytest -q > suite.log``), with the date the row was written; a row of the same stack
is replaced, the other rows are kept.
"""

import argparse
import collections
import datetime
import json
import os
import re
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PAGE = ROOT / "docs" / "test-matrix.md"
COUNTS = "<!-- TEST-COUNTS -->", "<!-- /TEST-COUNTS -->"
MATRIX = "<!-- TEST-MATRIX -->", "<!-- /TEST-MATRIX -->"
STACK = ("Python", "jax", "jaxlib", "equinox", "numpy")
HEADER = (*STACK, "date", "result")
#: a test id of ``--collect-only -q``: ``tests/test_x.py::test_y[a]``
_TEST = re.compile(r"^(tests/[^:\s]+\.py)::\S")
#: pytest's last collection line: ``1345/1362 tests collected (17 deselected) in 11.85s``
_COLLECTED = re.compile(r"^(\d+)(?:/(\d+))? tests? collected(?: \((\d+) deselected\))?")
_VERSIONS = (
    "import json, platform\n"
    "from importlib.metadata import version\n"
    "print(json.dumps([platform.python_version()] + [version(d) for d in "
    "('jax', 'jaxlib', 'equinox', 'numpy')]))"
)


def collect(python: str = sys.executable) -> tuple[dict[str, int], int]:
    """``({module: tests of the default suite}, tests deselected)`` from ``pytest --collect-only
    -q`` run by ``python`` in the repository root; exits with pytest's output if it fails."""
    proc = subprocess.run(
        [python, "-m", "pytest", "--collect-only", "-q", "-p", "no:xdist", "-p",
         "no:cacheprovider"],
        capture_output=True, text=True, cwd=ROOT,
        env={k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"},  # e.g. -n, --lf
    )
    counts: dict[str, int] = collections.Counter()
    deselected = None
    for line in proc.stdout.splitlines():
        m = _TEST.match(line)
        if m:
            counts[m.group(1)] += 1
        c = _COLLECTED.match(line.strip())
        if c:
            deselected = int(c.group(3) or 0)
    if proc.returncode != 0 or deselected is None or not counts:
        sys.exit(f"pytest --collect-only failed ({proc.returncode}):\n"
                 f"{(proc.stdout + proc.stderr)[-3000:]}")
    return dict(sorted(counts.items())), deselected


def render_counts(counts: dict[str, int], deselected: int) -> str:
    """The TEST-COUNTS block: the total, then one row per module (alphabetical)."""
    total = sum(counts.values())
    return "\n".join([
        COUNTS[0],
        f"Written by `bench/test_matrix.py` from `pytest --collect-only -q`: **{total} tests** "
        f"in {len(counts)} modules in the default suite, and {deselected} more marked `slow` "
        "(run with `-m slow`).",
        "",
        "| module | tests |",
        "|---|---|",
        *(f"| `{name}` | {n} |" for name, n in counts.items()),
        f"| all ({len(counts)} modules) | {total} |",
        COUNTS[1],
    ])


def stack(python: str = sys.executable) -> tuple[str, ...]:
    """The versions of :data:`STACK` in the environment of ``python``."""
    out = subprocess.run([python, "-c", _VERSIONS], capture_output=True, text=True, check=True)
    return tuple(json.loads(out.stdout))


def summary(log: str) -> str:
    """pytest's final summary line in ``log`` (``1325 passed, 11 skipped ... in 890.25s``)."""
    from suite_table import _SUMMARY

    found = [s.group(1) for s in map(_SUMMARY.match, (x.strip() for x in log.splitlines())) if s]
    if not found:
        raise ValueError("no pytest summary line ('N passed ... in S s') in the log")
    return found[-1]


def matrix_rows(page_text: str) -> list[tuple[str, ...]]:
    """The rows of the TEST-MATRIX table of the page (without its header)."""
    block = page_text.split(MATRIX[0], 1)[-1].split(MATRIX[1], 1)[0]
    rows = []
    for line in block.splitlines():
        cells = tuple(c.strip() for c in line.strip().strip("|").split("|"))
        if line.startswith("|") and len(cells) == len(HEADER) and cells != HEADER \
                and not set(cells[0]) <= set("-: "):
            rows.append(cells)
    return rows


def render_matrix(rows: list[tuple[str, ...]]) -> str:
    """The TEST-MATRIX block, newest Python and jax first."""
    def order(r):
        return tuple(tuple(int(p) if p.isdigit() else 0 for p in v.split(".")) for v in r[:2])

    return "\n".join([
        MATRIX[0],
        "| " + " | ".join(HEADER) + " |",
        "|" + "---|" * len(HEADER),
        *("| " + " | ".join(r) + " |" for r in sorted(rows, key=order, reverse=True)),
        MATRIX[1],
    ])


def with_row(rows: list[tuple[str, ...]], versions: tuple[str, ...], result: str,
             date: str) -> list[tuple[str, ...]]:
    """``rows`` with the row of the stack ``versions`` replaced (or added)."""
    return [r for r in rows if r[:len(STACK)] != versions] + [(*versions, date, result)]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--python", default=sys.executable,
                   help="the interpreter of the stack (default: this one)")
    p.add_argument("--log", type=Path, help="a whole-suite pytest log of that stack: its row")
    p.add_argument("--note", default="", help="appended to the row's result (with --log)")
    p.add_argument("--page", type=Path, default=PAGE, help="the Markdown page to update")
    p.add_argument("--print", action="store_true", help="print the parts, leave the page")
    a = p.parse_args(argv)
    text = a.page.read_text(encoding="utf-8")
    parts = [render_counts(*collect(a.python))]
    if a.log:
        result = summary(a.log.read_text(encoding="utf-8", errors="replace"))
        result += f"; {a.note}" if a.note else ""
        rows = with_row(matrix_rows(text), stack(a.python), result,
                        datetime.date.today().isoformat())
        parts.append(render_matrix(rows))
    if not a.print:
        from pages import write_between

        write_between(a.page, *COUNTS, parts[0])
        if a.log:
            write_between(a.page, *MATRIX, parts[1])
    print("\n\n".join(parts))


if __name__ == "__main__":
    sys.path.insert(0, str(HERE))
    main()
