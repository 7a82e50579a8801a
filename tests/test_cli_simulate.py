"""The simulate and stiffness commands: outputs, units, errors for bad input."""

import csv

import numpy as np
import pytest

from diffguide.cli import main


def test_stiffness_command_writes_fig3_csv(tmp_path, capsys):
    out, png = tmp_path / "s.csv", tmp_path / "s.png"
    assert (
        main(
            [
                "stiffness",
                "--preset",
                "majda2012",
                "--out",
                str(out),
                "--plot",
                str(png),
                "--steps",
                "5",
                "--max-load",
                "4000",
            ]
        )
        == 0
    )
    rows = list(csv.DictReader(out.open()))
    assert {r["direction"] for r in rows} == {"down", "up", "lateral"}
    assert list(rows[0]) == ["direction", "load_N", "deflection_um"]
    down = [float(r["deflection_um"]) for r in rows if r["direction"] == "down"]
    assert down[0] == 0.0 and np.all(np.diff(down) > 0)
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_simulate_writes_one_row_per_position_and_point(tmp_path):
    out, png, field = tmp_path / "e.csv", tmp_path / "e.png", tmp_path / "field.png"
    assert (
        main(
            [
                "simulate",
                "--field-plot",
                str(field),
                "--variant",
                "2",
                "--positions",
                "-300:300:5",
                "--mesh",
                "10x5",
                "--out",
                str(out),
                "--plot",
                str(png),
                "--quiet",
            ]
        )
        == 0
    )
    rows = list(csv.DictReader(out.open()))
    assert list(rows[0]) == [
        "position_mm",
        "point",
        "x_mm",
        "y_mm",
        "EXX_um",
        "EYX_um",
        "EZX_um",
        "EAX_urad",
        "EBX_urad",
        "ECX_urad",
    ]
    assert len(rows) == 5 * 5
    # the reference position x = 0 is in the sweep: every error is zero there
    at_ref = [r for r in rows if float(r["position_mm"]) == 0.0]
    assert all(abs(float(r[k])) < 1e-6 for r in at_ref for k in list(r)[4:])
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert field.read_bytes()[:4] == b"\x89PNG"


def test_simulate_reads_rails_csv_same_as_the_paper_variant(tmp_path):
    # the paper's variant 1 written as a rails file must give the variant-1 result
    s = np.linspace(-700, 700, 141)
    i_um = 0.5 * 50.0 * (s / 1000 + (s / 1000) ** 2)  # Δ/2·(x/1000 + (x/1000)²), Δ = 50 µm
    rails = tmp_path / "rails.csv"
    rails.write_text(
        "rail,s_mm,vertical_um,horizontal_um\n" + "".join(f"1,{a},{b},0\n" for a, b in zip(s, i_um))
    )
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    common = ["--positions", "-350:350:8", "--mesh", "10x5", "--quiet"]
    assert main(["simulate", "--variant", "1", "--out", str(a), *common]) == 0
    assert main(["simulate", "--rails", str(rails), "--out", str(b), *common]) == 0
    va = np.array(
        [
            [float(v) for v in r.values() if v not in ("P1", "P2", "P3", "P4", "P5")]
            for r in csv.DictReader(a.open())
        ]
    )
    vb = np.array(
        [
            [float(v) for v in r.values() if v not in ("P1", "P2", "P3", "P4", "P5")]
            for r in csv.DictReader(b.open())
        ]
    )
    # a quadratic is reproduced exactly by the cubic spline except for the interpolation's end
    # effects far outside the visited range: agreement to 1e-4 µm / µrad
    np.testing.assert_allclose(vb, va, atol=1e-4)


