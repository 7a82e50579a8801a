"""docs/test-matrix.md's tests per module (written by bench/test_matrix.py) are the suite's as
pytest collects it now, so that the page cannot go stale."""

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_test_matrix_counts_match_the_collection():
    """docs/test-matrix.md's tests per module (written by bench/test_matrix.py) are the
    suite's as pytest collects it now: counted here from ``--collect-only -q`` (collection
    only, no test runs) and read from the page's table by this test's own parsing. After adding
    or removing tests: ``python bench/test_matrix.py``."""
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:xdist", "-p",
         "no:cacheprovider"],
        capture_output=True, text=True, cwd=ROOT, timeout=600,
        env={k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"},  # e.g. -n, --lf
    )
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    collected: dict[str, int] = {}
    for line in proc.stdout.splitlines():
        if line.startswith("tests/") and "::" in line:
            module = line.split("::", 1)[0]
            collected[module] = collected.get(module, 0) + 1
    tail = re.search(r"(\d+)/\d+ tests collected \((\d+) deselected\)", proc.stdout)
    page = (ROOT / "docs" / "test-matrix.md").read_text(encoding="utf-8")
    block = page.split("<!-- TEST-COUNTS -->", 1)[1].split("<!-- /TEST-COUNTS -->", 1)[0]
    listed = {m: int(n) for m, n in re.findall(r"^\| `(tests/[^`]+)` \| (\d+) \|$", block, re.M)}
    stale = {m: (listed.get(m), n) for m, n in {**listed, **collected}.items()
             if listed.get(m) != collected.get(m)}
    assert not stale, f"docs/test-matrix.md (page, collected): {stale}; run bench/test_matrix.py"
    total = sum(collected.values())
    assert f"**{total} tests** in {len(collected)} modules" in block
    assert f"| all ({len(collected)} modules) | {total} |" in block
    if tail:  # the slow tests, deselected by pyproject.toml's addopts
        assert int(tail.group(1)) == total
        assert f"and {tail.group(2)} more marked `slow`" in block
