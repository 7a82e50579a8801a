"""The files of ``diffguide design``: the history of evaluations (CSV) and the result (JSON),
in user units (:class:`diffguide.studies.DesignResult` in SI inside)."""

import json


def history_csv(res) -> str:
    """One row per evaluation (user units): variables, objective with its interval, its
    derivatives, failed samples."""
    u = 1e6
    head = ["evaluation", "iteration"]
    head += [f"{n}_{unit}" for n, unit in zip(res.variables, res.units)]
    ou = res.unit
    head += [f"objective_{ou}", f"objective_low_{ou}", f"objective_high_{ou}"]
    head += [f"d_objective_d_{n}_{ou}_per_{unit}" for n, unit in zip(res.variables, res.units)]
    head += ["failed", "stage"]
    lines = [",".join(head).replace("µ", "u").replace("%", "pct")]
    for k, r in enumerate(res.history, 1):
        cells = [str(k), str(r["iteration"])]
        cells += [f"{x / s:.8g}" for x, s in zip(r["x"], res.scales)]
        cells += [f"{v * u:.8g}" for v in (r["objective"], *r["interval"])]
        cells += [f"{g * u * s:.8g}" for g, s in zip(r["gradient"], res.scales)]
        cells += [str(r["failed"]), str(r.get("stage", 0))]
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def _est(e) -> dict | None:
    if e is None:
        return None
    return {"value": e.value * 1e6, "interval": [v * 1e6 for v in e.interval], "samples": e.n,
            "failed": e.failed}


def as_json(res) -> dict:
    """The result for ``--json`` (user units, plain JSON types)."""
    from ..studies.design_space import CONSTRAINTS

    variables = {}
    for j, (n, unit, s) in enumerate(zip(res.variables, res.units, res.scales)):
        variables[n] = {"unit": unit, "bounds": [b / s for b in res.bounds[j]],
                        "start": res.start[j] / s, "optimum": res.optimum[j] / s,
                        "sensitivity": res.sensitivities[j] * 1e6 * s,
                        "sensitivity_unit": f"{res.unit}/{unit}"}
    cons = []
    for text, slack, active in res.constraints:
        q = CONSTRAINTS[text.split()[0]]
        cons.append({"constraint": text, "slack": slack / q.scale, "unit": q.unit,
                     "active": active})
    return {"objective": res.objective.text(), "unit": res.unit,
            "variables": variables, "before": _est(res.before), "after": _est(res.after),
            "fresh_before": _est(res.fresh_before), "fresh_after": _est(res.fresh_after),
            "improvement": _est(res.improvement), "improved": res.improved,
            "constraints": cons, "active_bounds": [list(a) for a in res.active_bounds],
            "evaluations": res.evaluations, "sample_sweeps": res.sample_sweeps,
            "samples": res.n_samples, "seed": res.seed, "fresh_seed": res.fresh_seed,
            "success": res.success, "message": res.message, "seconds": res.seconds,
            "stages": [{"stage": st["stage"], "carriage_x_mm": [v * 1e3 for v in st["carriage_x"]],
                        "rail_y_mm": [v * 1e3 for v in st["rail_y"]],
                        "optimum": [v / s for v, s in zip(st["optimum"], res.scales)],
                        "objective": st["objective"] * 1e6, "recentred": st["recentred"],
                        "message": st["message"]} for st in res.stages]}


def design_json_text(res) -> str:
    """The ``--json`` file's text: :func:`as_json`, indented."""
    return json.dumps(as_json(res), indent=2) + "\n"
