r"""The linearised experiment over every candidate placement (:mod:`.plan` explains the model):
:func:`build_planner` computes it in steps — inputs checked, the prior (gauge, ``Ω``, ``λ``),
one Jacobian of the model at straight rails, the structure's mixed derivatives, the prior rail
draws, each placement's thin information factor, the evaluation rows — and returns a
:class:`Planner` holding the results."""

import dataclasses
import logging
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.precision import require_x64
from ..inverse.basis import PROFILES, RailBasis, null_space_basis
from ..inverse.data import QUANTITIES, Measurements
from ..inverse.model import _model
from ..inverse.problem import _as_family, _problem, visited_range
from .design import N_S, Evaluation, check_placements, evaluate, information
from .greedy import Step, greedy
from .instruments import Instrument, Placement

_log = logging.getLogger("diffguide")
_UM = 1e-6
#: Step in the scaled structural unknowns (prior σ) of the mixed derivatives' central differences.
STRUCTURE_STEP = 0.1


@dataclasses.dataclass(frozen=True, eq=False)
class Planner:
    """The linearised experiment over all candidate placements, as :func:`build_planner`
    computed it.

    Attributes:
        family: the :class:`~diffguide.inverse.MachineFamily`. sites: ``{name: (x, y)}`` (m), every
            point of the machine. candidates: the sites the greedy may use.
        instruments: the :class:`~.instruments.Instrument` types. positions: the distinct table
            positions read (m). readings: readings per position (runs × directions).
        work_point: ``(site, quantities)`` or None.
        basis: the rails' :class:`~diffguide.inverse.RailBasis`. fix_slope, gauge: its gauge (as
            :func:`~diffguide.inverse.fit_rails` with straightness data). Z: gauge-fixed
            coefficients ``c = Zθ``. Omega: the prior's ``Ω``. Pi: the common gauge ``Π`` of the
            reported profiles. lam: the prior's weight λ. rail_rms: the expected rail RMS it came
            from (m).
        P: prior precision of ``(θ, q)``. raw: ``{(site, quantity): ∂E/∂(θ, q)}`` per position
            at straight rails. mixed: ``{(site, quantity, k): D_k}``, ``∂²E/∂q_k∂θ``.
        draws: the prior rail draws ``θ_d``, ``(n_draws, n_theta)``.
        blocks: ``{placement: R}``, each placement's thin factors ``(n_draws, r, n_x)``.
        s: profile samples (m). W: gauge-fixed profiles' rows (µm per unknown).
        W_work: the work point's rows, or None.
    """

    family: object
    sites: dict
    candidates: tuple[str, ...]
    instruments: tuple[Instrument, ...]
    positions: np.ndarray
    readings: int
    work_point: tuple[str, tuple[str, ...]] | None
    basis: RailBasis
    fix_slope: tuple[bool, bool]
    gauge: object
    Z: np.ndarray
    Omega: np.ndarray
    Pi: np.ndarray
    lam: float
    rail_rms: float
    P: np.ndarray
    raw: dict
    mixed: dict
    draws: np.ndarray
    blocks: dict
    s: np.ndarray
    W: np.ndarray
    W_work: np.ndarray | None

    @property
    def n_theta(self) -> int:
        """Gauge-fixed rail unknowns."""
        return self.Z.shape[1]

    @property
    def n_q(self) -> int:
        """Structural unknowns."""
        return self.family.n_params

    @property
    def n_x(self) -> int:
        """All unknowns."""
        return self.n_theta + self.n_q

    @property
    def instrument(self) -> dict:
        """``{kind: Instrument}``."""
        return {i.kind: i for i in self.instruments}

    def check(self, placements: Sequence[Placement]) -> tuple[Placement, ...]:
        """:func:`~.design.check_placements`."""
        return check_placements(self, placements)

    def information(self, placements: Sequence[Placement]) -> np.ndarray:
        """:func:`~.design.information`."""
        return information(self, placements)

    def evaluate(self, placements: Sequence[Placement] = ()) -> Evaluation:
        """:func:`~.design.evaluate`: the predicted posterior of a plan."""
        return evaluate(self, placements)

    def greedy(
        self,
        budget: dict[str, int] | None = None,
        criterion: str = "worst",
        start: Sequence[Placement] = (),
        progress: Callable[[str], None] | None = None,
    ) -> tuple[tuple[Step, ...], Evaluation]:
        """:func:`~.greedy.greedy`: add placements one at a time."""
        return greedy(self, budget, criterion, start, progress)


