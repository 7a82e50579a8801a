"""The files of ``diffguide plan``: candidate sites and placements read from CSV (mm on the
table top), and the plan written as ``plan.csv`` and the report's JSON fields.

Sites CSV: ``name,x_mm,y_mm``. Placements CSV: ``instrument,x_mm,y_mm[,point][,reads]``
(instrument ``level``, ``interferometer`` or ``straightness``; the ``layout.csv`` that
``diffguide fit`` writes is one), or ``bundled``: the bundled data set's layout.
"""

import numpy as np

from ..planning.instruments import KINDS, bundled_layout_mm, check_on_table, place_on_sites
from .csvtable import number, read_table


def _rows(path, required, optional=()):
    """The data rows of a small CSV (:func:`~.csvtable.read_table`: comments, blank lines,
    separators and one-line errors as for every input file)."""
    rows = read_table(path, required, optional)
    if not rows:
        raise ValueError(f"{path}: no rows")
    return rows


def _mm(path, line, row, key) -> float:
    return number(row, key, str(path), line, "mm")


def read_sites(path, table_mm) -> dict:
    """Candidate sites ``{name: (x, y)}`` (m) from a ``name,x_mm,y_mm`` CSV; names unique and
    non-empty, every site on the ``table_mm = (length, width)`` (mm) table top."""
    out = {}
    for line, row in _rows(path, ("name", "x_mm", "y_mm")):
        x, y = (_mm(path, line, row, k) for k in ("x_mm", "y_mm"))
        name = row["name"]
        if not name or name in out:
            raise ValueError(
                f"{path}:{line}: site names must be unique and non-empty, got {name!r}"
            )
        check_on_table(name, x, y, table_mm, f"{path}:{line}")
        out[name] = (x * 1e-3, y * 1e-3)
    return out


def read_placement_rows(path, table_mm) -> list[tuple[str, float, float]]:
    """``(kind, x_mm, y_mm)`` of a placements CSV: known kinds, sites on the table top, one
    location per ``point`` name."""
    rows, named = [], {}
    for line, row in _rows(path, ("instrument", "x_mm", "y_mm"), ("point", "reads")):
        kind = row["instrument"]
        if kind not in KINDS:
            raise ValueError(
                f"{path}:{line}: field 'instrument': must be one of "
                f"{', '.join(KINDS)}, got {kind!r}"
            )
        x, y = (_mm(path, line, row, k) for k in ("x_mm", "y_mm"))
        check_on_table(row.get("point", "?"), x, y, table_mm, f"{path}:{line}")
        if row.get("point"):
            first = named.setdefault(row["point"], (line, x, y))
            if abs(first[1] - x) > 1e-6 or abs(first[2] - y) > 1e-6:
                raise ValueError(
                    f"{path}:{line}: field 'point': {row['point']!r} is at "
                    f"({x:g}, {y:g}) mm here but at ({first[1]:g}, {first[2]:g}) mm on line "
                    f"{first[0]}; one name, one location"
                )
        rows.append((kind, x, y))
    return rows


def read_placements(which, option, table_mm, sites: dict) -> list[tuple[str, str]]:
    """A plan given as ``"bundled"`` or a placements CSV, as ``(kind, site)``, adding its sites
    to ``sites`` where new (:func:`~diffguide.planning.instruments.place_on_sites`); ``option``
    names the command-line option in errors."""
    if which == "bundled":
        rows, where = bundled_layout_mm(*table_mm), "bundled layout"
    else:
        rows, where = read_placement_rows(which, table_mm), which
    return place_on_sites(rows, sites, f"{option} {where}")


def plan_csv(result) -> str:
    """``plan.csv``: the greedy steps of a :class:`~diffguide.planning.Plan` in order, what
    each bought (criterion before and after, worst and RMS profile σ in µm)."""
    crit = result.criterion
    unit = "nats" if crit == "D" else "um"
    lines = [
        f"step,instrument,site,x_mm,y_mm,reads,{crit}_before_{unit},{crit}_after_{unit},"
        "worst_sigma_um,rms_sigma_um"
    ]
    for k, s in enumerate(result.steps):
        lines.append(
            f"{k + 1},{s.placement[0]},{s.placement[1]},{s.xy[0] * 1e3:.1f},"
            f"{s.xy[1] * 1e3:.1f},{'+'.join(s.quantities)},{s.before:.5g},"
            f"{s.after:.5g},{s.worst * 1e6:.5g},{s.rms * 1e6:.5g}"
        )
    return "\n".join(lines) + "\n"


def evaluation_json(ev, sites) -> dict:
    """An :class:`~diffguide.planning.Evaluation` as the report's JSON fields (µm, mm)."""
    return {
        "placements": [
            {"instrument": k, "site": s, "x_mm": sites[s][0] * 1e3, "y_mm": sites[s][1] * 1e3}
            for k, s in ev.placements
        ],
        "worst_profile_sigma_um": ev.worst * 1e6,
        "rms_profile_sigma_um": ev.rms * 1e6,
        "log_det_cov": ev.logdet,
        "work_point_sigma": None if not np.isfinite(ev.work) else ev.work * 1e6,
        "worst_profile_sigma_um_per_profile": {
            f"rail {r + 1} {pl}": float(ev.sigma[r, p].max() * 1e6)
            for r in range(2)
            for p, pl in enumerate(("vertical", "horizontal"))
        },
        "structure_posterior_over_prior_sigma": ev.structure_ratio,
    }


def _site_json(kind, name, sites) -> dict:
    x, y = sites[name]
    return {"instrument": kind, "site": name, "x_mm": x * 1e3, "y_mm": y * 1e3}


def plan_report(result, sites, start, compare, settings: dict) -> dict:
    """The fields of ``report.json`` (before its total time) for a plan ``result``:
    ``settings`` (command, preset, config, mesh; positions, runs, directions, structure,
    draws, rail_rms_um) as given, the instruments, sites, steps and the evaluations."""
    head = ("command", "preset", "config", "mesh")
    return {
        **{k: settings[k] for k in head},
        "criterion": result.criterion,
        "criterion_unit": "nats" if result.criterion == "D" else "µm (µm/m for angles)",
        "lambda": result.lam,
        "rail_rms_um": settings["rail_rms_um"],
        "lambda_note": "pass to 'diffguide fit --lambda' to fit with the planner's prior",
        **{k: settings[k] for k in ("positions", "runs", "directions")},
        "instruments": [
            {
                "kind": i.kind,
                "count": i.count,
                "reads": list(i.quantities),
                "reading_sigma": i.sigma * 1e6,
            }
            for i in result.instruments
        ],
        **{k: settings[k] for k in ("structure", "draws")},
        "gauge": "each profile's mean and each plane's common slope removed",
        "candidate_sites": {n: [sites[n][0] * 1e3, sites[n][1] * 1e3] for n in result.candidates},
        "start": [_site_json(k, n, sites) for k, n in start],
        "steps": [
            {
                **_site_json(*s.placement, {s.placement[1]: s.xy}),
                "reads": list(s.quantities),
                "before": s.before,
                "after": s.after,
                "worst_sigma_um": s.worst * 1e6,
                "rms_sigma_um": s.rms * 1e6,
            }
            for s in result.steps
        ],
        "plan": evaluation_json(result.best, sites),
        "compare": None if compare is None else evaluation_json(result.compare, sites),
        "prior_only": evaluation_json(result.prior, sites),
        "planning_seconds": result.seconds,
    }
