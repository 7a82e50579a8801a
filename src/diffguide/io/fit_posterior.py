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
``x0_mm``; and (format 2) the machine's ``fingerprint`` and ``snapshot`` under ``machine``
(:func:`machine_snapshot`), and ``checksum``: the SHA-256 of the file's own content without it
(:func:`content_fingerprint`: canonical JSON, so re-indenting the file does not change it,
editing a value does).

Reading is strict (:func:`read_fit_posterior`): every field of its JSON type (a bool a JSON
``true``/``false``, never the string ``"false"``; numbers finite numbers, not strings), shapes
consistent, variances not negative, the checksum matching; each error names the file and the
field. A file of format 1 (before the checksum) is read with a warning: its content and its
machine cannot be checked.
"""

import hashlib
import json
import math
import os
from pathlib import Path

import numpy as np

from .._core.limits import MAX_MESH_DIVISIONS, check_range
from ..guideway.rails import JOINT_WIDTH
from ..inverse.basis import RailBasis
from ..inverse.predict import FitPosterior

FORMAT = "diffguide fit posterior 2"
#: The format before the checksum and the machine's fingerprint: read with a warning.
FORMAT_1 = "diffguide fit posterior 1"
NAME = "posterior.json"
#: Sections of a machine configuration that do not define the machine ``predict`` builds: the
#: fit's own settings, the instruments' points (``predict`` takes those from the file) and the
#: controller settings of the compensation exports (how a table is written, not the machine).
NOT_MACHINE = ("fit", "points", "export")
#: Keys of an imported table's description file that name the files it reads.
_TABLE_FILES = ("matrix", "nodes", "held_loads")


def content_fingerprint(obj) -> str:
    """SHA-256 (hex) of ``obj``'s canonical JSON (sorted keys, no spaces, NaN refused): the
    same for any two objects that JSON reads back equal, whatever their layout in a file."""
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False,
                      allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def posterior_json_text(fit, meas, *, preset: str | None, config: str | None,
                        nx: int | None, ny: int | None, x0_mm: float | None = None,
                        machine_cfg: dict | None = None) -> str:
    """The file's text for the elastic ``fit`` (a :class:`~diffguide.inverse.RailFit`) of
    ``meas`` and the machine it was fitted with (``preset`` or the machine file ``config``,
    absolute path; the mesh ``nx × ny``, ``None`` the machine's own; ``machine_cfg`` its
    validated configuration, for the fingerprint — None: the preset's or the file's, read
    now)."""
    post = FitPosterior.from_fit(fit)
    snap = machine_snapshot(machine_cfg if machine_cfg is not None else _config_of(config))
    data = {
        "format": FORMAT,
        "units": "SI: m, rad; structure unknowns in prior sigma of their log",
        "knots": {"start_m": post.basis.start, "spacing_m": post.basis.spacing,
                  "n": post.basis.n_coeffs, "joints_m": list(post.basis.joints),
                  "joint_width_m": post.basis.joint_width},
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
                    "nx": nx, "ny": ny, "fingerprint": content_fingerprint(snap),
                    "snapshot": snap},
        "x0_mm": x0_mm,
    }
    return stamped_text(data)


def stamped_text(data: dict) -> str:
    """``data`` as the file's text with its ``checksum`` (replaced if present)."""
    body = {k: v for k, v in data.items() if k != "checksum"}
    return json.dumps({**body, "checksum": content_fingerprint(body)}, allow_nan=False) + "\n"


def _config_of(config) -> dict:
    from .config import default_config, load_config

    return load_config(config) if config else default_config()


def machine_snapshot(cfg: dict) -> dict:
    """The machine's configuration as its fingerprint sees it (plain JSON): every section
    but :data:`NOT_MACHINE`; an imported table by the SHA-256 of its description file and of
    the files that names, not by their paths."""
    snap = {k: v for k, v in cfg.items() if k not in NOT_MACHINE and k != "table_source"}
    src = cfg.get("table_source")
    if src:
        snap["table_source"] = {"source": src.get("source"), "files": _table_files(src["file"])}
    return json.loads(json.dumps(snap, default=_plain, allow_nan=False))


def _plain(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, (np.ndarray, tuple, set)):
        return list(obj.tolist() if isinstance(obj, np.ndarray) else obj)
    if isinstance(obj, os.PathLike):
        return str(obj)
    raise TypeError(f"not JSON data: {type(obj).__name__}")


def _table_files(description) -> dict:
    """``{name: sha256}`` of an imported table's description file and the files it names."""
    import tomllib

    def sha(path):
        try:
            return hashlib.sha256(Path(path).read_bytes()).hexdigest()
        except OSError:
            return "unreadable"

    path = Path(description)
    out = {path.name: sha(path)}
    try:
        desc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return out
    for key in _TABLE_FILES:
        if isinstance(desc.get(key), str):
            out[desc[key]] = sha(path.parent / desc[key])
    return out


