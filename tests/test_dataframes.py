"""DataFrame views (the [pandas] extra): same numbers as the arrays, in the CSV columns."""

import types

import jax.numpy as jnp
import numpy as np
import pytest

pd = pytest.importorskip("pandas")

from diffguide.inverse.fit import RailFit  # noqa: E402
from diffguide.machine import RESULTS  # noqa: E402
from diffguide.machine.kinematics import ERROR_NAMES, JointErrors  # noqa: E402


def test_joint_errors_to_dataframe():
    rng = np.random.default_rng(1)
    err = rng.normal(size=(3, 2, 6)) * 1e-6
    je = JointErrors(
        positions=jnp.array([-0.1, 0.0, 0.1]),
        x_ref=jnp.array(0.0),
        point_names=("A", "B"),
        points_xy=jnp.array([[0.1, 0.2], [-0.3, 0.0]]),
        errors=jnp.asarray(err),
        result=RESULTS.successful,
        interface=jnp.zeros((3, 4)),
        interface_ref=jnp.zeros(4),
    )
    df = je.to_dataframe()
    assert list(df.columns[:4]) == ["position_mm", "point", "x_mm", "y_mm"]
    assert len(df) == 6 and df["converged"].all()
    row = df[(df.point == "B") & (df.position_mm == 100.0)].iloc[0]
    assert (row.x_mm, row.y_mm) == pytest.approx((-300.0, 0.0))
    for k, name in enumerate(ERROR_NAMES):
        unit = "um" if k < 3 else "urad"
        assert row[f"{name}_{unit}"] == pytest.approx(err[2, 1, k] * 1e6)


def test_rail_fit_to_dataframe_matches_profiles():
    s = np.linspace(-0.2, 0.2, 5)
    val = np.arange(20.0).reshape(2, 2, 5) * 1e-7
    sig = val / 10
    stub = types.SimpleNamespace(profiles=lambda s_: (val, sig), basis=None)
    df = RailFit.to_dataframe(stub, s)
    assert list(df.columns) == [
        "rail",
        "s_mm",
        "vertical_um",
        "vertical_sigma_um",
        "horizontal_um",
        "horizontal_sigma_um",
    ]
    r2 = df[df.rail == 2]
    np.testing.assert_allclose(r2.s_mm, s * 1e3)
    np.testing.assert_allclose(r2.horizontal_um, val[1, 1] * 1e6)
    np.testing.assert_allclose(r2.vertical_sigma_um, sig[1, 0] * 1e6)
