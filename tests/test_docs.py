"""The documentation site builds without a warning, and its examples run as written.

``mkdocs build --strict`` (mkdocs.yml at the repository root, pages in docs/, the API reference
from the docstrings by mkdocstrings) must log no warning at all: broken links, missing anchors,
docstrings griffe cannot parse. The site must need no network to view: no script or stylesheet
from another host.
"""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted((ROOT / "docs").glob("*.md"))


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    pytest.importorskip("mkdocs")
    pytest.importorskip("mkdocstrings_handlers.python")
    out = tmp_path_factory.mktemp("site")
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"),
         "-d", str(out)],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=ROOT,  # mkdocs.yml names its griffe extension relative to the repository root
    )
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log[-3000:]
    return out, log


def test_the_site_builds_with_no_warning(site):
    out, log = site
    warnings = [line for line in log.splitlines() if "WARNING" in line or "ERROR" in line]
    assert not warnings, "\n".join(warnings[:20])
    for page in ("index", "user-guide", "file-formats", "theory", "validation", "benchmarks",
                 "test-matrix", "notebooks", "api"):
        path = out / "index.html" if page == "index" else out / page / "index.html"
        assert path.exists(), page


def test_the_site_needs_no_network(site):
    out, _ = site
    remote = re.compile(
        r"<(?:script|img)[^>]*\bsrc=\"(?:https?:)?//|<link[^>]*\bhref=\"(?:https?:)?//"
    )
    for html in out.rglob("*.html"):
        match = remote.search(html.read_text(encoding="utf-8"))
        assert match is None, f"{html.relative_to(out)}: {match.group(0)}"


def test_the_api_page_names_the_main_entry_points(site):
    out, _ = site
    api = (out / "api" / "index.html").read_text(encoding="utf-8")
    for name in ("joint_errors", "fit_rails", "majda2012_machine", "read_measurements",
                 "HertzBall", "MachineSpec"):
        assert re.search(rf'id="diffguide\.[\w.]*{name}"', api), name


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_the_python_examples_of_each_page_run(page, monkeypatch):
    """Every ```python block of a page runs, in order, in one namespace (```text, ```bash and
    any other fence are not run)."""
    text = page.read_text(encoding="utf-8")
    blocks = re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)
    if not blocks:
        pytest.skip("no Python examples")
    monkeypatch.chdir(ROOT)  # the examples read data/ relative to the repository
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, str(page.relative_to(ROOT)), "exec"), namespace)
