"""Catalogue roller blocks (HIWIN RG): published capacity, preload classes and envelope; the
effective roller length fitted to the rigidity the user gives (the sources read publish none
for RG as numbers).

The fit is checked against Palmgren's law in closed form: at the preload, each of the ``4n``
rollers carries ``F₀ = f·C/(4n)`` along its load line at 45° to the vertical, its approach is
``a₀ = 2·3.84·10⁻⁵·F₀^0.9/l^0.8`` (mm, N; two line contacts in series) and its stiffness
``F₀/(0.9·a₀)``, so the block's radial stiffness is ``4n·cos²45°·F₀/(0.9·a₀)``, which gives the
roller length for a rigidity without the carriage model or the root-find.
"""

import numpy as np
import pytest
from test_catalogue import CLASSES, PUBLISHED, fd_radial_rigidity

from diffguide.cli import main
from diffguide.guideway.carriage import carriage_from_spec
from diffguide.guideway.catalogue import calibrate_block, catalogue_block

ROLLER_BLOCKS = sorted(n for n in PUBLISHED if n.startswith("HIWIN-RG"))
#: Rigidities a user might read off a datasheet (N/µm), one per class: illustrative inputs, not
#: catalogue values.
GIVEN = {"Z0": 1200.0, "ZA": 1500.0, "ZB": 1800.0}


def palmgren_length(rigidity, capacity, fraction, n):
    """Effective roller length (m) whose four rows of ``n`` rollers at 45° have the radial
    stiffness ``rigidity`` (N/m) at the preload ``fraction·capacity`` (N), Palmgren's law."""
    f0 = fraction * capacity / (4 * n)
    k_mm = rigidity * 1e-3  # N/mm
    # k = 4n·½·F₀/(0.9·2·3.84e-5·F₀^0.9·l^-0.8) = n·F₀^0.1·l^0.8/(0.9·3.84e-5)
    return (0.9 * 3.84e-5 * k_mm / (n * f0**0.1)) ** (1 / 0.8) * 1e-3


@pytest.mark.parametrize("name", ROLLER_BLOCKS)
@pytest.mark.parametrize("cls", ["Z0", "ZA", "ZB"])
def test_roller_length_fitted_to_the_given_rigidity(name, cls):
    spec, prov = calibrate_block(name, cls, rigidity=GIVEN[cls] * 1e6)
    assert spec.law == "roller" and spec.contact_angle_deg == 45.0
    # the published capacity and the middle of the published class range
    assert spec.capacity == PUBLISHED[name]["C"]
    lo, hi = CLASSES["HIWIN-RG"][cls]
    assert spec.preload_fraction == pytest.approx((lo + hi) / 2)
    carriage = carriage_from_spec(spec)
    total = float(carriage.preload_force) * 4 * carriage.n_elements
    assert total == pytest.approx(spec.preload_fraction * spec.capacity, rel=1e-12)
    # Palmgren in closed form gives the same roller length, and the wrench's finite difference
    # the given rigidity
    expected = palmgren_length(
        GIVEN[cls] * 1e6, spec.capacity, spec.preload_fraction, spec.elements_per_row
    )
    assert spec.roller_length == pytest.approx(expected, rel=1e-6)
    assert abs(fd_radial_rigidity(spec) / (GIVEN[cls] * 1e6) - 1) < 0.05
    assert prov["roller_length"].startswith("calibrated") and "given" in prov["roller_length"]
    assert prov["capacity"].startswith("published")
    assert prov["contact_angle_deg"].startswith("published")