def expected_rms_lambda(basis: RailBasis, Z, Omega, Pi, rail_rms_um: float) -> float:
    r"""λ whose prior ``θ ~ N(0, (λΩ)⁻¹)`` gives the four gauge-fixed profiles (``ΠZθ``) an
    expected RMS of ``rail_rms_um`` (µm) over the basis length: ``λ = L³ tr(AΩ⁻¹)/(4ρ²)``
    (:mod:`.plan`)."""
    if not (np.isfinite(rail_rms_um) and rail_rms_um > 0):
        raise ValueError(f"the expected rail RMS must be > 0 µm, got {rail_rms_um!r}")
    L = basis.end - basis.start
    G0 = basis.amplitude_factor() @ Pi @ Z
    A = G0.T @ G0
    return float(L**3 * np.trace(np.linalg.solve(Omega, A)) / (4.0 * rail_rms_um**2))


def gauge_projector(basis: RailBasis) -> np.ndarray:
    """``Π`` (size × size): removes each profile's mean and each plane's common least-squares
    slope from stacked coefficients — the oblique projection onto the constraints' null space
    along the gauge modes (constants, and a common linear function per plane)."""
    C, _ = basis.gauge_functionals((True, True))
    n = basis.per_profile
    s = basis.grid(4 * n)
    B = basis.matrix(s)
    one = np.linalg.lstsq(B, np.ones_like(s), rcond=None)[0]
    lin = np.linalg.lstsq(B, s - s.mean(), rcond=None)[0]
    G = np.zeros((4 * n, 6))
    for k in range(4):
        G[k * n : (k + 1) * n, k] = one
    for k, (_, plane) in enumerate(PROFILES):
        G[k * n : (k + 1) * n, 4 + (plane == "horizontal")] = lin
    return np.eye(4 * n) - G @ np.linalg.solve(C @ G, C)


@eqx.filter_jit
def _jacobian(v, prob):
    """Model values' Jacobian w.r.t. ``v = (c, q)`` at ``v`` (SI per µm / per scaled unit)."""
    return jax.jacfwd(lambda t: _model(t, prob)[0])(v), _model(v, prob)[1]


def _checked_inputs(base, instruments, positions, runs, bidirectional, candidates, work_point):
    """Sites, candidates, instruments, distinct positions, readings per position, work point —
    each checked, in this order."""
    names = tuple(base.point_names)
    xy = np.asarray(base.points_xy, float)
    sites = {n: (float(p[0]), float(p[1])) for n, p in zip(names, xy)}
    candidates = tuple(names if candidates is None else candidates)
    for n in candidates:
        if n not in sites:
            raise ValueError(
                f"candidate site {n!r} is not a point of the machine ({', '.join(names)})"
            )
    instruments = tuple(instruments)
    kinds = [i.kind for i in instruments]
    if not kinds or len(set(kinds)) != len(kinds):
        raise ValueError(f"give each instrument kind once, got {kinds}")
    positions = np.unique(np.round(np.asarray(positions, float), 9))
    if positions.size < 4:
        raise ValueError("at least 4 distinct table positions are needed")
    if int(runs) != runs or runs < 1:
        raise ValueError(f"runs must be an integer >= 1, got {runs!r}")
    readings = int(runs) * (2 if bidirectional else 1)
    work = None
    if work_point is not None:
        wname, wq = work_point[0], tuple(work_point[1])
        if wname not in sites:
            raise ValueError(f"work point {wname!r} is not a point of the machine")
        bad = [q for q in wq if q not in QUANTITIES]
        if not wq or bad:
            raise ValueError(f"work point quantities must be among {QUANTITIES}, got {wq}")
        work = (wname, wq)
    return sites, candidates, instruments, positions, readings, work


