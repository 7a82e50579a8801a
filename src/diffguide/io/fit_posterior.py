"""``posterior.json`` of a fit's output folder: what ``diffguide predict`` needs to rebuild the
fit's posterior — the rails' knot grid and coefficients, the full posterior covariance of the
rails, the structure and the lead/alignment nuisances, the structure's estimate and prior, the
lead spline, the measured positions' range and points, and the machine (preset or machine file,
mesh) — in SI units (m; the structure in prior σ of its log, thickness in m, preload a fraction
of C). A separate file: the formats of rails.csv and report.json are unchanged.

Keys: ``format`` (:data:`FORMAT`), ``units``, ``knots`` ``{start_m, spacing_m, n}``,
``coeffs_m`` ``[2 rails][2 planes (vertical, horizontal)][n]``, ``cov`` (``n_v × n_v``, the order
of ``v = (c, q, ℓ)``: the four profiles' coefficients rail 1 vertical, rail 1 horizontal, rail 2
vertical, rail 2 horizontal; the structural unknowns; the lead coefficients then the alignment
slopes), ``structure`` ``{name: {value, prior_value, prior_sigma_log}}`` (fit order), ``lead_m``,
``lead_knots`` (``[start_m, spacing_m, n]`` or ``[]``), ``position_range_m``, ``rigid``,
``x_ref_m``, ``points_m`` ``{name: [x, y]}``, ``machine`` ``{preset, config, nx, ny}``,
``x0_mm``.
"""

import json
from pathlib import Path

import numpy as np

from .._core.limits import MAX_MESH_DIVISIONS, check_range
from ..guideway.rails import JOINT_WIDTH
from ..inverse.predict import FitPosterior

FORMAT = "diffguide fit posterior 1"
NAME = "posterior.json"


def posterior_json_text(fit, meas, *, preset: str | None, config: str | None,
                        nx: int | None, ny: int | None, x0_mm: float | None = None) -> str:
    """The file's text for the elastic ``fit`` (a :class:`~diffguide.inverse.RailFit`) of
    ``meas`` and the machine it was fitted with (``preset`` or the machine file ``config``,
    absolute path; the mesh ``nx × ny``, ``None`` the machine's own)."""
    post = FitPosterior.from_fit(fit)
    data = {
        "format": FORMAT,
        "units": "SI: m, rad; structure unknowns in prior sigma of their log",
        "knots": {"start_m": post.start, "spacing_m": post.spacing, "n": post.n_coeffs,
                  "joints_m": list(post.joints), "joint_width_m": post.joint_width},
        "coeffs_m": post.coeffs.tolist(),
        "cov": post.cov.tolist(),
        "structure": post.structure,
        "lead_m": post.lead.tolist(),
        "lead_knots": list(post.lead_basis),
        "position_range_m": list(post.position_range),
        "rigid": post.rigid,
        "x_ref_m": post.x_ref,
        "points_m": {n: [float(x), float(y)] for n, (x, y) in
                     zip(meas.point_names, np.asarray(meas.points_xy, float))},
        "machine": {"preset": preset,
                    "config": None if config is None else str(Path(config).resolve()),
                    "nx": nx, "ny": ny},
        "x0_mm": x0_mm,
    }
    return json.dumps(data, allow_nan=False) + "\n"


def read_fit_posterior(folder) -> tuple[FitPosterior, dict]:
    """``(FitPosterior, meta)`` from a fit's output folder (``meta``: ``points_m``,
    ``machine``, ``x0_mm``). ``ValueError`` naming the file when it is missing (a fit written
    before this file existed: fit again) or malformed."""
    path = Path(folder) / NAME
    if not path.is_file():
        hint = (" (a fit output folder written before predict existed: run diffguide fit again)"
                if (Path(folder) / "report.json").exists() else
                " (not a 'diffguide fit --out' folder)")
        raise ValueError(f"{path}: not found{hint}")
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
        if d.get("format") != FORMAT:
            raise ValueError(f"format is {d.get('format')!r}, expected {FORMAT!r}")
        k = d["knots"]
        post = FitPosterior(
            start=float(k["start_m"]), spacing=float(k["spacing_m"]), n_coeffs=int(k["n"]),
            coeffs=np.asarray(d["coeffs_m"], float), cov=np.asarray(d["cov"], float),
            structure={n: {a: float(b) for a, b in v.items()}
                       for n, v in d["structure"].items()},
            lead=np.asarray(d["lead_m"], float), lead_basis=_lead_knots(d["lead_knots"]),
            position_range=tuple(map(float, d["position_range_m"])), rigid=bool(d["rigid"]),
            x_ref=float(d["x_ref_m"]), joints=tuple(map(float, k.get("joints_m", ()))),
            joint_width=float(k.get("joint_width_m", JOINT_WIDTH)))
        if not (np.all(np.isfinite(post.coeffs)) and np.all(np.isfinite(post.cov))):
            raise ValueError("non-finite coefficients or covariance")
        meta = {"points_m": {n: (float(x), float(y)) for n, (x, y) in d["points_m"].items()},
                "machine": dict(d["machine"]), "x0_mm": d.get("x0_mm")}
        for key in ("nx", "ny"):  # before a machine of that mesh is built
            v = meta["machine"].get(key)
            if v is not None:
                check_range(v, 1, MAX_MESH_DIVISIONS, f"machine.{key} (the fit's table mesh)")
    except (KeyError, TypeError, ValueError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: malformed ({type(exc).__name__}: {exc})") from None
    return post, meta


def _lead_knots(v) -> tuple:
    """``[start_m, spacing_m, n]`` → ``(float, float, int)``; ``[]`` → ``()``."""
    if not v:
        return ()
    start, spacing, n = v
    return float(start), float(spacing), int(n)