def test_without_a_rigidity_the_error_says_what_to_give():
    with pytest.raises(ValueError, match="no rigidity is published.*rigidity=.*roller_length"):
        calibrate_block("HIWIN-RG 35 H", "ZB")
    # an explicit roller length needs no rigidity
    spec, prov = calibrate_block("HIWIN-RG 35 H", "ZB", roller_length=5e-3)
    assert spec.roller_length == 5e-3 and prov["roller_length"] == "explicit"
    with pytest.raises(ValueError, match="rigidity must be > 0"):
        calibrate_block("HIWIN-RG 25 C", "ZA", rigidity=-1.0)
    # a published rigidity is not replaced by the user's
    with pytest.raises(ValueError, match="publishes a rigidity for class 'ZA' .630 N/µm.*not both"):
        calibrate_block("HIWIN-HG 25 C", "ZA", rigidity=1e9)
    # nor fitted and given at once: the explicit roller length would leave it unused
    with pytest.raises(ValueError, match="either the rigidity .fitted by roller_length. or"):
        calibrate_block("HIWIN-RG 25 C", "ZA", rigidity=1.5e9, roller_length=5e-3)


def test_the_envelope_is_the_published_one():
    block = catalogue_block("hiwin-rg 35 c")
    assert block.element == "roller"
    assert block.footprint == pytest.approx((79.0e-3, 70.0e-3))
    assert (block.block_height, block.rail_width, block.rail_height) == pytest.approx(
        (55.0e-3, 34.0e-3, 30.2e-3)
    )


CONFIG = """\
[table]
length_mm = 1200.0
width_mm = 600.0
thickness_mm = 60.0
mesh_nx = 6
mesh_ny = 3

[guideway]
rail_y_mm = [-220.0, 220.0]
carriage_x_mm = [-250.0, 250.0]

[carriage]
block = "HIWIN-RG 25 C"
preload_class = "ZA"
rigidity_N_um = 1500.0

[machine]
stroke_mm = 600.0
"""


def test_a_short_machine_file_with_a_roller_block_explains_and_simulates(tmp_path, capsys):
    assert len(CONFIG.splitlines()) <= 20
    path = tmp_path / "machine.toml"
    path.write_text(CONFIG, encoding="utf-8")
    assert main(["config", "--explain", str(path)]) == 0
    text = capsys.readouterr().out
    source = "HIWIN Technical Information G99TE20-1808, RG series"
    assert f"capacity_N = 27700.0  # catalogue, published: C = 27700 N ({source})" in text
    assert "carriage_footprint_mm = [64.5, 48.0]  # catalogue, published" in text
    assert 'law = "roller"' in text
    assert "1500 N/µm, given (none published in" in text
    errors = tmp_path / "errors.csv"
    assert (
        main(
            [
                "simulate",
                "--config",
                str(path),
                "--variant",
                "1",
                "--positions",
                "-300:300:3",
                "--out",
                str(errors),
                "--quiet",
                "--no-cache",
            ]
        )
        == 0
    )
    table = np.genfromtxt(errors, delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert len(table) == 3 * 5
    # errors are relative to x = 0 (zero there); the vertical rail error moves the table
    at_ref = table["position_mm"] == 0
    for q in ("EZX_um", "EBX_urad", "EAX_urad"):
        assert np.all(np.isfinite(table[q]))
        assert np.allclose(table[q][at_ref], 0.0, atol=1e-9)
    assert np.max(np.abs(table["EZX_um"])) > 0.1


def test_the_solved_secant_of_a_roller_block_agrees():
    """The carriage's equilibrium under 5 % of C pressing it onto the rail (rotations held)
    gives a secant rigidity within 5 % of the rigidity the roller length was fitted to."""
    from diffguide._core.result import RESULTS
    from diffguide.guideway import static_characteristics

    spec, _ = calibrate_block("HIWIN-RG 35 C", "ZB", rigidity=GIVEN["ZB"] * 1e6)
    load = 0.05 * PUBLISHED["HIWIN-RG 35 C"]["C"]
    deflection, sols = static_characteristics(carriage_from_spec(spec), np.array([load]))["down"]
    assert bool(np.all(sols.result == RESULTS.successful))
    assert abs(load / float(deflection[0]) / (GIVEN["ZB"] * 1e6) - 1) < 0.05
