"""The README is a manual: short, its links resolve, its Python examples run as written."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def test_readme_is_short():
    """Results, validation, benchmarks and history live in docs/ and the CHANGELOG."""
    assert len(README.splitlines()) <= 300


def test_readme_relative_links_point_to_files():
    targets = re.findall(r"\]\(([^)\s]+)\)", README)
    relative = [t.split("#")[0] for t in targets if not re.match(r"[a-z]+:|#", t)]
    assert relative  # the docs pages, the figure, the licence
    missing = [t for t in relative if not (ROOT / t).exists()]
    assert not missing, missing


def test_readme_python_examples_run(monkeypatch):
    blocks = re.findall(r"```python\n(.*?)```", README, flags=re.S)
    assert len(blocks) >= 2
    monkeypatch.chdir(ROOT)  # the examples read data/ relative to the repository
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, "README.md", "exec"), namespace)
    assert namespace["je"].user_units().shape == (141, 5, 6)
    assert namespace["fit"].converged