def machine_changes(meta: dict, cfg: dict) -> list[str]:
    """What differs between the machine the fit was made with (``meta["machine"]``, from
    :func:`read_fit_posterior`) and ``cfg`` (its configuration now), one line per key in
    ``section.key: <at the fit> at the fit, <now> now`` (empty: the same machine; a file of
    format 1 has no fingerprint: empty, its reader warned)."""
    m = meta["machine"]
    if m.get("fingerprint") is None:
        return []
    now = machine_snapshot(cfg)
    if content_fingerprint(now) == m["fingerprint"]:
        return []
    old = m.get("snapshot") or {}
    a, b = _flatten(old), _flatten(now)
    lines = [f"{k}: {_show(a.get(k))} at the fit, {_show(b.get(k))} now"
             for k in sorted(a.keys() | b.keys()) if a.get(k) != b.get(k)]
    return lines or ["the machine's configuration (its fingerprint differs)"]


def _flatten(d, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _show(v) -> str:
    return "absent" if v is None else json.dumps(v, ensure_ascii=False)


def read_fit_posterior(folder) -> tuple[FitPosterior, dict]:
    """``(FitPosterior, meta)`` from a fit's output folder (``meta``: ``points_m``,
    ``machine``, ``x0_mm``, ``warnings``: lines for the user, e.g. a file of format 1 without
    a checksum). ``ValueError`` naming the file when it is missing (a fit written before this
    file existed: fit again), malformed, of a wrong type or value in a field (named), or
    changed since it was written (checksum)."""
    path = Path(folder) / NAME
    if not path.is_file():
        hint = (" (a fit output folder written before predict existed: run diffguide fit again)"
                if (Path(folder) / "report.json").exists() else
                " (not a 'diffguide fit --out' folder)")
        raise ValueError(f"{path}: not found{hint}")
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: malformed ({type(exc).__name__}: {exc})") from None
    try:
        return _parse(d, path)
    except ValueError as exc:  # a field's (_Bad), or FitPosterior's shape checks
        raise ValueError(f"{path}: {exc}") from None


class _Bad(ValueError):
    """A field's problem (the file's name is added by the reader)."""


def _parse(d, path) -> tuple[FitPosterior, dict]:
    if not isinstance(d, dict):
        raise _Bad(f"must hold a JSON object, got {type(d).__name__}")
    fmt = d.get("format")
    warnings = []
    if fmt == FORMAT:
        _check_sum(d)
    elif fmt == FORMAT_1:
        warnings.append(f"{path}: written by an older diffguide (format 1, without a checksum "
                        "or the machine's fingerprint): neither its content nor the machine "
                        "can be checked; run diffguide fit again to get both")
    else:
        raise _Bad(f"field 'format' is {fmt!r}, expected {FORMAT!r} (or {FORMAT_1!r})")
    k = _field(d, "knots", dict)
    n = _int(k, "n", "knots.n", lo=1)
    joints = tuple(_numbers(k.get("joints_m", []), "knots.joints_m"))
    basis = RailBasis(
        float(_num(k, "start_m", "knots.start_m")),
        float(_num(k, "spacing_m", "knots.spacing_m", positive=True)), int(n),
        tuple(map(float, joints)),
        float(_num(k, "joint_width_m", "knots.joint_width_m", positive=True)
              if "joint_width_m" in k else JOINT_WIDTH))
    post = FitPosterior(
        basis=basis, coeffs=_matrix(d, "coeffs_m", 3), cov=_cov(d), structure=_structure(d),
        lead=np.asarray(_numbers(_field(d, "lead_m", list), "lead_m"), float),
        lead_basis=_lead_knots(_field(d, "lead_knots", list)),
        position_range=_range(d), rigid=_field(d, "rigid", bool),
        x_ref=_num(d, "x_ref_m", "x_ref_m"))
    meta = {"points_m": _points(d), "machine": _machine(d, fmt),
            "x0_mm": _num(d, "x0_mm", "x0_mm", optional=True), "warnings": warnings}
    return post, meta


def _check_sum(d: dict) -> None:
    want = d.get("checksum")
    if not isinstance(want, str):
        raise _Bad("field 'checksum' is missing or not a string: the file cannot be checked "
                   "(run diffguide fit again)")
    got = content_fingerprint({k: v for k, v in d.items() if k != "checksum"})
    if got != want:
        raise _Bad("its content does not match its checksum: the file was changed after the "
                   "fit wrote it (run diffguide fit again; predictions from an edited "
                   "posterior are not the fit's)")


def _kind(v) -> str:
    return "null" if v is None else {bool: "a bool", str: "a string", list: "a list",
                                     dict: "an object"}.get(type(v), type(v).__name__)


def _field(d: dict, key: str, typ, name: str | None = None):
    name = name or key
    if key not in d:
        raise _Bad(f"required field '{name}' is missing")
    v = d[key]
    if typ is bool and not isinstance(v, bool):
        raise _Bad(f"field '{name}' must be a JSON bool (true or false), got {_kind(v)} {v!r}")
    if not isinstance(v, typ):
        raise _Bad(f"field '{name}' must be {_kind(typ())}, got {_kind(v)} {v!r}"[:300])
    return v


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _num(d: dict, key: str, name: str, *, positive: bool = False,
         optional: bool = False) -> float | None:
    if optional and d.get(key) is None:
        return None
    if key not in d:
        raise _Bad(f"required field '{name}' is missing")
    v = d[key]
    if not _is_num(v):
        raise _Bad(f"field '{name}' must be a finite number, got {_kind(v)} {v!r}")
    if positive and not v > 0:
        raise _Bad(f"field '{name}' must be > 0, got {v!r}")
    return float(v)


def _int(d: dict, key: str, name: str, lo: int = 0) -> int:
    v = _field(d, key, int, name)
    if isinstance(v, bool) or v < lo:
        raise _Bad(f"field '{name}' must be an integer >= {lo}, got {v!r}")
    return v


def _numbers(v, name: str) -> list[float]:
    if not isinstance(v, list) or not all(_is_num(x) for x in v):
        raise _Bad(f"field '{name}' must be a list of finite numbers, got {str(v)[:80]}")
    return [float(x) for x in v]


def _matrix(d: dict, key: str, ndim: int) -> np.ndarray:
    """A rectangular nest of finite numbers of ``ndim`` levels."""
    v = _field(d, key, list)

    def walk(x, depth):
        if depth == ndim:
            if not _is_num(x):
                raise _Bad(f"field '{key}' must hold finite numbers only, got {_kind(x)} {x!r}")
            return
        if not isinstance(x, list):
            raise _Bad(f"field '{key}' must be nested lists {ndim} deep, got {_kind(x)}")
        for y in x:
            walk(y, depth + 1)

    walk(v, 0)
    try:
        a = np.asarray(v, float)
    except ValueError:
        raise _Bad(f"field '{key}' must be rectangular (rows of equal length)") from None
    if a.ndim != ndim:
        raise _Bad(f"field '{key}' must be rectangular with {ndim} axes, got shape {a.shape}")
    return a


def _cov(d: dict) -> np.ndarray:
    c = _matrix(d, "cov", 2)
    if c.shape[0] != c.shape[1]:
        raise _Bad(f"field 'cov' must be square, got shape {c.shape}")
    scale = float(np.max(np.abs(c))) if c.size else 0.0
    diag = np.diag(c)
    if np.any(diag < 0):
        i = int(np.argmin(diag))
        raise _Bad(f"field 'cov': the variance cov[{i}][{i}] = {diag[i]:.6g} is negative "
                   "(a covariance's diagonal is >= 0)")
    if np.max(np.abs(c - c.T), initial=0.0) > 1e-9 * scale:
        raise _Bad("field 'cov' must be symmetric (a covariance)")
    return c


def _structure(d: dict) -> dict:
    out = {}
    for name, v in _field(d, "structure", dict).items():
        if not isinstance(v, dict):
            raise _Bad(f"field 'structure.{name}' must be an object, got {_kind(v)}")
        # log-parametrised unknowns (a thickness, a preload fraction, a stiffness scale): > 0
        out[name] = {a: _num(v, a, f"structure.{name}.{a}", positive=True)
                     for a in ("value", "prior_value", "prior_sigma_log")}
    return out


def _range(d: dict) -> tuple[float, float]:
    r = _numbers(_field(d, "position_range_m", list), "position_range_m")
    if len(r) != 2 or not r[0] <= r[1]:
        raise _Bad(f"field 'position_range_m' must be [min, max] (m), got {r}")
    return r[0], r[1]


def _points(d: dict) -> dict:
    out = {}
    for name, xy in _field(d, "points_m", dict).items():
        v = _numbers(xy, f"points_m.{name}")
        if len(v) != 2:
            raise _Bad(f"field 'points_m.{name}' must be [x, y] (m), got {xy!r}")
        out[name] = (v[0], v[1])
    return out


def _machine(d: dict, fmt: str) -> dict:
    m = _field(d, "machine", dict)
    for key in ("preset", "config"):
        if m.get(key) is not None and not isinstance(m[key], str):
            raise _Bad(f"field 'machine.{key}' must be a string or null, got {_kind(m[key])}")
    if (m.get("preset") is None) == (m.get("config") is None):
        raise _Bad("field 'machine' must name exactly one of 'preset' and 'config'")
    for key in ("nx", "ny"):  # before a machine of that mesh is built
        if m.get(key) is not None:
            v = _int(m, key, f"machine.{key}", lo=1)
            try:
                check_range(v, 1, MAX_MESH_DIVISIONS, f"machine.{key} (the fit's table mesh)")
            except ValueError as exc:
                raise _Bad(str(exc)) from None
    if fmt == FORMAT:
        _field(m, "fingerprint", str, "machine.fingerprint")
        _field(m, "snapshot", dict, "machine.snapshot")
    return dict(m)


def _lead_knots(v) -> tuple:
    """``[start_m, spacing_m, n]`` → ``(float, float, int)``; ``[]`` → ``()``."""
    if not v:
        return ()
    if len(v) != 3 or not (_is_num(v[0]) and _is_num(v[1]) and v[1] > 0
                           and type(v[2]) is int and v[2] >= 1):
        raise _Bad(f"field 'lead_knots' must be [] or [start_m, spacing_m > 0, n >= 1], "
                   f"got {v!r}")
    return float(v[0]), float(v[1]), int(v[2])
