"""``report.html``: a fit's report for a metrologist, one self-contained file (figures
embedded as base64 PNG, no script, no network, no external style sheet), built from
``report.json``'s own content so that both show the same numbers; and the console's lines
that say the same in the same words (:func:`straightness_lines`, :func:`verdict_line`)."""

import base64
import html
import json

from .report_text import undetermined_lines

#: Decimals of the straightness table (µm): 10 nm.
DECIMALS = 2

_CSS = """
body{font-family:sans-serif;max-width:1150px;margin:1.5em auto;padding:0 1em;color:#222}
h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ccc;margin-top:1.6em}
table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #bbb;padding:.25em .6em}
th{background:#eee}td.num{text-align:right;font-variant-numeric:tabular-nums}
.pass{background:#d8f0d8}.fail{background:#f6d0d0}.undecided{background:#f8ecc8}
.note{color:#555;font-size:.92em}img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:.92em;color:#444;margin-bottom:1em}code{background:#f3f3f3}
"""


def _e(x) -> str:
    return html.escape(str(x))


def _num(x, decimals: int = DECIMALS) -> str:
    return "—" if x is None else f"{x:.{decimals}f}"


def _rail_words(row: dict) -> str:
    side = f" ({row['side']} side)" if row.get("side") else ""
    return f"rail {row['rail']}{side} {row['plane']}"


def straightness_lines(section: dict) -> list[str]:
    """One line per rail and plane: straightness (the draws' median), its 95 % interval, the
    mean profile's value, and the verdict with its reason (µm)."""
    lines = []
    for row in section["rails"]:
        lo, hi = row["interval_95_um"]
        text = (f"{_rail_words(row)}: straightness {_num(row['straightness_um'])} µm, 95 % "
                f"interval {_num(lo)} … {_num(hi)} µm (mean profile's "
                f"{_num(row['mean_profile_um'])} µm)")
        if row.get("verdict"):
            text += f": {row['verdict']} ({row['verdict_reason']})"
        lines.append(text)
    return lines


def verdict_line(section: dict) -> str:
    """The overall verdict: fail if any profile fails, not decidable if any is, else pass
    (ISO 14253-1 per profile); or that no tolerance was stated."""
    verdicts = [r["verdict"] for r in section["rails"]]
    tol = section.get("tolerance_um")
    if tol is None or None in verdicts:
        return ("no verdict: no tolerance stated (give --tolerance-um to judge the straightness "
                "by ISO 14253-1)")
    overall = ("fail" if "fail" in verdicts else "not decidable" if "not decidable" in verdicts
               else "pass")
    return (f"verdict: {overall} — straightness of every rail and plane against {tol:g} µm "
            f"({section['decision_rule']})")


def _straightness_table(section: dict) -> str:
    rows = []
    for r in section["rails"]:
        v = r.get("verdict")
        cls = {"pass": "pass", "fail": "fail", "not decidable": "undecided"}.get(v, "")
        lo, hi = r["interval_95_um"]
        y = "" if r.get("y_mm") is None else f" (y = {r['y_mm']:g} mm)"
        rows.append(
            f'<tr data-rail="{r["rail"]}" data-plane="{_e(r["plane"])}">'
            f'<td>{r["rail"]}</td><td>{_e(r.get("side") or "")}{y}</td><td>{_e(r["plane"])}</td>'
            f'<td class="num" data-key="straightness_um">{_num(r["straightness_um"])}</td>'
            f'<td class="num" data-key="interval_95_um">{_num(lo)} … {_num(hi)}</td>'
            f'<td class="num" data-key="mean_profile_um">{_num(r["mean_profile_um"])}</td>'
            f'<td class="num" data-key="u_um">{_num(r["u_um"])}</td>'
            f'<td class="verdict {cls}" data-key="verdict" '
            f'title="{_e(r.get("verdict_reason") or "")}">'
            f'{_e(v or "no tolerance")}</td></tr>')
    return ('<table id="straightness"><tr><th>rail</th><th>side</th><th>plane</th>'
            '<th>straightness: median of the draws (µm)</th><th>95 % interval of the draws '
            '(µm)</th><th>mean profile\'s (µm)</th><th>u: standard deviation of the draws '
            '(µm)</th><th>verdict</th></tr>' + "".join(rows) + "</table>")


def _reasons(section: dict) -> str:
    """Each profile's verdict with its reason, as a list (none without a tolerance)."""
    items = [f"<li>{_e(_rail_words(r))}: {_e(r['verdict'])} — {_e(r['verdict_reason'])}</li>"
             for r in section["rails"] if r.get("verdict")]
    return f'<ul class="note" id="verdict-reasons">{"".join(items)}</ul>' if items else ""


