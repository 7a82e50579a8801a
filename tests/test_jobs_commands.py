"""``diffguide.jobs``: each command's job writes what the command writes, byte for byte (the
seconds a study took aside), on the smallest inputs the commands' own tests use (a 10x5 mesh,
a handful of positions and samples: the claim is about the code path from the options to the
files, which does not depend on the size), and the settings refuse what the command refuses,
in its words."""

import json
from pathlib import Path

import pytest

from diffguide.cli import main
from diffguide.jobs import (
    ImportSettings,
    MontecarloSettings,
    SimulateSettings,
    ToleranceSettings,
    import_job,
    montecarlo_job,
    simulate_job,
    tolerance_job,
)

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"


def _same_files(cli: dict, job: dict) -> None:
    """Every file of the command's run equal to the job's, byte for byte."""
    assert len(cli) == len(job)
    for (a, b) in zip(cli.values(), job.values()):
        assert Path(a).read_bytes() == Path(b).read_bytes(), (a, b)


def _paths(root: Path, tag: str, names) -> dict:
    return {n: root / f"{tag}_{n}" for n in names}


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return tmp_path_factory.mktemp("jobs_commands")


def test_simulate_job_writes_the_commands_files(root):
    names = ("e.csv", "e.png", "field.png", "comp.csv")
    cli, job = _paths(root, "cli", names), _paths(root, "job", names)

    def options(p):
        return dict(positions="-300:300:5", mesh="10x5", out=str(p["e.csv"]),
                    plot=str(p["e.png"]), field_plot=str(p["field.png"]),
                    export_compensation=str(p["comp.csv"]), at="P1")

    argv = [f"--{k.replace('_', '-')}={v}" for k, v in options(cli).items()]
    assert main(["simulate", *argv, "--quiet"]) == 0
    res = simulate_job(SimulateSettings(**options(job)))
    assert res.converged and res.exit_code == 0
    written = res.write()
    assert written == [str(job[n]) for n in ("e.csv", "field.png", "comp.csv", "e.png")]
    _same_files(cli, job)
    assert res.errors.errors.shape == (5, 5, 6)  # positions x points x errors


def test_simulate_job_runs_the_cross_table_for_its_preset(root):
    cli, job = root / "cross_cli.csv", root / "cross_job.csv"
    assert main(["simulate", "--preset", "majda2012-cross", "--grid-xy", "2x2", "--out",
                 str(cli), "-q"]) == 0
    res = simulate_job(SimulateSettings(preset="majda2012-cross", grid_xy="2x2"))
    assert res.write(job) == [str(job)]
    assert cli.read_bytes() == job.read_bytes()


def test_montecarlo_job_writes_the_commands_files(root):
    names = ("mc.csv", "mc.png")
    cli, job = _paths(root, "cli", names), _paths(root, "job", names)
    opts = dict(samples=5, mesh="10x5", chunk=4, positions="-350:350:11", rail_rms_um=5.0,
                mounting="size25-ZA")
    argv = [f"--{k.replace('_', '-')}={v}" for k, v in opts.items()]
    assert main(["montecarlo", *argv, "--out", str(cli["mc.csv"]), "--plot",
                 str(cli["mc.png"]), "-q"]) == 0
    res = montecarlo_job(MontecarloSettings(**opts, out=job["mc.csv"], plot=job["mc.png"]))
    assert res.write() == [str(job["mc.csv"]), str(job["mc.png"])]
    _same_files(cli, job)
    assert res.exit_code == 0 and res.n_failed == 0 and "largest roll difference" in (
        res.summary())


def test_tolerance_job_writes_the_commands_json(root):
    cli, job = root / "tol_cli.json", root / "tol_job.json"
    opts = dict(limit=3.0, probability=0.8, samples=32, check_samples=0, mesh="10x5",
                positions="-300:300:5", chunk=32)
    argv = [f"--{k.replace('_', '-')}={v}" for k, v in opts.items()]
    assert main(["tolerance", *argv, "--out", str(cli), "-q"]) == 0
    res = tolerance_job(ToleranceSettings(**opts))
    res.write(job)
    a, b = (json.loads(p.read_text(encoding="utf-8")) for p in (cli, job))
    assert a.pop("seconds") >= 0 and b.pop("seconds") >= 0  # the time each took
    assert a == b and b["grade_um"] == res.allocation.grade * 1e6
    assert res.report().startswith("rail straightness grade for roll_difference <= 3 µrad")


def test_import_job_writes_the_commands_file(root, capsys):
    cli, job = root / "imp_cli.csv", root / "imp_job.csv"
    assert main(["import", str(DATA), "--x0-mm", "0", "--explain", "--out", str(cli)]) == 0
    explained = capsys.readouterr().out
    res = import_job(ImportSettings(input=(str(DATA),), x0_mm=0.0, out=str(job)))
    assert res.write() == [str(job)]
    assert cli.read_bytes() == job.read_bytes()
    assert "\n".join(res.explain_lines()) in explained
    assert res.measurements.n > 0 and len(res.readings) >= res.measurements.n


@pytest.mark.parametrize("command, argv, make", [
    ("simulate", ["--positions", "300:-300:5"],
     lambda: SimulateSettings(positions="300:-300:5")),
    ("simulate", ["--tol-um", "0"], lambda: SimulateSettings(tol_um=0.0)),
    ("montecarlo", ["--samples", "0"], lambda: MontecarloSettings(samples=0)),
    ("montecarlo", ["--corr-mm", "0"], lambda: MontecarloSettings(corr_mm=0.0)),
    ("tolerance", ["--limit", "3", "--probability", "1.5"],
     lambda: ToleranceSettings(limit=3.0, probability=1.5)),
    ("import", [str(DATA)], lambda: ImportSettings(input=(str(DATA),))),
])
def test_settings_refuse_what_the_command_refuses_in_its_words(tmp_path, capsys, command, argv,
                                                               make):
    out = [] if command in ("import", "tolerance") else ["--out", str(tmp_path / "o.csv")]
    assert main([command, *argv, *out, "--no-cache"]) == 2
    line = capsys.readouterr().err.strip().splitlines()[-1]
    with pytest.raises(ValueError) as err:
        make()
    assert line == f"diffguide {command}: error: {err.value}"
    assert not (tmp_path / "o.csv").exists()
