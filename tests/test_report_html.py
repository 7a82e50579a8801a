"""``report.html`` of ``diffguide fit``: one self-contained file whose straightness table and
verdict are report.json's numbers, opened in a real browser (headless Chromium: a screenshot
and the rendered DOM); the console says the same."""

import contextlib
import io
import json
import os
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from diffguide.cli import main
from diffguide.io.report_html import report_html, straightness_lines, verdict_line

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"
TOLERANCE_UM = 4.5


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """One fit of the bundled data with a tolerance: (output folder, console text)."""
    out = tmp_path_factory.mktemp("report") / "fit"
    console = io.StringIO()
    with contextlib.redirect_stdout(console):
        rc = main(["fit", "--preset", "majda2012", "--measurements", str(DATA), "--out",
                   str(out), "--tolerance-um", str(TOLERANCE_UM)])
    assert rc == 0
    return out, console.getvalue()


class _Page(HTMLParser):
    """The straightness table's rows (cell texts), the verdict's text, the images' sources
    and every URL-bearing attribute and tag name."""

    def __init__(self):
        super().__init__()
        self.rows, self.verdict, self.images, self.urls, self.tags = [], "", [], [], set()
        self._table = self._in_verdict = False
        self._row = self._cell = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.add(tag)
        self.urls += [v for k, v in attrs if k in ("src", "href") and v]
        if tag == "img":
            self.images.append(a.get("src", ""))
        if tag == "table" and a.get("id") == "straightness":
            self._table = True
        if self._table and tag == "tr":
            self._row = []
        if self._row is not None and tag in ("td", "th"):
            self._cell = ""
        if tag == "p" and a.get("id") == "verdict":
            self._in_verdict = True

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append(self._cell.strip())
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.rows.append(self._row)
            self._row = None
        elif tag == "table":
            self._table = False
        elif tag == "p":
            self._in_verdict = False

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data
        if self._in_verdict:
            self.verdict += data


def _parse(text: str) -> _Page:
    page = _Page()
    page.feed(text)
    page.close()
    return page


def _check_table(page: _Page, section: dict) -> None:
    header, *rows = page.rows
    assert header[3:6] == ["straightness: median of the draws (µm)",
                           "95 % interval of the draws (µm)", "mean profile's (µm)"]
    assert header[-1] == "verdict"
    assert len(rows) == len(section["rails"]) == 4
    for cells, r in zip(rows, section["rails"]):
        assert cells[0] == str(r["rail"]) and cells[2] == r["plane"]
        assert cells[1].startswith(r["side"])
        assert float(cells[3]) == round(r["straightness_um"], 2)
        assert [float(v) for v in cells[4].split(" … ")] == [round(v, 2) for v in
                                                             r["interval_95_um"]]
        assert float(cells[5]) == round(r["mean_profile_um"], 2)
        assert cells[-1] == r["verdict"]
    assert page.verdict.strip() == verdict_line(section)


def test_json_straightness_section(fitted):
    out, _ = fitted
    st = json.loads((out / "report.json").read_text())["straightness"]
    assert st["tolerance_um"] == TOLERANCE_UM and st["coverage_probability"] == 0.95
    assert "least-squares" in st["reference_line"]
    assert {(r["rail"], r["side"], r["plane"]) for r in st["rails"]} == {
        (1, "−y", "vertical"), (1, "−y", "horizontal"), (2, "+y", "vertical"),
        (2, "+y", "horizontal")}  # majda2012: rail 1 at y = −170 mm
    for r in st["rails"]:
        assert 0 < r["u_um"] < r["straightness_um"] < 20  # µm-scale rails, a sound fit
        lo, hi = r["interval_95_um"]
        assert lo < r["straightness_um"] < hi
        # the peak-to-valley's bias: the draws above the mean profile's
        assert r["bias_um"] == pytest.approx(r["straightness_um"] - r["mean_profile_um"])
        assert 0 < r["bias_um"] < r["u_um"]
        # the basic bootstrap interval, for comparison: the draws' reflected about the mean
        # profile's value (lower: the verdict does not use it)
        m = r["mean_profile_um"]
        assert r["interval_95_basic_um"] == pytest.approx([2 * m - hi, 2 * m - lo])
        assert r["informative"] and r["prior_ratio"] < 0.9  # the data narrow the prior
        # ISO 14253-1 on the interval, not on value ± U
        expected = ("pass" if hi <= TOLERANCE_UM else "fail" if lo > TOLERANCE_UM else
                    "not decidable")
        assert r["verdict"] == expected and r["verdict_reason"]


def test_html_is_self_contained_and_matches_the_json(fitted):
    out, _ = fitted
    text = (out / "report.html").read_text(encoding="utf-8")
    rep = json.loads((out / "report.json").read_text())
    page = _parse(text)
    _check_table(page, rep["straightness"])
    assert not {"script", "link", "iframe", "object"} & page.tags  # nothing loaded from outside
    assert page.urls and all(u.startswith("data:image/png;base64,") for u in page.urls)
    assert len(page.images) == 3
    for needle in ("EAX (roll)", "EBX (pitch)", "ECX (yaw)", "error bars ±1σ", "−y (y = -170 mm)",
                   "least-squares reference line", "not determined", "diffguide plan",
                   "majda2012_measurements.csv",
                   "levels at P1-P4"):  # the file's header in the stamp
        assert needle in text, needle
    assert not [p for p in out.iterdir() if p.name.startswith("_")]  # staging figures gone