def _figure(figures: dict, name: str, caption: str) -> str:
    png = figures.get(name)
    if png is None:
        return ""
    data = base64.b64encode(png).decode("ascii")
    return (f'<figure><img alt="{_e(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{_e(caption)}</figcaption></figure>")


#: What each combination of the two rails does to the table (rigid-body reading).
_COMBINATION_WORDS = {
    "vertical mean": "the table's vertical straightness (EZX) and pitch (EBX)",
    "vertical difference": "the table's roll (EAX)",
    "horizontal mean": "the table's horizontal straightness (EYX) and yaw (ECX)",
    "horizontal difference": "the rails' spacing: no rigid-body motion, seen only through the "
                             "table's elastic response",
}


def _determined_section(report: dict) -> str:
    ident = report["identifiability"]
    el = report["elastic"]
    items = [f"<li>{_e(line)}</li>" for line in
             undetermined_lines(ident, el["resolution"]["rail_waviness_um"] * 1e-6)]
    rows = []
    for c in ident["wavelengths"]:
        bands = ", ".join(f"{lo:.0f}–{hi:.0f}" for lo, hi in c["undetermined_wavelengths_mm"])
        key = " ".join(c["combination"].split()[:2])
        words = _COMBINATION_WORDS.get(key, "")
        bands = bands or "none: determined at every analysed wavelength"
        rows.append(f"<tr><td>{_e(c['combination'])}</td><td>{_e(words)}</td>"
                    f"<td>{_e(bands)}</td></tr>")
    lam = [r["wavelength_mm"] for c in ident["wavelengths"] for r in c["transfer"]]
    span = f"{min(lam):.0f}–{max(lam):.0f} mm" if lam else "—"
    for name, s in el["structure"].items():
        items.append(f"<li>{_e(s.get('label', name))}: {s['value']:.4g} ± {s['sigma']:.2g} "
                     f"{_e(s['unit'])} — "
                     f"{_e(s['note'])}</li>")
    if el["resolution"]["rail_waviness_um"] > 0:
        items.append(f"<li>{_e(el['resolution']['note'])}</li>")
    for d in el.get("rail_joint_steps_um", []):
        items.append(f"<li>step at the rail joint s = {d['s_mm']:g} mm, rail {d['rail']} "
                     f"{_e(d['plane'])}: {d['value']:+.3g} ± {d['sigma']:.2g} µm (fitted)</li>")
    items.append(f"<li>{_e(ident['gauge']['note'])}: each rail's offset and the rails' common "
                 "slope are not measured; the straightness does not depend on them</li>")
    return (f"<p>A wavelength is <em>determined</em> where the fit recovers at least "
            f"{ident['threshold']:.0%} of a sinusoid of that wavelength (analysed: {span}); "
            "elsewhere the profile is the prior's guess and its band the prior's.</p>"
            "<table id=\"wavelengths\"><tr><th>combination of the rails</th><th>what it moves"
            "</th><th>not determined (wavelengths, mm)</th></tr>" + "".join(rows) + "</table>"
            f"<ul>{''.join(items)}</ul>")


def _files_section(report: dict) -> str:
    """Each measurement file's χ² against the fit of all of them (several files only)."""
    files = report["elastic"].get("files") or []
    if not files:
        return ""
    rows = "".join(
        f"<tr><td>{_e(f['file'])}</td><td class=\"num\">{f['rows']}</td>"
        f"<td class=\"num\">{f['chi2']:.4g}</td><td class=\"num\">{f['dof']:.4g}</td>"
        f"<td class=\"num\">{_num(f['chi2_per_dof'], 3)}</td></tr>" for f in files)
    return ("<table id=\"files\"><tr><th>measurement file</th><th>merged values read</th>"
            "<th>χ²</th><th>dof (its share)</th><th>χ²/dof</th></tr>" + rows + "</table>"
            "<p class=\"note\">Each file's values against the fit of all the files; a file "
            "far above 1 is the one the model does not explain (a reversed sensor?).</p>")


def _compensation_section(report: dict) -> str:
    comp = report["compensation"]
    rows = "".join(
        f"<tr><td>{_e(named(c['channel']))}</td><td class=\"num\">{c['fitted_range_user']:.3g}"
        f"</td><td class=\"num\">{c['residual_rms_user']:.3g}</td><td>{_e(c['unit'])}</td>"
        f"<td class=\"num\">{_ratio(c)}</td></tr>" for c in comp["channels"])
    ex = comp.get("export")
    export = ("<p>No compensation table was requested (<code>--export-compensation</code>).</p>"
              if not ex else
              f"<p>Compensation table: <code>{_e(ex['file'])}</code>, format {_e(ex['format'])}, "
              f"at point {_e(ex['point'])}.</p>")
    return (export + "<table id=\"compensation\"><tr><th>channel</th><th>fitted error range"
            "</th><th>residual RMS</th><th>unit</th><th>range / residual RMS</th></tr>"
            + rows + "</table>"
            f"<p class=\"note\">{_e(comp['note'])}.</p>")


#: What each joint error of the X axis is, in a metrologist's words (ISO 230-1).
ERROR_WORDS = {"EXX": "positioning", "EYX": "horizontal straightness",
               "EZX": "vertical straightness", "EAX": "roll", "EBX": "pitch", "ECX": "yaw"}


def named(label: str) -> str:
    """``"EBX at P1 (level)"`` → ``"EBX (pitch) at P1 (level)"``."""
    q, sep, rest = label.partition(" ")
    return f"{q} ({ERROR_WORDS[q]}){sep}{rest}" if q in ERROR_WORDS else label


def _ratio(c: dict) -> str:
    r = c["residual_rms_user"]
    return "—" if not r else f"{c['fitted_range_user'] / r:.1f}"


def _stamp(report: dict) -> str:
    st = report["stamp"]
    rows = [("machine", st["machine"]), ("date", st["date_utc"]),
            ("diffguide", st["diffguide"])]
    if st.get("layout"):
        rows.append(("layout read", st["layout"]))
    if st.get("x0_mm") is not None:
        rows.append(("machine coordinate of x = 0", f"{st['x0_mm']:g} mm"))
    meta = {f.get("file"): f.get("metadata") or {}
            for f in report.get("measurements", {}).get("files", [])}
    for f in st["files"]:
        rows.append(("measurement file", f["file"]))
        rows += [("  header", line) for line in f["header"]]
        # what the file states of itself (instrument serials, dates, temperatures, operator,
        # machine serial number, ... as its profile or metadata lines read them): traceability
        rows += [(f"  {key}", value if isinstance(value, str) else json.dumps(value))
                 for key, value in meta.get(f["file"], {}).items()]
    rows += [("reading note", n) for n in st.get("reading_notes", [])]
    m = report["measurements"]
    rows.append(("readings", f"{m['readings']} readings merged into {m['merged_rows']} values"))
    return ('<table id="stamp">' + "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>"
                                           for k, v in rows) + "</table>")


