"""The cross table's machine file (``io.cross_config``): the preset round-trips, a file's
values land in the right fields (read by TOML, an independent parser), and bad input gives one
line naming the section and key."""

import jax
import numpy as np
import pytest

from diffguide.io.cross_config import (
    cross_config_from_spec,
    cross_spec_from_raw,
    load_cross_config,
)
from diffguide.machine.paper_cross import majda2012_cross_spec


def _leaves_equal(a, b, same_tree=True):
    la, ta = jax.tree_util.tree_flatten(a)
    lb, tb = jax.tree_util.tree_flatten(b)
    assert ta == tb or not same_tree
    assert len(la) == len(lb)
    for x, y in zip(la, lb):
        np.testing.assert_allclose(np.asarray(x, dtype=float), np.asarray(y, dtype=float),
                                   rtol=1e-12, atol=0)


def test_the_preset_round_trips():
    spec = majda2012_cross_spec()
    back = cross_spec_from_raw(cross_config_from_spec(spec))
    # (a file's materials are named "table", as in the one-axis file: the static fields differ)
    _leaves_equal(back, spec, same_tree=False)
    _leaves_equal(cross_spec_from_raw({}), back)  # the defaults are the preset


def test_a_file_sets_both_joints(tmp_path):
    path = tmp_path / "cross.toml"
    path.write_text(
        "[table]\nthickness_mm = 60\n"
        "[saddle]\nthickness_mm = 100\nlength_mm = 600\n"
        "[guideway.y]\nrail_y_mm = [-250, 250]\n"
        "[carriage.y]\npreload_fraction = 0.05\n"
        "[screw.y]\nfree_length_at_ref_mm = 400\n"
        "[machine.y]\nstroke_mm = 400\n"
        "[cross]\nx_guideway_height_mm = 40\n"
    )
    spec = load_cross_config(path)
    assert spec.x.table.thickness == pytest.approx(0.06)
    assert spec.y.table.thickness == pytest.approx(0.1)
    assert spec.y.table.length == pytest.approx(0.6)
    assert spec.y.guideway.rail_y == pytest.approx((-0.25, 0.25))
    assert spec.y.carriage.preload_fraction == pytest.approx(0.05)
    assert spec.x.carriage.preload_fraction == pytest.approx(0.08)  # the X blocks unchanged
    assert spec.y.screw.free_length_at_ref == pytest.approx(0.4)
    assert spec.y.stroke == pytest.approx(0.4)
    assert spec.x_guideway_height == pytest.approx(0.04)


@pytest.mark.parametrize("raw, words", [
    ({"saddle": {"lenght_mm": 600}}, "'saddle.lenght_mm' is unknown"),
    ({"saddle": {"thickness_mm": 0.0}}, "'saddle.thickness_mm'"),
    ({"guideway": {"y": {"rail_y_mm": [-100, 900]}}}, "guideway.y"),
    ({"machine": {"y": {"gravity_m_s2": 9.0}}}, "'machine.y.gravity_m_s2' is unknown"),
    ({"table": {"y": {"length_mm": 1}}}, "[table.y]: unknown section"),
    ({"cross": {"x_guideway_height_mm": 1000}}, "'cross.x_guideway_height_mm'"),
    ({"saddle": {"length_mm": 200}}, "'guideway.y.carriage_x_mm': -200 puts a carriage "
                                     "footprint off the saddle"),
    ({"saddle": {"length_mm": 400}, "guideway": {"rail_y_mm": [-240, 240], "y": {
        "carriage_x_mm": [-100, 100]}}, "table": {"width_mm": 600}}, "off the saddle"),
])
def test_bad_input_names_the_key(raw, words):
    with pytest.raises(ValueError) as info:
        cross_spec_from_raw(raw, "m.toml")
    message = str(info.value)
    assert message.startswith("m.toml") and words in message and "\n" not in message
