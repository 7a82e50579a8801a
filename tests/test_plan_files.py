"""Plan inputs read from files (no JAX): sites, placements, the bundled layout."""

import pytest

from diffguide.planning.instruments import grid_sites
from diffguide.io.plan_files import read_placements, read_sites

TABLE = (1000.0, 500.0)  # mm


def test_bundled_layout_lands_on_the_grid_corners_and_centre():
    """The bundled layout is 50 mm inside the edges: on a 7x3 grid with the same margin its
    levels take the four corner sites and its interferometer the centre; nothing is added."""
    sites = grid_sites(1.0, 0.5, 7, 3)
    before = dict(sites)
    plan = read_placements("bundled", "--compare", TABLE, sites)
    assert sites == before
    assert sorted(plan) == sorted(
        [("level", n) for n in ("G1_1", "G1_3", "G7_1", "G7_3")] + [("interferometer", "G4_2")]
    )


def test_placements_off_the_grid_add_sites_and_repeat_names(tmp_path):
    f = tmp_path / "layout.csv"
    f.write_text(
        "instrument,point,x_mm,y_mm\nlevel,P1,100,50\ninterferometer,P1,100,50\nlevel,,-450,-200\n"
    )
    sites = grid_sites(1.0, 0.5, 7, 3)
    plan = read_placements(str(f), "--start", TABLE, sites)
    assert plan == [("level", "U1"), ("interferometer", "U1"), ("level", "G1_1")]
    assert sites["U1"] == pytest.approx((0.1, 0.05), abs=1e-15)


@pytest.mark.parametrize(
    "rows, match",
    [
        ("level,P1,600,0", r"layout.csv:2: site 'P1' at \(600, 0\) mm is off the table"),
        ("laser,P1,0,0", r"layout.csv:2: field 'instrument'"),
        ("level,P1,0,0\nlevel,P2,0,0", "the same instrument twice on one site"),
        ("level,P1,0,0\nlevel,P1,10,0", r"layout.csv:3: field 'point': 'P1' is at"),
    ],
)
def test_bad_placements_are_refused_with_file_and_line(tmp_path, rows, match):
    f = tmp_path / "layout.csv"
    f.write_text("instrument,point,x_mm,y_mm\n" + rows + "\n")
    with pytest.raises(ValueError, match=match):
        read_placements(str(f), "--start", TABLE, {})


def test_sites_file(tmp_path):
    f = tmp_path / "sites.csv"
    f.write_text("name,x_mm,y_mm\nA,-400,-200\nB,0,0\n")
    assert read_sites(str(f), TABLE) == {"A": (-0.4, -0.2), "B": (0.0, 0.0)}
    f.write_text("name,x_mm,y_mm\nA,0,0\nA,10,0\n")
    with pytest.raises(ValueError, match="sites.csv:3: site names must be unique"):
        read_sites(str(f), TABLE)