@pytest.mark.parametrize(
    "content, message",
    [
        ("", "empty file"),
        ("rail,s_mm,vertical_um\n1,0,0\n", "field 'horizontal_um': missing column"),
        ("rail,s_mm,vertical_um,horizontal_um\n3,0,0,0\n", ":2: field 'rail'"),
        (
            "rail,s_mm,vertical_um,horizontal_um\n1,abc,0,0\n",
            ":2: field 's_mm': 'abc' is not a number",
        ),
        ("rail,s_mm,vertical_um,horizontal_um\n1,0,nan,0\n", "field 'vertical_um'"),
        ("rail,s_mm,vertical_um,horizontal_um\n1,0,0,0\n1,10,0,0\n", "at least 4"),
        ("rail,s_mm,vertical_um,horizontal_um\n1,0,0\n", ":2: 3 fields, expected 4"),
        ("rail,s_mm,vertical_um,horizontal_um\n1,0,1e9,0\n", "outside the allowed range"),
    ],
)
def test_simulate_rejects_bad_rails_file(tmp_path, capsys, content, message):
    rails = tmp_path / "bad.csv"
    rails.write_text(content)
    out = tmp_path / "e.csv"
    assert main(["simulate", "--rails", str(rails), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and "bad.csv" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--positions", "1:2"], "START:STOP:COUNT"),
        (["--positions", "300:-300:5"], "STOP > START"),
        (["--positions", "-500:500:5"], "stroke"),
        (["--mesh", "0x5"], "--mesh"),
        (["--rails", "/nonexistent/rails.csv"], "cannot read rails file"),
        (["--positions", "-300:300:5", "--field-at", "900"], "--field-at must lie within"),
        (["--tol-um", "-1"], "--tol-um must be a finite number > 0"),
    ],
)
def test_simulate_rejects_bad_arguments(tmp_path, capsys, args, message):
    assert main(["simulate", "--out", str(tmp_path / "e.csv"), "--quiet", *args]) == 2
    assert message in capsys.readouterr().err


def test_simulate_plot_alone(tmp_path):
    """``--plot`` without ``--field-plot`` (the README's form) writes the CSV and the figure."""
    out, png = tmp_path / "e.csv", tmp_path / "e.png"
    rc = main(["simulate", "--positions", "-300:300:5", "--out", str(out), "--plot", str(png),
               "--quiet"])
    assert rc == 0 and png.read_bytes()[:4] == b"\x89PNG" and out.exists()


def test_a_command_run_in_process_keeps_the_callers_figures_and_backend(tmp_path):
    """A notebook that has pyplot open calls a command: its backend and its figures stay, and
    the command leaves none of its own figures open."""
    import matplotlib
    import matplotlib.pyplot as plt

    backend = matplotlib.get_backend()
    mine = plt.figure()
    try:
        before = set(plt.get_fignums())
        args = ["stiffness", "--preset", "majda2012", "--steps", "3", "--max-load", "2000"]
        png = tmp_path / "s.png"
        assert main([*args, "--out", str(tmp_path / "s.csv"), "--plot", str(png)]) == 0
        assert png.read_bytes()[:4] == b"\x89PNG"
        assert set(plt.get_fignums()) == before and plt.fignum_exists(mine.number)
        assert matplotlib.get_backend() == backend
    finally:
        plt.close(mine)


def test_x0_means_one_quantity_in_simulate_and_fit():
    # x0 is the machine coordinate of the table position x = 0 in both commands; simulate's
    # --x0-mm is its --machine-x0-mm (the compensation table only), fit's is the measurement
    # files' x0 (which also places fit's table): both helps say which
    import argparse

    from diffguide.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    sim, fit = sub.choices["simulate"], sub.choices["fit"]
    for flag in ("--x0-mm", "--machine-x0-mm"):
        args = sim.parse_args(["--out", "x.csv", flag, "400"])
        assert args.machine_x0_mm == 400.0
    helps = {a.dest: " ".join(a.help.split()) for a in sim._actions if a.help}
    assert "only the compensation table" in helps["machine_x0_mm"]
    assert "stay in table positions x" in helps["machine_x0_mm"]
    assert "not machine coordinates" in helps["positions"]
    fit_helps = {a.dest: " ".join(a.help.split()) for a in fit._actions if a.help}
    assert "x = position - x0" in fit_helps["x0_mm"]
    assert "compensation table's x0 unless --machine-x0-mm" in fit_helps["x0_mm"]
    assert fit.parse_args(["--measurements", "m.csv", "--out", "o", "--x0-mm", "middle"]
                          ).x0_mm == "middle"
