"""The historical construction paths of the ``majda2012`` preset build the same objects.

diffguide 0.1 had two ways to the paper's machine: the preset functions
(``majda2012_machine()``, ``majda2012_carriage()``, ``majda2012_table()``) and the
configuration path (``build_machine(spec_from_config(default_config()))``, ``carriage_from_config``,
``table_from_config``). These tests pinned that they agree leaf by leaf before the two were
unified; both now start from ``diffguide.presets.majda2012()`` (the configuration path through
its TOML mapping, ``io.config.KEYS``), and the tests keep that mapping faithful.
"""

import dataclasses

import equinox as eqx
import jax
import numpy as np

from diffguide.guideway import majda2012_carriage
from diffguide.io.config import (
    carriage_from_config,
    default_config,
    spec_from_config,
    table_from_config,
)
from diffguide.machine.build import build_machine
from diffguide.machine.majda2012 import majda2012_machine, majda2012_table


def assert_same_tree(a, b, rtol=1e-12):
    """Same structure (static fields included) and every leaf equal to ``rtol`` of its size."""
    la, ta = jax.tree_util.tree_flatten(a)
    lb, tb = jax.tree_util.tree_flatten(b)
    assert ta == tb
    assert len(la) > 0
    for x, y in zip(la, lb):
        x, y = np.asarray(x), np.asarray(y)
        assert x.shape == y.shape and x.dtype.kind == y.dtype.kind
        scale = max(float(np.max(np.abs(x), initial=0.0)), 1e-300)
        np.testing.assert_allclose(x, y, rtol=0, atol=rtol * scale)


def test_machine_paths_agree():
    cfg = default_config()
    a = majda2012_machine(nx=6, ny=4)
    b = build_machine(spec_from_config(cfg), nx=6, ny=4)
    assert_same_tree(a, b)
    assert eqx.tree_equal(a.point_names, b.point_names)


def test_rivin_machine_paths_agree():
    cfg = default_config()
    cfg["carriage"]["law"] = "rivin"
    assert_same_tree(majda2012_machine(nx=4, ny=2, law="rivin"),
                     build_machine(spec_from_config(cfg), nx=4, ny=2))


def test_carriage_paths_agree():
    for law in ("hertz", "rivin"):
        cfg = default_config()
        cfg["carriage"]["law"] = law
        assert_same_tree(majda2012_carriage(law), carriage_from_config(cfg))


def test_table_paths_agree():
    a = majda2012_table(6, 4)
    b = table_from_config(default_config(), nx=6, ny=4)
    # the only difference is the material's label (a static string): "cast iron" vs "table"
    relabelled = dataclasses.replace(b.plate.material, name=a.plate.material.name)
    b = eqx.tree_at(lambda t: t.plate.material, b, relabelled)
    assert_same_tree(a, b)


def test_subpackages_are_attributes_of_a_fresh_import():
    """``diffguide.presets.majda2012()`` works in a fresh session, whatever was touched before
    (a subpackage is imported on first attribute access), and the structure classes are part of
    the top-level API."""
    import subprocess
    import sys

    code = (
        "import diffguide, sys\n"
        "assert 'jax' not in sys.modules\n"
        "spec = diffguide.presets.majda2012()\n"
        "assert type(spec).__name__ == 'MachineSpec'\n"
        "assert diffguide.io.config.spec_from_config is not None\n"
        "from diffguide import MachineFamily, Prior, StructurePriors\n"
        "assert Prior(0.05, 0.025, 0.1).sigma_log > 0\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
