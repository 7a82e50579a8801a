"""The documentation site builds without a warning, and its examples run as written.

``mkdocs build --strict`` (mkdocs.yml at the repository root, pages in docs/, the API reference
from the docstrings by mkdocstrings) must log no warning at all: broken links, missing anchors,
docstrings griffe cannot parse. The site must need no network to view: no script or stylesheet
from another host.
"""

import ast
import datetime
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


KAC_SECTIONS = ("Added", "Changed", "Deprecated", "Removed", "Fixed", "Security")


def test_the_changelog_is_kept_by_release():
    """CHANGELOG.md follows Keep a Changelog 1.1.0: releases newest first, each headed
    ``## [X.Y.Z] - YYYY-MM-DD`` (or ``- Unreleased`` for the next one only), holding only the six
    standard sections, each at most once and in the standard order; the newest release is the
    package's version or the next one after it; nothing is grouped by internal work sessions."""
    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    assert "session" not in text.lower()
    source = (ROOT / "src" / "diffguide" / "_core" / "version.py").read_text(encoding="utf-8")
    version = next(
        node.value.value for node in ast.parse(source).body
        if isinstance(node, ast.Assign) and node.targets[0].id == "__version__"
    )
    current = tuple(int(part) for part in version.split("."))

    release = re.compile(r"## \[(\d+)\.(\d+)\.(\d+)\] - (\d{4}-\d{2}-\d{2}|Unreleased)")
    releases = []  # [(version tuple, date or None, [section names])]
    for number, line in enumerate(text.splitlines(), 1):
        if line.startswith("## "):
            match = release.fullmatch(line)
            assert match, f"CHANGELOG.md:{number}: release heading {line!r}"
            date = match.group(4)
            when = None if date == "Unreleased" else datetime.date.fromisoformat(date)
            releases.append((tuple(int(g) for g in match.group(1, 2, 3)), when, []))
        elif line.startswith("### "):
            assert releases, f"CHANGELOG.md:{number}: a section before the first release"
            name = line[4:]
            assert name in KAC_SECTIONS, f"CHANGELOG.md:{number}: section {name!r}"
            releases[-1][2].append(name)
        elif line.startswith("#") and number > 1:
            raise AssertionError(f"CHANGELOG.md:{number}: heading {line!r}")
    assert text.startswith("# Changelog\n")
    assert releases, "no release heading"

    for (newer, newer_date, _), (older, older_date, _) in zip(releases, releases[1:]):
        assert newer > older, f"{newer} listed above {older}"
        assert older_date is not None, f"{older} is below a newer release but unreleased"
        if newer_date is not None:
            assert newer_date >= older_date, f"{newer} dated before {older}"
    for number, _, sections in releases:
        assert len(set(sections)) == len(sections), f"{number}: a section twice"
        order = [KAC_SECTIONS.index(name) for name in sections]
        assert order == sorted(order), f"{number}: sections out of order {sections}"

    newest, newest_date, _ = releases[0]
    major, minor, patch = current
    following = {(major, minor, patch + 1), (major, minor + 1, 0), (major + 1, 0, 0)}
    if newest_date is None:
        assert newest in following | {current}, f"Unreleased {newest} after version {version}"
    else:
        assert newest == current, f"newest release {newest}, version {version}"


def test_the_machine_file_key_list_is_the_schemas():
    """docs/file-formats.md's list of machine-file keys is what ``docs/config_keys.py`` writes
    from the table that validation, ``diffguide config`` and ``--explain`` read
    (:mod:`diffguide.io.config_spec`), so it cannot drift from them; and every key a default
    configuration holds is listed (read here from the configuration, not the table)."""
    import importlib.util

    from diffguide.io.config import default_config

    spec = importlib.util.spec_from_file_location("config_keys", ROOT / "docs" / "config_keys.py")
    writer = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(writer)
    assert writer.main(["--check"]) == 0, "docs/file-formats.md is stale: docs/config_keys.py"
    page = (ROOT / "docs" / "file-formats.md").read_text(encoding="utf-8")
    block = page.split(writer.BEGIN, 1)[1].split(writer.END, 1)[0]
    for section, body in default_config().items():
        if isinstance(body, dict) and section not in ("points", "export"):
            for key in body:
                assert f"| `{key}` |" in block, f"[{section}] {key}"