def rail_prior(basis: RailBasis, rail_rms: float, n_q: int) -> dict:
    """The gauge (both slopes fixed, as :func:`~diffguide.inverse.fit_rails` with straightness
    data), ``Z``, ``Ω = Zᵀ(Ω_curv + Ω_amp)Z``, the reporting gauge ``Π``, λ from the expected RMS
    and the prior precision ``P = diag(λΩ, I)``."""
    fix_slope = (True, True)  # as in fit_rails: straightness has a free slope
    C, gauge = basis.gauge_functionals(fix_slope)
    Z = null_space_basis(C, basis.size)
    G2, G0 = basis.penalty_factor() @ Z, basis.amplitude_factor() @ Z
    Omega = G2.T @ G2 + G0.T @ G0
    Pi = gauge_projector(basis)
    lam = expected_rms_lambda(basis, Z, Omega, Pi, rail_rms / _UM)
    n_th = Z.shape[1]
    P = np.zeros((n_th + n_q, n_th + n_q))
    P[:n_th, :n_th] = lam * Omega
    P[n_th:, n_th:] = np.eye(n_q)
    return dict(fix_slope=fix_slope, gauge=gauge, Z=Z, Omega=Omega, Pi=Pi, lam=lam, P=P)


def _problem_at_every_site(family, basis, positions, rows_q, x_ref):
    """The fit's problem with one (zero) value at every (position, point, quantity row)."""
    base = family.base
    names = tuple(base.point_names)
    xy = np.asarray(base.points_xy, float)
    pts = list(range(len(names)))  # every point: candidates, a user's plan, work point
    grid = np.array([(i, p, q) for i in range(len(positions)) for p in pts for q in rows_q])
    meas = Measurements(
        names,
        xy,
        positions[grid[:, 0]],
        grid[:, 1],
        grid[:, 2],
        np.zeros(len(grid)),
        np.ones(len(grid)),
        np.ones(len(grid), int),
        np.full(len(grid), np.nan),
        ("level",) * len(grid),
        ("column",) * len(grid),
    )
    return _problem(family, meas, basis, np.zeros((meas.n, 0)), x_ref)


def _sensitivities(prob, names, positions, rows_q, basis, Z, n_q, say) -> dict:
    """``{(site, quantity): ∂E/∂(θ, q)}`` (per position) at straight rails and the prior
    structure: one compiled forward-mode Jacobian."""
    n_th = Z.shape[1]
    line = (
        f"plan: sensitivities of {len(names)} points x {len(rows_q)} quantities at "
        f"{len(positions)} positions to {basis.size} rail + {n_q} structural unknowns "
        "(one compiled forward-mode Jacobian)"
    )
    _log.info(line)
    say(line)
    Jv, ok = _jacobian(jnp.zeros(basis.size + n_q), prob)
    Jv = np.asarray(Jv)
    if not bool(ok) or not np.all(np.isfinite(Jv)):
        raise ValueError(
            "the machine equilibrium did not converge for straight rails at "
            "the prior structure; check the machine configuration"
        )
    M = np.zeros((basis.size + n_q, n_th + n_q))
    M[: basis.size, :n_th] = Z
    M[basis.size :, n_th:] = np.eye(n_q)
    Jx = (Jv @ M).reshape(len(positions), len(names), len(rows_q), n_th + n_q)
    return {
        (names[p], QUANTITIES[q]): Jx[:, p, b]
        for p in range(len(names))
        for b, q in enumerate(rows_q)
    }