def test_html_states_what_each_file_says_of_itself(fitted):
    """Instrument serials, dates, temperatures, operator and machine S/N that a file's profile
    or metadata lines read (report.json's measurements.files[].metadata) are on the page."""
    out, _ = fitted
    rep = json.loads((out / "report.json").read_text())
    rep["measurements"]["files"][0]["metadata"] = {
        "instrument serial": "WY-<12345>", "date": "2026-11-02", "temperature_C": 20.4,
        "operator": "J. Kowalski", "machine S/N": "VMC-0815"}
    text = report_html(rep)
    for needle in ("instrument serial", "WY-&lt;12345&gt;", "2026-11-02", "temperature_C",
                   "20.4", "J. Kowalski", "machine S/N", "VMC-0815"):
        assert needle in text, needle


def test_html_shows_each_files_chi2(fitted):
    """Several files (a reversed one accepted with --accept-file-conflicts): report.json's
    elastic.files rows, each file's χ² against the fit of all, are a table on the page; one
    file gives no such table (and an empty list)."""
    out, _ = fitted
    rep = json.loads((out / "report.json").read_text())
    assert rep["elastic"]["files"] == [] and 'id="files"' not in report_html(rep)
    rep["elastic"]["files"] = [
        {"file": "a<1>.csv", "rows": 36, "readings": 360, "chi2": 30.5, "dof": 33.0,
         "chi2_per_dof": 30.5 / 33.0},
        {"file": "b.csv", "rows": 36, "readings": 144, "chi2": 4012.0, "dof": 33.0,
         "chi2_per_dof": 4012.0 / 33.0}]
    text = report_html(rep)
    for needle in ('id="files"', "a&lt;1&gt;.csv", "30.5", "0.924", "b.csv", "4012", "121.576"):
        assert needle in text, needle


def test_console_says_the_same(fitted):
    out, console = fitted
    st = json.loads((out / "report.json").read_text())["straightness"]
    for line in [*straightness_lines(st), verdict_line(st)]:
        assert line in console


def test_html_without_figures(fitted):
    # --no-plots: the same page, figures left out
    out, _ = fitted
    rep = json.loads((out / "report.json").read_text())
    page = _parse(report_html(rep, {}))
    assert not page.images
    _check_table(page, rep["straightness"])


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
        pytest.fail("chromium is missing under CI (.ci/run installs it)")
    pytest.skip("chromium not installed (apt-get install chromium)")


def test_opens_in_headless_chromium(fitted, tmp_path):
    exe = _chromium()
    out, _ = fitted
    url = (out / "report.html").resolve().as_uri()
    base = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
            "--no-first-run", "--hide-scrollbars", f"--user-data-dir={tmp_path / 'profile'}"]
    shot = tmp_path / "report.png"
    subprocess.run([*base, f"--screenshot={shot}", "--window-size=1200,2400", url],
                   capture_output=True, timeout=180, check=True)
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import matplotlib.image

    img = matplotlib.image.imread(shot)
    assert img.shape[0] >= 2000 and img.shape[1] >= 1000
    colours = np.unique((img[..., :3] * 255).astype(np.uint8).reshape(-1, 3), axis=0)
    assert len(colours) > 50 and img[..., :3].std() > 0.02  # text, tables, figures: not blank
    dom = subprocess.run([*base, "--dump-dom", url], capture_output=True, timeout=180,
                         check=True, text=True).stdout
    assert "chrome-error" not in dom and "ERR_" not in dom
    page = _parse(dom)
    _check_table(page, json.loads((out / "report.json").read_text())["straightness"])
    assert len(page.images) == 3


@pytest.mark.parametrize("value", ["0", "-3", "nan", "1e6"])
def test_bad_tolerance_is_refused_before_any_work(tmp_path, capsys, value):
    out = tmp_path / "out"
    assert main(["fit", "--preset", "majda2012", "--measurements", str(DATA), "--out", str(out),
                 "--tolerance-um", value, "--quiet"]) == 2
    assert "--tolerance-um must be a straightness tolerance in (0, 10000] µm" in \
        capsys.readouterr().err
    assert not out.exists()


def test_report_figures_take_ax_and_draw(tmp_path):
    # the figures of report.html on synthetic input: given Axes are drawn into and returned;
    # the bare figures save (as the figures' process does)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from diffguide.plotting.report import (
        plot_residuals,
        plot_straightness,
        residuals_figure,
        straightness_figure,
    )

    s = np.linspace(-300.0, 300.0, 61)
    dev = np.sin(s / 100.0)[None, None] * np.ones((2, 2, 1))
    sig = 0.1 * np.ones_like(dev)
    rows = [{"rail": r + 1, "side": "−y" if r == 0 else "+y", "y_mm": -170.0 + 340.0 * r,
             "plane": pl, "straightness_um": 2.0, "interval_95_um": [1.8, 2.3],
             "verdict": None}
            for r in range(2) for pl in ("vertical", "horizontal")]
    chans = [(f"EAX (roll) at P{k}", "µrad", s, np.cos(s), 0.5 + 0 * s) for k in range(3)]
    fig, axes = plt.subplots(2, 2)
    assert plot_straightness(s, dev, sig, rows, ax=axes)[1, 0] is axes[1, 0]
    assert "rail 1, −y side" in axes[0, 0].get_title()
    fig2, axes2 = plt.subplots(2, 2)
    got = plot_residuals(chans, ax=axes2)
    assert got[1, 0] is axes2[1, 0] and not axes2[1, 1].get_visible()
    plt.close(fig)
    plt.close(fig2)
    straightness_figure(s, dev, sig, rows).savefig(tmp_path / "a.png")
    residuals_figure(chans[:1]).savefig(tmp_path / "b.png")
    assert (tmp_path / "a.png").read_bytes()[:4] == b"\x89PNG"
