"""A ribbed table against a full CalculiX model of the machine built on it (stored results).

``reference/calculix/make_reference.py`` built the ``ribbed`` machine of ``tests/data/calculix``
in CalculiX: the ``majda2012`` machine on a 30 mm plate with two transverse ribs 20 x 40 mm at
x = -/+300 mm running the whole width (the table of ``data/examples/superelement/
make_plate_deck.py``'s ``ribbed`` variant), plate and ribs C3D20R bricks (two layers each) sharing
the plate's underside nodes, rigid carriages, every ball a nonlinear Hertz spring, the screw,
gravity; the paper's rail variants 1, 2, 3 at 9 positions over ±350 mm. Nothing there calls
diffguide.

Two diffguide models of that machine are compared with it, with the metric of
``test_calculix_reference.py`` (its :func:`deviation`: ``|diffguide - ccx|`` in % of each
error's range at each point, ranges below 15 % of the case's largest range of their kind held to
that floor):

- the table imported from CalculiX (``data/examples/superelement/ribbed.*``: a separate brick
  model of the same table, 25 mm grid, one layer in the plate, reduced to its carriage, nut and
  point nodes, the points' rotations from the fibre and the mid-surface), machine file
  ``ribbed_imported.toml``: within 2 %. Measured worst: variant 1 0.04 % (EYX at P1), variant 2
  0.71 % (EZX at P2), variant 3 0.79 % (EBX at P4). (With the rotations from the top face's
  slope and two plate layers, before: 0.21, 1.43, 1.61 %, roll EAX at P2.)
- diffguide's own ribbed plate (MITC4 shells on Timoshenko beam ribs, 40 x 20 mesh), machine
  file ``ribbed.toml``. Measured worst: variant 1 0.25 % (EBX at P1), variant 2 1.05 % (EAX at
  P2), variant 3 1.15 % (EAX at P2); asserted at 1.5 %. On an 80 x 40 mesh: 0.16, 0.57, 0.92 %.
  With the ribs' torsion constant that of the free 20 x 40 mm rectangle instead of their share
  of the T-section's (:func:`~diffguide.fe.beam.bonded_rib_torsion`, 2.52 times larger): 0.32,
  1.97, 1.96 % (roll EAX at the corners), and 2.48, 2.55 % on 80 x 40 for variants 2, 3.

The two tables differ from each other by at most 1 % of a range
(``test_superelement_machine.py``). Without its ribs the native plate is 87 % (variant 2) and
105 % (variant 3) of a range off: the reference sees the ribs.
"""

import dataclasses
import json
import tomllib

import pytest
from test_calculix_reference import DATA, REL, worst

import diffguide as dg

META = json.loads((DATA / "reference.json").read_text())["machines"]["ribbed"]
CASES = list(META["cases"])
#: the native plate's bound, of each error's range (measured worst 1.15 %, docstring)
NATIVE_REL = 0.015


def _worst(machine, case):
    """:func:`test_calculix_reference.worst` of ``machine`` in the ribbed ``case``."""
    return worst(machine, META["cases"][case])


@pytest.fixture(scope="module")
def imported():
    return dg.config_machine(dg.load_config(DATA / "ribbed_imported.toml"))


@pytest.fixture(scope="module")
def native():
    return dg.config_machine(dg.load_config(DATA / META["toml"]))


def test_imported_machine_file_is_the_reference_machine():
    # every key but the plate's is the reference machine's
    a = tomllib.loads((DATA / "ribbed_imported.toml").read_text())
    b = tomllib.loads((DATA / META["toml"]).read_text())
    assert {k: v for k, v in a.items() if k != "table"} == {
        k: v for k, v in b.items() if k not in ("table", "ribs")
    }
    assert a["table"]["source"] == "superelement"
    for key in ("length_mm", "width_mm"):
        assert a["table"][key] == b["table"][key]


@pytest.mark.parametrize("case", CASES)
def test_imported_table_agrees_with_full_calculix(imported, case):
    pct, where = _worst(imported, case)
    assert pct <= 100 * REL, f"ribbed/{case}, imported table: {where} (bound {REL:.0%})"


@pytest.mark.parametrize("case", CASES)
def test_native_ribbed_plate_agrees_with_full_calculix(native, case):
    pct, where = _worst(native, case)
    assert pct <= 100 * NATIVE_REL, f"ribbed/{case}, native plate: {where} (bound {NATIVE_REL:.1%})"


#: the native plate on an 80 x 40 mesh (measured worst 0.92 %, docstring)
FINE_REL = 0.012


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES)
def test_refined_native_ribbed_plate_agrees_with_full_calculix(case):
    """Refined, the native ribbed plate converges within 1 % of the bricks (before the ribs
    twisted with their share of the T-section's torsion: to 2.5 %, roll at the corners)."""
    spec = dg.spec_from_config(dg.load_config(DATA / META["toml"]))
    pct, where = _worst(dg.build_machine(spec, nx=80, ny=40), case)
    assert pct <= 100 * FINE_REL, f"ribbed/{case}, native 80 x 40: {where}"


def test_reference_sees_the_ribs():
    # the same plate without its ribs is far off where the table twists (measured 87 %)
    spec = dg.spec_from_config(dg.load_config(DATA / META["toml"]))
    assert len(spec.ribs) == 2
    pct, where = _worst(dg.build_machine(dataclasses.replace(spec, ribs=())), "variant2")
    assert pct > 40.0, f"ribbed/variant2 without ribs: {where}"