def _mixed_derivatives(prob, family, names, positions, rows_q, basis, Z, say) -> dict:
    """``{(site, quantity, k): D_k}``, ``D = ∂²E/∂q∂θ``: ``∂E/∂q`` vanishes at straight rails
    (straight rails give no errors at any structure); at rails θ it is ``Dθ`` (central
    differences of the rail Jacobian in ``q``, step :data:`STRUCTURE_STEP`)."""
    n_q, n_th = family.n_params, Z.shape[1]
    mixed = {}
    for k in range(n_q):
        dv = np.zeros(basis.size + n_q)
        dv[basis.size + k] = STRUCTURE_STEP
        line = f"plan: mixed derivatives in {family.names[k]} ({k + 1}/{n_q})"
        _log.info(line)
        say(line)
        Jp, okp = _jacobian(jnp.asarray(dv), prob)
        Jm, okm = _jacobian(jnp.asarray(-dv), prob)
        if not (bool(okp) and bool(okm)):
            raise ValueError(
                "the machine equilibrium did not converge near the prior "
                "structure; check the machine configuration"
            )
        D = (np.asarray(Jp) - np.asarray(Jm))[:, : basis.size] @ Z / (2 * STRUCTURE_STEP)
        D = D.reshape(len(positions), len(names), len(rows_q), n_th)
        for p in range(len(names)):
            for b, q in enumerate(rows_q):
                mixed[(names[p], QUANTITIES[q], k)] = D[:, p, b]
    return mixed


def _prior_draws(lam, Omega, n_q, n_draws, seed) -> np.ndarray:
    """Rails ``θ_d`` drawn from the prior, at which the experiment is linearised; one zero
    draw when the structure is known (or ``n_draws`` is 0)."""
    n_th = Omega.shape[0]
    Lth = np.linalg.cholesky(np.linalg.inv(lam * Omega))  # Σθ = L Lᵀ
    rng = np.random.default_rng(seed)
    draws = (Lth @ rng.standard_normal((n_th, max(int(n_draws), 1)))).T
    if n_q == 0 or n_draws == 0:
        draws = np.zeros((1, n_th))
    return draws


def _placement_factor(inst, site, sig, positions, raw, mixed, draws, n_q) -> np.ndarray:
    """Thin factors ``R_d`` (``RᵀR = J_dᵀJ_d``) of one placement at every draw, stacked
    ``(n_draws, r, n_x)`` (zero rows pad the ranks to one ``r``): the rows whitened by the
    merged σ ``sig``, each channel's zero (and a straightness channel's slope) projected out."""
    x = positions - positions.mean()
    slope = x / np.linalg.norm(x)

    def centred(a, q):
        a = a - a.mean(axis=0)
        if q in ("EYX", "EZX"):
            a = a - np.outer(slope, slope @ a)
        return a / sig

    Jt = np.vstack([centred(raw[(site, q)], q) for q in inst.quantities])
    D = [np.vstack([centred(mixed[(site, q, k)], q) for q in inst.quantities]) for k in range(n_q)]
    n_th = draws.shape[1]
    out = []
    for th in draws:
        J = np.hstack([Jt[:, :n_th]] + [(Dk @ th)[:, None] for Dk in D])
        w, V = np.linalg.eigh(J.T @ J)
        keep = w > 1e-10 * max(w.max(), 1e-300)
        out.append((V[:, keep] * np.sqrt(w[keep])).T)
    r = max(R.shape[0] for R in out)
    return np.stack([np.vstack([R, np.zeros((r - R.shape[0], n_th + n_q))]) for R in out])


