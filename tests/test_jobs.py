"""``diffguide.jobs``: the library's fit job writes what ``diffguide fit`` writes, byte for byte
(timing fields and the date stamp aside), and refuses what the command refuses, in its words."""

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from diffguide.cli import main
from diffguide.jobs import FitSettings, fit_job

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"
TRUTH = ROOT / "data" / "majda2012_truth.csv"
#: what differs between two runs of the same fit: the seconds taken and the minute it ran
VOLATILE = re.compile(r'("(?:fit|total)_seconds": )[-+0-9.e]+|\d{4}-\d\d-\d\d \d\d:\d\d UTC')


def _steady(data: bytes) -> bytes:
    return VOLATILE.sub(lambda m: (m.group(1) or "") + "T", data.decode("utf-8")).encode()


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    """The command's output folder (copied aside), then the job's written to the same path
    (replacing the command's: an earlier output of fit), with the same options."""
    root = tmp_path_factory.mktemp("jobs")
    out, comp = root / "result", root / "comp.txt"
    options = dict(truth=str(TRUTH), rigid=True, export_compensation=str(comp), at="P1")
    rc = main(["fit", "--measurements", str(DATA), "--out", str(out), "--truth", str(TRUTH),
               "--rigid", "--export-compensation", str(comp), "--at", "P1", "--quiet"])
    assert rc == 0
    cli = root / "cli"
    shutil.copytree(out, cli)
    shutil.copy(comp, root / "cli_comp.txt")
    res = fit_job(FitSettings(measurements=(str(DATA),), **options))
    written = res.write(out)
    return cli, out, root, res, written


def test_the_job_writes_the_commands_files_byte_for_byte(both):
    cli, job, _, _, written = both
    names = sorted(p.name for p in cli.iterdir())
    assert sorted(p.name for p in job.iterdir()) == names
    assert set(written) | {".diffguide-output.json"} == set(names)
    for name in names:
        a, b = (cli / name).read_bytes(), (job / name).read_bytes()
        if name in ("report.json", "report.html"):
            a, b = _steady(a), _steady(b)
        assert a == b, name  # the PNGs too: matplotlib's files are stable run to run
    report = (job / "report.json").read_text()
    assert f'--start {job / "layout.csv"}' in report  # the planner command names the folder


def test_the_compensation_table_too(both):
    _, _, root, res, _ = both
    assert (root / "comp.txt").read_bytes() == (root / "cli_comp.txt").read_bytes()
    assert list(res.compensation) == [root / "comp.txt"]


def test_the_result_holds_the_fits_and_the_report(both):
    _, job, _, res, _ = both
    assert set(res.fits) == {"", "_rigid"} and res.converged and res.exit_code == 0
    assert res.files["rails.csv"] == (job / "rails.csv").read_text(encoding="utf-8")
    assert res.report["truth"]["rms_error_um"]["elastic"]["all"] > 0


@pytest.mark.parametrize("option, value, field", [
    ("--max-steps", "-1", {"max_steps": -1}),
    ("--lambda", "0", {"lam": 0.0}),
    ("--knot-spacing-mm", "0.5", {"knot_spacing_mm": 0.5}),
])
def test_settings_refuse_what_the_command_refuses_in_its_words(tmp_path, capsys, option, value,
                                                               field):
    rc = main(["fit", "--measurements", str(DATA), "--out", str(tmp_path / "o"), option, value])
    assert rc == 2 and not (tmp_path / "o").exists()
    line = capsys.readouterr().err.strip().splitlines()[-1]
    with pytest.raises(ValueError) as err:
        FitSettings(measurements=(str(DATA),), **field)
    assert line == f"diffguide fit: error: {err.value}"


def test_importing_the_jobs_starts_neither_jax_nor_matplotlib():
    code = ("import sys, diffguide.jobs; bad = {'jax', 'matplotlib'} & set(sys.modules); "
            "assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=300)


def test_the_predict_job_writes_the_commands_file_byte_for_byte(both, tmp_path):
    """On the fit above (its posterior.json): the command's prediction and the job's."""
    from diffguide.jobs import PredictSettings, predict_job

    _, fit, _, _, _ = both
    cli, job = tmp_path / "cli.csv", tmp_path / "job.csv"
    assert main(["predict", "--fit", str(fit), "--point", "Q:300,100", "--positions-mm",
                 "-300:300:5", "--z-mm", "150", "--out", str(cli), "-q"]) == 0
    res = predict_job(PredictSettings(fit=fit, point=("Q:300,100",), positions_mm="-300:300:5",
                                      z_mm=150.0))
    assert res.write(job) == [str(job)]
    assert job.read_bytes() == cli.read_bytes()
    assert res.prediction.errors.shape == (5, len(res.prediction.point_names), 6)
    assert not res.warnings and res.machine_change is None
