"""ISO 230-2:2014 figures against values computed by hand on a tiny bidirectional test."""

import math

import pytest

from diffguide.io.measurements import merge_readings, parse_readings
from diffguide.studies.iso230_2 import channel_figures, positioning_figures

# targets P1, P2; three runs up (forward), three down (backward), µm
UP = [[1.0, 2.0, 3.0], [4.0, 4.0, 7.0]]
DOWN = [[0.0, 0.0, 0.0], [5.0, 6.0, 7.0]]
R3 = math.sqrt(3.0)
# by hand: x̄↑ = (2, 5), s↑ = (1, √3); x̄↓ = (0, 6), s↓ = (0, 1); B_i = (2, -1)
HAND = {
    "B": 2.0,
    "B_mean": 0.5,
    "R_up": 4 * R3,
    "R_down": 4.0,
    "R": 4 * R3,  # R_2 = max(2√3 + 2 + 1, 4√3, 4) = 4√3; R_1 = max(2 + 0 + 2, 4, 0) = 4
    "E_up": 3.0,
    "E_down": 6.0,
    "E": 6.0,
    "M": 4.5,
    "A_up": 5 + 2 * R3 - 0.0,
    "A_down": 8.0 - 0.0,
    "A": 5 + 2 * R3,
}


def test_figures_by_hand():
    f = positioning_figures(UP, DOWN)
    for k, v in HAND.items():
        assert f[k] == pytest.approx(v, abs=1e-12), k
    assert f["mean_bidirectional_deviation"] == pytest.approx([1.0, 5.5])
    assert f["reversal_per_target"] == pytest.approx([2.0, -1.0])


def test_channel_figures_from_a_measurement_file():
    lines = ["position_mm,point,x_mm,y_mm,quantity,value,unit,run,direction"]
    for i, x in enumerate((0.0, 100.0)):
        for j in range(3):
            lines.append(f"{x},P5,0,0,EXX,{UP[i][j]},um,{j + 1},forward")
            lines.append(f"{x},P5,0,0,EXX,{DOWN[i][j] / 1000},mm,{j + 1},backward")
    # a channel with one run per direction: no figures
    lines += ["0,P5,0,0,EBX,1,um/m,1,+", "100,P5,0,0,EBX,1,um/m,1,+"]
    meas = merge_readings(parse_readings("\n".join(lines)))
    (fig,) = channel_figures(meas)
    assert (fig["point"], fig["quantity"], fig["unit"]) == ("P5", "EXX", "µm")
    assert fig["positions_mm"] == pytest.approx([0.0, 100.0])
    for k, v in HAND.items():
        assert fig[k] == pytest.approx(v, abs=1e-9), k


def test_too_few_runs_refused():
    with pytest.raises(ValueError):
        positioning_figures([[1.0]], [[2.0]])