def _status(report: dict) -> str:
    el = report["elastic"]
    chi = el["chi2_per_dof"]
    how = "" if el["status"] == "converged" else f" ({_e(el['status'])})"
    lines = [f"fit {'converged' if el['converged'] else 'did NOT converge'}{how};"
             f" χ²/dof = {'—' if chi is None else f'{chi:.3f}'} (about 1 when the model "
             "explains the data to their stated uncertainty)"]
    lines += [f"warning: {_e(w['message'])}; {_e(w['action'])}" for w in report["validity"]]
    return "".join(f"<p>{line}</p>" for line in lines)


def report_html(report: dict, figures: dict | None = None) -> str:
    """The HTML text of ``report`` (``report.json``'s content, as loaded from the file) with
    ``figures`` ``{"straightness.png" | "residuals.png" | "curves.png": PNG bytes}`` embedded
    (a figure not given is left out)."""
    figures = figures or {}
    st = report["straightness"]
    plan = report.get("plan_suggestion")
    parts = [
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">",
        f"<title>diffguide fit report — {_e(report['stamp']['machine'])}</title>",
        f"<style>{_CSS}</style></head><body>",
        f"<h1>Rail straightness report — {_e(report['stamp']['machine'])}</h1>",
        _stamp(report), _status(report),
        "<h2>Straightness per rail and plane</h2>",
        f"<p>Reference line: <strong>{_e(st['reference_line'])}</strong>; straightness = "
        f"{_e(st['definition'])} (s = {st['evaluated_s_mm'][0]:g} … "
        f"{st['evaluated_s_mm'][1]:g} mm, every {st['grid_step_mm']:g} mm). Uncertainty: "
        f"{_e(st['uncertainty_method'])}. Bias: {_e(st['estimate_bias'])}. Not in the "
        f"interval: {_e(st['not_in_interval'])}.</p>",
        _straightness_table(st),
        _reasons(st),
        "" if figures else "<p class=\"note\">Figures left out (--no-plots).</p>",
        f'<p id="verdict"><strong>{_e(verdict_line(st))}</strong></p>',
        _figure(figures, "straightness.png",
                "Deviations of each rail from its least-squares reference line (µm); band: ±2σ "
                "(k = 2) of the fit's posterior; ▲ peak, ▼ valley. Rail 1 is at the smaller y."),
        "<h2>What the data determine, and what they cannot</h2>", _determined_section(report),
        ("" if not plan else
         f"<p>What more instruments would determine there: <code>{_e(plan)}</code></p>"),
        "<h2>Compensation and residuals</h2>", _compensation_section(report),
        _files_section(report),
        _figure(figures, "residuals.png",
                "Residuals, measured − fitted, per channel against the table position; error "
                "bars ±1σ (the standard uncertainty of each merged value). EAX roll, EBX pitch, "
                "ECX yaw; EXX positioning, EYX/EZX horizontal/vertical straightness."),
        _figure(figures, "curves.png",
                "Measured joint errors (error bars ±1σ) and the fitted model per channel."),
        "<p class=\"note\">Written by diffguide fit beside report.json, which holds every number "
        "of this page.</p></body></html>",
    ]
    return "\n".join(p for p in parts if p) + "\n"
