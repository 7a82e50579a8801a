"""Damage to JAX's persistent compilation cache that JAX does not see itself
(:mod:`diffguide._core.jaxentries`): two entries swapped — JAX would load each and run the other
function's program (reproduced with ``jit(sin)``/``jit(cos)``: each returned the other's values,
exit 0, no warning) — and a directory in an entry's place (JAX warned on every run and never
wrote the entry again). The next run removes them, says so in one line, and JAX compiles and
writes them afresh. In process, on entries made with JAX's own compression."""

import os
import warnings

import pytest

from diffguide._core import jaxentries
from diffguide._core.cachedir import drop_jax_entries
from diffguide._core.caches import CacheWarning

compress = pytest.importorskip("jax._src.compilation_cache").compress_executable
HASH = {"jit_f": "a" * 64, "jit_fit": "b" * 64, "jit_g": "c" * 64}


def _entries(folder, modules=tuple(HASH)):
    """Entries whose programs name their module (``jit_fit`` contains ``jit_f``)."""
    paths = {}
    for module in modules:
        h = HASH[module]
        p = folder / f"{module}-{h}-cache"
        p.write_bytes(compress(b"\x00HloModule " + module.encode() + b", entry=main\x00" * 3
                               + os.urandom(64)))
        paths[module] = p
    return paths


def _check(folder):
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        removed = jaxentries.check(folder)
    return removed, [str(w.message) for w in said if issubclass(w.category, CacheWarning)]


def _swap(a, b):
    tmp = a.with_name("swap.tmp")
    os.rename(a, tmp)
    os.rename(b, a)
    os.rename(tmp, b)


def test_clean_entries_pass_and_are_recorded(tmp_path):
    _entries(tmp_path)
    assert _check(tmp_path) == ([], [])
    assert len((tmp_path / jaxentries.LEDGER).read_text().splitlines()) == 3
    assert _check(tmp_path) == ([], [])  # the second time: a stat each, nothing said


@pytest.mark.parametrize("recorded", [False, True])
def test_swapped_entries_are_removed_with_one_note(tmp_path, recorded):
    paths = _entries(tmp_path)
    if recorded:  # the ledger knows what each held: a content of another entry is a swap
        _check(tmp_path)
    _swap(paths["jit_f"], paths["jit_g"])
    removed, said = _check(tmp_path)
    assert sorted(p.name for p, _ in removed) == sorted(paths[m].name for m in ("jit_f", "jit_g"))
    assert not paths["jit_f"].exists() and not paths["jit_g"].exists()
    assert paths["jit_fit"].exists()  # untouched
    assert len(said) == 1 and "2 JAX compilation cache entries" in said[0]
    assert ("holds the program of" if recorded else "another module's program") in said[0]
    assert said[0].endswith("removed, compiled again")
    # JAX writes them afresh: the next check takes them as new and clean
    _entries(tmp_path, ("jit_f", "jit_g"))
    assert _check(tmp_path) == ([], [])


def test_a_directory_in_an_entrys_place_is_removed(tmp_path):
    paths = _entries(tmp_path)
    paths["jit_g"].unlink()
    paths["jit_g"].mkdir()
    (paths["jit_g"] / "junk").write_text("x")
    removed, said = _check(tmp_path)
    assert [(p.name, why) for p, why in removed] == [(paths["jit_g"].name,
                                                      "a directory in its place")]
    assert not paths["jit_g"].exists() and len(said) == 1
    # and where JAX reported it first (its read error), the directory goes too
    paths["jit_f"].unlink()
    paths["jit_f"].mkdir()
    assert [p for p, _ in drop_jax_entries(tmp_path, "jit_f")] == [paths["jit_f"]]
    assert not paths["jit_f"].exists()


def test_an_entry_rewritten_in_place_is_removed(tmp_path):
    paths = _entries(tmp_path)
    _check(tmp_path)
    paths["jit_fit"].write_bytes(compress(b"HloModule jit_fit, other" * 9))
    removed, said = _check(tmp_path)
    assert [p for p, _ in removed] == [paths["jit_fit"]] and "content changed" in said[0]
