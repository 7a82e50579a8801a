"""The API reference builds from the docstrings (the README's command)."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]


def test_api_reference_builds(tmp_path):
    pytest.importorskip("pdoc")
    proc = subprocess.run(
        [sys.executable, str(ROOT / "docs" / "build_api.py"), str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (tmp_path / "index.html").exists()
    top = (tmp_path / "diffguide.html").read_text()
    for name in ("joint_errors", "fit_rails", "majda2012_machine", "read_measurements"):
        assert name in top, name
    for page in ("machine/kinematics", "inverse/fit", "plotting/errors", "guideway/rails"):
        assert (tmp_path / "diffguide" / f"{page}.html").exists(), page
