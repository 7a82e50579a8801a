"""The cache folder's size limit (diffguide._core.cachedir, the CLI's DIFFGUIDE_CACHE_MAX_MB):
least recently used entries removed first, and nothing but cache entries ever."""

import os
import time

import pytest

from diffguide._core.cachedir import IN_PROGRESS_S, entries, prune, touch
from diffguide.cli import main
from diffguide.cli._runtime import DEFAULT_CACHE_MAX_MB, cache_max_bytes


def _file(path, size, age_s):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"x" * size)
    t = time.time() - age_s
    os.utime(path, (t, t))
    return path


def test_prune_removes_the_least_recently_used_entries_first(tmp_path):
    old = _file(tmp_path / "jit_f-abc-cache", 400, 500)
    table = _file(tmp_path / "tables" / "k1.npz", 300, 400)
    prog = _file(tmp_path / "exports" / "k2.jaxexport", 200, 300)
    out = _file(tmp_path / "exports" / "k2.out", 100, 300)
    new = _file(tmp_path / "jit_g-def-cache", 100, 10)
    touch(table)  # read just now: the most recently used
    order = [p for _, _, p in entries(tmp_path)]
    assert order[0] == old and set(order[1:3]) == {prog, out} and order[3:] == [new, table]
    removed, freed = prune(tmp_path, 450)  # 1100 bytes: the oldest until <= 450 are left
    assert (removed, freed) == (3, 700)
    assert not prog.exists() and not out.exists() and not old.exists()
    assert new.exists() and table.exists()
    assert prune(tmp_path, 10**6) == (0, 0)


def test_prune_never_touches_other_files(tmp_path):
    """A cache folder named by the user may hold anything: only cache entries go."""
    keep = [
        _file(tmp_path / "notes.txt", 500, 10**6),
        _file(tmp_path / "tables" / "readme.md", 500, 10**6),
        _file(tmp_path / "exports" / "data.csv", 500, 10**6),
        _file(tmp_path / "other" / "x-cache", 500, 10**6),  # not a cache sub-folder
        _file(tmp_path / "tables" / ".k.npz", 500, IN_PROGRESS_S / 2),  # a write in progress
    ]
    stale = _file(tmp_path / "tables" / ".k2.npz", 500, 2 * IN_PROGRESS_S)  # a crashed write
    assert prune(tmp_path, 0) == (1, 500)
    assert all(p.exists() for p in keep) and not stale.exists()


def test_cache_limit_from_the_environment(monkeypatch, tmp_path, capsys):
    monkeypatch.delenv("DIFFGUIDE_CACHE_MAX_MB", raising=False)
    assert cache_max_bytes() == int(DEFAULT_CACHE_MAX_MB * 2**20)
    monkeypatch.setenv("DIFFGUIDE_CACHE_MAX_MB", "0.5")
    assert cache_max_bytes() == 2**19
    for bad in ("0", "-3", "lots", "nan", "inf"):
        monkeypatch.setenv("DIFFGUIDE_CACHE_MAX_MB", bad)
        with pytest.raises(ValueError, match="DIFFGUIDE_CACHE_MAX_MB"):
            cache_max_bytes()
    # a command: one line, exit 2, nothing written
    out = tmp_path / "s.csv"
    args = ["stiffness", "--steps", "3", "--out", str(out), "--cache-dir", str(tmp_path / "c")]
    assert main(args) == 2
    assert "DIFFGUIDE_CACHE_MAX_MB" in capsys.readouterr().err and not out.exists()


def test_a_command_keeps_its_cache_under_the_limit(monkeypatch, tmp_path):
    folder = tmp_path / "cache"
    stale = _file(folder / "tables" / "old.npz", 3 * 2**20, 10**5)
    monkeypatch.setenv("DIFFGUIDE_CACHE_MAX_MB", "2")
    out = tmp_path / "s.csv"
    assert main(["stiffness", "--steps", "3", "--out", str(out), "--cache-dir", str(folder)]) == 0
    assert out.exists() and not stale.exists()