def _evaluation_rows(basis, Pi, Z, n_q, raw, work_point):
    """Profile samples ``s`` (m), the gauge-fixed profiles' rows ``W`` at :data:`N_S` samples
    each (µm per unknown), and the work point's rows (or None)."""
    n_th = Z.shape[1]
    s = basis.grid(N_S)
    B = basis.matrix(s)
    W = np.zeros((4 * N_S, n_th + n_q))
    W[:, :n_th] = np.kron(np.eye(4), B) @ Pi @ Z
    W_work = None
    if work_point:
        W_work = np.vstack([raw[(work_point[0], q)] for q in work_point[1]])
    return s, W, W_work


def build_planner(
    machine,
    instruments: Sequence[Instrument],
    positions,
    *,
    runs: int = 5,
    bidirectional: bool = True,
    rail_rms: float = 1e-6,
    candidates: Sequence[str] | None = None,
    work_point: tuple[str, Sequence[str]] | None = None,
    knot_spacing: float | None = None,
    x_ref: float = 0.0,
    n_draws: int = 8,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> Planner:
    """The linearised experiment over all candidate placements (:mod:`.plan`).

    Arguments:
        machine: a :class:`~diffguide.machine.Machine` or a
            :class:`~diffguide.inverse.MachineFamily` (structure unknown) whose points include
            every site named below.
        instruments: the instrument types (:class:`~.instruments.Instrument`).
        positions: table positions read (m). runs: runs per direction. bidirectional: forward
            and backward runs (else forward only).
        rail_rms: expected RMS of the gauge-fixed rail profiles (m), sets λ.
        candidates: the candidate sites' names (default every point of the machine).
        work_point: ``(site name, quantities)`` for the ``"work"`` criterion (optional).
        knot_spacing: as :func:`~diffguide.inverse.fit_rails` (m; default the carriage's loaded
            length).
        x_ref: reference position (m).
        n_draws: rails drawn from the prior at which the experiment is linearised (the
            structure's information and its coupling to the rails; :mod:`.plan`).
        seed: their random seed. progress: called with a line of text per stage.
    """
    require_x64("plan")
    family = _as_family(machine)
    base = family.base
    sites, candidates, instruments, positions, readings, work = _checked_inputs(
        base, instruments, positions, runs, bidirectional, candidates, work_point
    )
    say = progress if progress is not None else (lambda t: None)
    if knot_spacing is None:
        knot_spacing = base.carriage.length
    lo, hi = visited_range(base, positions)
    basis = RailBasis.covering(lo, hi, knot_spacing)
    n_q = family.n_params
    prior = rail_prior(basis, rail_rms, n_q)
    Z = prior["Z"]
    used = {q for i in instruments for q in i.quantities}
    rows_q = sorted(
        {QUANTITIES.index(q) for q in used}
        | ({QUANTITIES.index(q) for q in work[1]} if work else set())
    )
    names = tuple(base.point_names)
    prob = _problem_at_every_site(family, basis, positions, rows_q, x_ref)
    raw = _sensitivities(prob, names, positions, rows_q, basis, Z, n_q, say)
    mixed = _mixed_derivatives(prob, family, names, positions, rows_q, basis, Z, say)
    draws = _prior_draws(prior["lam"], prior["Omega"], n_q, n_draws, seed)
    blocks: dict[Placement, np.ndarray] = {}
    for inst in instruments:
        sig = inst.sigma / np.sqrt(readings)
        for site in names:
            blocks[(inst.kind, site)] = _placement_factor(
                inst, site, sig, positions, raw, mixed, draws, n_q
            )
    s, W, W_work = _evaluation_rows(basis, prior["Pi"], Z, n_q, raw, work)
    return Planner(
        family=family,
        sites=sites,
        candidates=candidates,
        instruments=instruments,
        positions=positions,
        readings=readings,
        work_point=work,
        basis=basis,
        rail_rms=float(rail_rms),
        raw=raw,
        mixed=mixed,
        draws=draws,
        blocks=blocks,
        s=s,
        W=W,
        W_work=W_work,
        **prior,
    )
