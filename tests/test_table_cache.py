"""The disk cache of condensed tables (diffguide.fe.cache): a table read back equals the one
computed without the cache (bit for bit), any change of the inputs misses, a damaged file is
ignored and rewritten, and nothing is written without a folder (the library default)."""

import dataclasses
import io

import equinox as eqx
import jax
import numpy as np
import pytest

from diffguide._core import cacheentry
from diffguide._core.caches import Caches, CacheWarning
from diffguide.fe import Rib
from diffguide.fe import cache as table_cache
from diffguide.machine.majda2012 import majda2012_table

FIELDS = ("K", "f", "R", "r0", "node_modes", "node_u0", "ref_points", "nodes")


@pytest.fixture
def caches(tmp_path):
    with Caches(tables=tmp_path / "tables") as c:
        yield c


@pytest.fixture
def folder(caches):
    return caches.tables


def _equal(a, b):
    return all(np.array_equal(np.asarray(getattr(a, k)), np.asarray(getattr(b, k))) for k in FIELDS)


def _files(folder):
    return sorted(folder.glob("*.npz")) if folder.exists() else []


def test_cached_table_equals_fresh_and_changes_miss(caches, folder):
    tm = majda2012_table(6, 3)
    with Caches():  # caches without a table folder: computed
        fresh = tm.condense()
    assert not _files(folder)
    first = tm.condense()  # computed and written
    assert len(_files(folder)) == 1
    assert caches.table_stats == {"hits": 0, "misses": 1, "writes": 1, "damaged": 0}
    again = tm.condense()  # read back
    assert caches.table_stats["hits"] == 1
    assert _equal(fresh, first) and _equal(fresh, again)
    # a changed thickness, material, mesh, rib, gravity or method: another key
    variants = [
        majda2012_table(6, 3, thickness=0.041),
        majda2012_table(7, 3),
        majda2012_table(6, 3, ribs=[Rib("x", 0.0, 0.03, 0.05)]),
    ]
    keys = {table_cache.table_key("t", tm)}
    for v in variants:
        keys.add(table_cache.table_key("t", v))
    E = tm.plate.material.E
    keys.add(table_cache.table_key("t", eqx.tree_at(lambda m: m.plate.material.E, tm, E * 1.01)))
    keys.add(table_cache.table_key("t", dataclasses.replace(tm, gravity=9.80)))
    assert len(keys) == 6
    thicker = variants[0].condense()
    assert len(_files(folder)) == 2
    assert not np.allclose(np.asarray(thicker.K), np.asarray(fresh.K))
    assert not _equal(thicker, again)


def test_damaged_file_is_ignored_and_rewritten(folder):
    tm = majda2012_table(6, 3)
    good = tm.condense()
    (path,) = _files(folder)
    path.write_bytes(b"not an npz")
    with pytest.warns(CacheWarning, match="was damaged"):
        again = tm.condense()  # recomputed, not an error
    assert _equal(good, again)
    key = path.name.removesuffix(".npz")
    _, payload = cacheentry.read(path, table_cache._KIND, key, table_cache.FORMAT)
    with np.load(io.BytesIO(payload)) as z:  # rewritten whole
        assert set(FIELDS) <= set(z.files)
    # a file holding another key under this name: ignored too
    other = majda2012_table(6, 3, thickness=0.045).condense()
    (p2,) = [p for p in _files(folder) if p != path]
    p2.write_bytes(path.read_bytes())
    with pytest.warns(CacheWarning, match="key"):
        assert _equal(majda2012_table(6, 3, thickness=0.045).condense(), other)


def test_no_folder_no_files_and_traced_inputs_bypass(tmp_path):
    majda2012_table(6, 3).condense()  # no active caches (the library default): nothing written
    assert not list(tmp_path.rglob("*.npz"))
    with Caches(tables=tmp_path) as caches:
        tm = majda2012_table(6, 3)

        def k00(t):
            return eqx.tree_at(lambda m: m.plate.thickness, tm, t).condense().K[0, 0]

        g = jax.grad(k00)(0.04)  # traced thickness: no lookup, no write
        assert np.isfinite(g) and not list(tmp_path.rglob("*.npz"))
    assert caches.table_stats == {"hits": 0, "misses": 0, "writes": 0, "damaged": 0}
