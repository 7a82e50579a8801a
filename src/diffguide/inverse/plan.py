r"""Measurement planning: which instruments to place where on the table so that the data
determine the rails (and the table's structure) — before anything is measured.

**The linearised experiment.** Every candidate *placement* is an instrument (a level reading
pitch and/or roll, an angular interferometer reading pitch and/or yaw, straightness optics
reading EYX/EZX) at a candidate *site* ``(x, y)`` on the table top, read at the table positions
``x_1 … x_n`` with ``runs`` runs per direction. One forward-mode Jacobian of the model (the same
:func:`~.fit._model` the fit evaluates, every equilibrium differentiated implicitly) at straight
rails and the prior structure gives each candidate channel ``c`` (site, quantity) its rows

.. math::  J_c = \frac{1}{σ_c}\,(I - \tfrac{1}{n}\mathbf 1\mathbf 1^T)\,
           \frac{∂E_c(x_1 … x_n)}{∂(θ, q)},\qquad σ_c = \frac{σ_{reading}}{\sqrt{runs ·
           directions}},

with the channel's free zero projected out (the fit profiles each channel's zero out; for a
straightness channel its alignment slope too, ``1`` then spanning ``1`` and ``x − x̄``) and ``σ_c``
the merged σ :func:`diffguide.io.measurements.merge_readings` gives ``runs·directions`` readings of
σ ``σ_reading`` each. ``θ`` are the gauge-fixed rail coefficients (µm, ``c = Zθ``, as in
:func:`~.fit.fit_rails`: the common slope of both planes is fixed, as straightness channels
carry a free alignment slope) and ``q`` the structural unknowns scaled by their prior σ.

**The prior.** ``θ ~ N(0, (λΩ)⁻¹)``, ``Ω = Zᵀ(Ω_curv + Ω_amp)Z`` (:mod:`.basis`, ``κ = 1``), and
``q ~ N(0, I)``. λ is set from a physically stated expected RMS ``ρ`` (µm) of the four
gauge-fixed profiles over the visited length ``L``:

.. math::  ρ^2 = \frac{1}{4L}\,E\Bigl[\sum_k ∫ (Πe)_k^2\,ds\Bigr]
              = \frac{L^3}{4λ}\,\mathrm{tr}(A\,Ω^{-1}),\qquad A = (G_0 Π Z)^T(G_0 Π Z)
   \quad⇒\quad λ = \frac{L^3\,\mathrm{tr}(AΩ^{-1})}{4ρ^2},

(``‖G₀c‖² = Σ∫e²ds / L⁴``, :meth:`~.basis.RailBasis.amplitude_factor`), so that
``fit_rails(..., lam=plan.lam)`` fits with exactly the planner's prior.

**The structure.** At straight rails the data say nothing about the table's thickness or the
preload (straight rails give no errors at any structure): ``∂E/∂q = Dθ`` grows with the rails,
``D = ∂²E/∂q∂θ`` (central differences of the rail Jacobian in ``q``). Its information, and its
coupling to the rails (the structure's uncertainty widens the rails' bands), depend on rails
nobody knows yet, so the experiment is linearised at ``n_draws`` rails ``θ_d`` drawn from the
prior, ``J_{c,d} = [J_c^θ, D_c θ_d]``, and every variance below is the mean over the
draws of the posterior variance at ``θ_d`` — the expected posterior variance (a pseudo-Bayesian
design), which is the expected squared error of a fit over truths from the prior.

**Posterior.** For a set ``𝒫`` of placements ``H_d = P + Σ_{b∈𝒫} J_{b,d}ᵀJ_{b,d}``,
``P = diag(λΩ, I)``, ``Cov_d = H_d⁻¹`` — the fit's ``s²(JᵀJ + P)⁻¹`` at ``s = 1``. The profiles'
σ are reported in **one gauge for every plan**, whatever it measures: each profile's mean and each
plane's common least-squares slope removed (``Π`` below, what
:meth:`~.basis.RailBasis.gauge_fix` does with both slopes fixed; for plans without straightness
data it is the fit's own gauge), so the σ of different plans compare.

**Criteria** (smaller is better):

- ``"worst"`` (default): the largest σ of the four gauge-fixed profiles over the visited rail
  length (µm);
- ``"A"``: the RMS σ over the four profiles and the rail length, ``√(tr(WH⁻¹Wᵀ)/n)`` (µm;
  A-optimal design on the sampled profiles);
- ``"D"``: ``log det H⁻¹`` of all unknowns (rails and structure; D-optimal);
- ``"work"``: the largest σ over the stroke of the predicted errors at a work point (µm, µrad).

**Greedy selection.** Starting from the prior (or a given plan), each step tries every remaining
placement (instrument types with budget left, a site not yet used by that type) and keeps the
one with the smallest criterion after it. Each placement's information ``J_bᵀJ_b = R_bᵀR_b``
(per draw) is held as a thin factor ``R_b`` (rank ``r_b``), so a trial is a rank-``r_b``
Woodbury update of ``S = H⁻¹``:

.. math::  S' = S - U K^{-1} U^T,\quad U = SR_b^T,\quad K = I + R_b S R_b^T,\qquad
           \log\det H' = \log\det H + \log\det K,

and the new profile variances are ``diag(WSWᵀ) − colsum(X²)``, ``X = L_K⁻¹(WU)ᵀ`` with
``K = L_K L_Kᵀ`` — no ``n_x × n_x`` inverse per trial.

**What it does not model**: the rails' own nonlinearity (small for µm-size rails), χ²/dof > 1
in a real fit (the fit widens its
bands by ``s``; the planner assumes the data are as good as stated), and positioning (EXX)
channels (with their lead-error unknowns) — plan those with the fit itself.
"""

import dataclasses
import logging
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.precision import require_x64
from .basis import PROFILES, RailBasis, null_space_basis
from .data import QUANTITIES, Measurements
from .fit import _as_family, _model, _problem, visited_range

_log = logging.getLogger("diffguide")
_UM = 1e-6

#: Instrument kinds and the quantities each can read.
KINDS = {
    "level": ("EBX", "EAX"),
    "interferometer": ("EBX", "ECX"),
    "straightness": ("EYX", "EZX"),
}
#: σ of one reading per kind (rad for the angular kinds, m for straightness): the defaults of
#: :mod:`diffguide.io.measurements` (4 µm/m levels, 2 µm/m interferometer, 1 µm straightness).
DEFAULT_READING_SIGMA = {"level": 4e-6, "interferometer": 2e-6, "straightness": 1e-6}
CRITERIA = ("worst", "A", "D", "work")
#: Step in the scaled structural unknowns (prior σ) of the mixed derivatives' central differences.
STRUCTURE_STEP = 0.1
#: Profile samples per profile over the visited rail length (for σ and the criteria).
N_S = 121


@dataclasses.dataclass(frozen=True)
class Instrument:
    """An instrument type available for the plan.

    Attributes:
        kind: ``"level"``, ``"interferometer"`` (angular) or ``"straightness"`` (optics).
        count: how many can be placed (the greedy budget), >= 0.
        quantities: what one placement reads (a subset of :data:`KINDS` ``[kind]``; default
            all of them, e.g. a two-axis level reads pitch EBX and roll EAX).
        sigma: σ of one reading (rad, or m for straightness); default
            :data:`DEFAULT_READING_SIGMA`.
    """

    kind: str
    count: int = 1
    quantities: tuple[str, ...] | None = None
    sigma: float | None = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"instrument kind must be one of {tuple(KINDS)}, got {self.kind!r}")
        if self.quantities is None:
            object.__setattr__(self, "quantities", KINDS[self.kind])
        q = tuple(self.quantities)
        object.__setattr__(self, "quantities", q)
        bad = [x for x in q if x not in KINDS[self.kind]]
        if not q or bad or len(set(q)) != len(q):
            raise ValueError(f"a {self.kind} reads {' and/or '.join(KINDS[self.kind])}, got {q!r}")
        if self.sigma is None:
            object.__setattr__(self, "sigma", DEFAULT_READING_SIGMA[self.kind])
        if not (np.isfinite(self.sigma) and self.sigma > 0):
            raise ValueError(f"{self.kind}: the reading sigma must be > 0, got {self.sigma!r}")
        if int(self.count) != self.count or self.count < 0:
            raise ValueError(f"{self.kind}: count must be an integer >= 0, got {self.count!r}")


Placement = tuple[str, str]  # (instrument kind, site name)


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """The predicted posterior of one plan.

    Attributes:
        placements: the plan, ``(kind, site)`` pairs.
        s: rail coordinate of the samples (m). sigma: ``(2 rails, 2 planes, len(s))`` σ of the
            gauge-fixed profiles (m), planes (vertical, horizontal).
        worst: largest profile σ (m). rms: RMS profile σ (m). logdet: ``log det Cov`` of all
            unknowns (whitened units). work: largest σ of the work point's predicted errors
            over the stroke (m or rad; NaN without a work point).
        structure_ratio: per structural unknown, posterior σ / prior σ (1: the plan says
            nothing about it).
    """

    placements: tuple[Placement, ...]
    s: np.ndarray
    sigma: np.ndarray
    worst: float
    rms: float
    logdet: float
    work: float
    structure_ratio: dict

    def criterion(self, name: str) -> float:
        """The value of criterion ``name`` (:data:`CRITERIA`; µm, µm/m or nats)."""
        return {
            "worst": self.worst / _UM,
            "A": self.rms / _UM,
            "D": self.logdet,
            "work": self.work / _UM,
        }[name]


@dataclasses.dataclass(frozen=True)
class Step:
    """One greedy step: the placement added and what it bought (criterion in user units)."""

    placement: Placement
    xy: tuple[float, float]
    quantities: tuple[str, ...]
    before: float
    after: float
    worst: float
    rms: float
    logdet: float


@dataclasses.dataclass(frozen=True)
class Plan:
    """Result of :func:`plan`.

    Attributes:
        criterion: the criterion minimised. lam: the prior's weight (pass to
            ``fit_rails(..., lam=)``). rail_rms: the expected rail RMS it came from (m).
        steps: the greedy steps in order. best: the chosen plan's :class:`Evaluation`.
        compare: the user's plan's :class:`Evaluation` (or None). prior: no data at all.
        sites: ``{name: (x, y)}`` (m), candidates first. candidates: the candidate sites' names.
        instruments: the instruments. planner: the :class:`Planner` (for further evaluations).
        seconds: time spent (s).
    """

    criterion: str
    lam: float
    rail_rms: float
    steps: tuple[Step, ...]
    best: Evaluation
    compare: Evaluation | None
    prior: Evaluation
    sites: dict
    candidates: tuple[str, ...]
    instruments: tuple[Instrument, ...]
    planner: "Planner"
    seconds: float

    @property
    def placements(self) -> tuple[Placement, ...]:
        return self.best.placements


def expected_rms_lambda(basis: RailBasis, Z, Omega, Pi, rail_rms_um: float) -> float:
    r"""λ whose prior ``θ ~ N(0, (λΩ)⁻¹)`` gives the four gauge-fixed profiles (``ΠZθ``) an
    expected RMS of ``rail_rms_um`` (µm) over the basis length: ``λ = L³ tr(AΩ⁻¹)/(4ρ²)``
    (module docstring)."""
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
    n = basis.n_coeffs
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


class Planner:
    """The linearised experiment over all candidate placements (module docstring).

    Arguments:
        machine: a :class:`~diffguide.machine.Machine` or a :class:`~.structure.MachineFamily`
            (structure unknown) whose points include every site named below.
        instruments: the instrument types (:class:`Instrument`).
        positions: table positions read (m). runs: runs per direction. bidirectional: forward
            and backward runs (else forward only).
        rail_rms: expected RMS of the gauge-fixed rail profiles (m), sets λ.
        candidates: the candidate sites' names (default every point of the machine).
        work_point: ``(site name, quantities)`` for the ``"work"`` criterion (optional).
        knot_spacing: as :func:`~.fit.fit_rails` (m; default the carriage's loaded length).
        x_ref: reference position (m).
        n_draws: rails drawn from the prior at which the experiment is linearised (the
            structure's information and its coupling to the rails; module docstring).
        seed: their random seed. progress: called with a line of text per stage.
    """

    def __init__(
        self,
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
    ):
        require_x64("plan")
        family = _as_family(machine)
        base = family.base
        self.family = family
        names = tuple(base.point_names)
        xy = np.asarray(base.points_xy, float)
        self.sites = {n: (float(p[0]), float(p[1])) for n, p in zip(names, xy)}
        self.candidates = tuple(names if candidates is None else candidates)
        for n in self.candidates:
            if n not in self.sites:
                raise ValueError(
                    f"candidate site {n!r} is not a point of the machine ({', '.join(names)})"
                )
        self.instruments = tuple(instruments)
        kinds = [i.kind for i in self.instruments]
        if not kinds or len(set(kinds)) != len(kinds):
            raise ValueError(f"give each instrument kind once, got {kinds}")
        positions = np.unique(np.round(np.asarray(positions, float), 9))
        if positions.size < 4:
            raise ValueError("at least 4 distinct table positions are needed")
        if int(runs) != runs or runs < 1:
            raise ValueError(f"runs must be an integer >= 1, got {runs!r}")
        self.positions = positions
        self.readings = int(runs) * (2 if bidirectional else 1)
        self.work_point = None
        if work_point is not None:
            wname, wq = work_point[0], tuple(work_point[1])
            if wname not in self.sites:
                raise ValueError(f"work point {wname!r} is not a point of the machine")
            bad = [q for q in wq if q not in QUANTITIES]
            if not wq or bad:
                raise ValueError(f"work point quantities must be among {QUANTITIES}, got {wq}")
            self.work_point = (wname, wq)
        say = progress if progress is not None else (lambda t: None)

        if knot_spacing is None:
            knot_spacing = base.carriage.length
        lo, hi = visited_range(base, positions)
        basis = RailBasis.covering(lo, hi, knot_spacing)
        self.basis = basis
        used = {q for i in self.instruments for q in i.quantities}
        self.fix_slope = (True, True)  # as in fit_rails: straightness has a free slope
        C, self.gauge = basis.gauge_functionals(self.fix_slope)
        Z = null_space_basis(C, basis.size)
        self.Z = Z
        G2, G0 = basis.penalty_factor() @ Z, basis.amplitude_factor() @ Z
        self.Omega = G2.T @ G2 + G0.T @ G0
        self.Pi = gauge_projector(basis)
        self.lam = expected_rms_lambda(basis, Z, self.Omega, self.Pi, rail_rms / _UM)
        self.rail_rms = float(rail_rms)
        n_th, n_q = Z.shape[1], family.n_params
        self.n_theta, self.n_q, self.n_x = n_th, n_q, n_th + n_q
        P = np.zeros((self.n_x, self.n_x))
        P[:n_th, :n_th] = self.lam * self.Omega
        P[n_th:, n_th:] = np.eye(n_q)
        self.P = P

        # one Jacobian of the model at every (position, site, quantity) needed
        rows_q = sorted(
            {QUANTITIES.index(q) for q in used}
            | ({QUANTITIES.index(q) for q in self.work_point[1]} if self.work_point else set())
        )
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
        prob = _problem(family, meas, basis, np.zeros((meas.n, 0)), x_ref)
        line = (
            f"plan: sensitivities of {len(pts)} points x {len(rows_q)} quantities at "
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
        M = np.zeros((basis.size + n_q, self.n_x))
        M[: basis.size, :n_th] = Z
        M[basis.size :, n_th:] = np.eye(n_q)
        Jx = (Jv @ M).reshape(len(positions), len(pts), len(rows_q), self.n_x)
        self._raw = {
            (names[p], QUANTITIES[q]): Jx[:, a, b]
            for a, p in enumerate(pts)
            for b, q in enumerate(rows_q)
        }
        # the structure: ∂E/∂q vanishes at straight rails (straight rails give no errors at
        # any structure); at rails θ it is D θ, D = ∂²E/∂q∂θ the mixed derivatives (central
        # differences of the rail Jacobian in q, step STRUCTURE_STEP)
        self._mixed = {}
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
            D = D.reshape(len(positions), len(pts), len(rows_q), n_th)
            for a, p in enumerate(pts):
                for b, q in enumerate(rows_q):
                    self._mixed[(names[p], QUANTITIES[q], k)] = D[:, a, b]
        # rails drawn from the prior, at which the experiment is linearised (module docstring)
        Lth = np.linalg.cholesky(np.linalg.inv(self.lam * self.Omega))  # Σθ = L Lᵀ
        rng = np.random.default_rng(seed)
        self.draws = (Lth @ rng.standard_normal((n_th, max(int(n_draws), 1)))).T
        if n_q == 0 or n_draws == 0:
            self.draws = np.zeros((1, n_th))
        # each placement's whitened, zero-projected rows, as a thin factor R (RᵀR = JᵀJ)
        self.blocks: dict[Placement, np.ndarray] = {}
        for inst in self.instruments:
            sig = inst.sigma / np.sqrt(self.readings)
            for site in names:
                self.blocks[(inst.kind, site)] = self._factor(inst, site, sig)
        # evaluation rows: gauge-fixed profiles at N_S samples each (µm per unknown)
        self.s = basis.grid(N_S)
        B = basis.matrix(self.s)
        W = np.zeros((4 * N_S, self.n_x))
        W[:, :n_th] = np.kron(np.eye(4), B) @ self.Pi @ Z
        self.W = W
        self.W_work = None
        if self.work_point:
            self.W_work = np.vstack(
                [self._raw[(self.work_point[0], q)] for q in self.work_point[1]]
            )
        self.instrument = {i.kind: i for i in self.instruments}

    def _factor(self, inst: Instrument, site: str, sig: float) -> np.ndarray:
        """Thin factors ``R_d`` (``RᵀR = J_dᵀJ_d``) of one placement at every draw, stacked
        ``(n_draws, r, n_x)`` (zero rows pad the ranks to one ``r``)."""

        x = self.positions - self.positions.mean()
        slope = x / np.linalg.norm(x)

        def centred(a, q):
            """The channel's zero (and a straightness channel's slope) projected out."""
            a = a - a.mean(axis=0)
            if q in ("EYX", "EZX"):
                a = a - np.outer(slope, slope @ a)
            return a / sig

        Jt = np.vstack([centred(self._raw[(site, q)], q) for q in inst.quantities])
        D = [
            np.vstack([centred(self._mixed[(site, q, k)], q) for q in inst.quantities])
            for k in range(self.n_q)
        ]
        out = []
        for th in self.draws:
            J = np.hstack([Jt[:, : self.n_theta]] + [(Dk @ th)[:, None] for Dk in D])
            w, V = np.linalg.eigh(J.T @ J)
            keep = w > 1e-10 * max(w.max(), 1e-300)
            out.append((V[:, keep] * np.sqrt(w[keep])).T)
        r = max(R.shape[0] for R in out)
        return np.stack([np.vstack([R, np.zeros((r - R.shape[0], self.n_x))]) for R in out])

    def check(self, placements: Sequence[Placement]) -> tuple[Placement, ...]:
        out = []
        for p in placements:
            p = (str(p[0]), str(p[1]))
            if p not in self.blocks:
                kinds = ", ".join(self.instrument)
                raise ValueError(
                    f"placement {p}: the instrument kind must be one of {kinds} "
                    "and the site a point of the machine "
                    f"({', '.join(self.sites)})"
                )
            out.append(p)
        return tuple(out)

    def information(self, placements: Sequence[Placement]) -> np.ndarray:
        """``H_d = P + Σ_b R_bdᵀR_bd`` of a plan at every draw, ``(n_draws, n_x, n_x)``."""
        H = np.repeat(self.P[None], len(self.draws), axis=0)
        for p in self.check(placements):
            R = self.blocks[p]
            H += np.einsum("dri,drj->dij", R, R)
        return H

    def evaluate(self, placements: Sequence[Placement] = ()) -> Evaluation:
        """The predicted posterior of a plan, computed directly (no updates)."""
        placements = self.check(placements)
        H = self.information(placements)
        S = np.linalg.inv(H)
        S = 0.5 * (S + np.swapaxes(S, 1, 2))
        logdet = -np.linalg.slogdet(H)[1]
        return self._evaluation(placements, S, logdet)

    def _variances(self, S):
        """Profile and work-point variances averaged over the draws (µm², user units²)."""
        var = np.maximum(np.einsum("ij,djk,ik->i", self.W, S, self.W) / len(S), 0.0)
        var_w = None
        if self.W_work is not None:
            var_w = np.einsum("ij,djk,ik->i", self.W_work, S, self.W_work) / len(S) / _UM**2
        return var, var_w

    def _evaluation(self, placements, S, logdet) -> Evaluation:
        var, var_w = self._variances(S)
        sig = np.sqrt(var) * _UM
        work = float("nan") if var_w is None else float(np.sqrt(max(var_w.max(), 0.0))) * _UM
        ratio = {
            n: float(np.sqrt(max(np.mean(S[:, self.n_theta + i, self.n_theta + i]), 0.0)))
            for i, n in enumerate(self.family.names)
        }
        return Evaluation(
            tuple(placements),
            self.s,
            sig.reshape(2, 2, N_S),
            float(sig.max()),
            float(np.sqrt(np.mean(sig**2))),
            float(np.mean(logdet)),
            work,
            ratio,
        )

    def _trial(self, S, var, var_w, R, criterion):
        """Criterion after adding the factors ``R`` (one per draw) to ``H_d = S_d⁻¹``
        (Woodbury), and the pieces of the update."""
        U = S @ np.swapaxes(R, 1, 2)  # (d, n_x, r)
        K = np.eye(R.shape[1]) + R @ U
        Lk = np.linalg.cholesky(0.5 * (K + np.swapaxes(K, 1, 2)))
        logdet_k = 2.0 * np.sum(np.log(np.diagonal(Lk, axis1=1, axis2=2)), axis=1)
        X = np.linalg.solve(Lk, np.swapaxes(U, 1, 2))  # (d, r, n_x): U K⁻¹ Uᵀ = XᵀX
        if criterion == "D":
            return -float(np.mean(logdet_k)), X, logdet_k
        if criterion == "work":
            dv = np.sum(np.einsum("ij,drj->dri", self.W_work, X) ** 2, axis=(0, 1))
            return float(np.max(var_w - dv / len(S) / _UM**2)), X, logdet_k
        dv = np.sum(np.einsum("ij,drj->dri", self.W, X) ** 2, axis=(0, 1)) / len(S)
        v = np.maximum(var - dv, 0.0)
        value = float(np.max(v)) if criterion == "worst" else float(np.mean(v))
        return value, X, logdet_k

    def greedy(
        self,
        budget: dict[str, int] | None = None,
        criterion: str = "worst",
        start: Sequence[Placement] = (),
        progress: Callable[[str], None] | None = None,
    ) -> tuple[tuple[Step, ...], Evaluation]:
        """Add placements one at a time, each the best for ``criterion`` given those before.

        Arguments:
            budget: placements per instrument kind (default each instrument's ``count``).
            criterion: one of :data:`CRITERIA`. start: placements already decided.
        Returns the steps and the final plan's :class:`Evaluation`.
        """
        if criterion not in CRITERIA:
            raise ValueError(f"criterion must be one of {CRITERIA}, got {criterion!r}")
        if criterion == "work" and self.W_work is None:
            raise ValueError("the 'work' criterion needs a work point")
        budget = dict({i.kind: i.count for i in self.instruments} if budget is None else budget)
        chosen = list(self.check(start))
        H = self.information(chosen)
        S = np.linalg.inv(H)
        S = 0.5 * (S + np.swapaxes(S, 1, 2))
        logdet = -np.linalg.slogdet(H)[1]  # log det Cov, per draw
        total = sum(budget.values())
        steps = []
        for k in range(total):
            var, var_w = self._variances(S)
            before = self._value(criterion, var, var_w, logdet)
            best = None
            for p, R in self.blocks.items():
                if (
                    budget.get(p[0], 0) <= 0
                    or p in chosen
                    or R.shape[1] == 0
                    or p[1] not in self.candidates
                ):
                    continue
                value, X, ldk = self._trial(S, var, var_w, R, criterion)
                if best is None or value < best[0] - 1e-12 * abs(best[0]):
                    best = (value, p, X, ldk)
            if best is None:
                break
            _, p, X, ldk = best
            S = S - np.swapaxes(X, 1, 2) @ X  # Woodbury: S − U K⁻¹ Uᵀ
            S = 0.5 * (S + np.swapaxes(S, 1, 2))
            logdet = logdet - ldk
            chosen.append(p)
            budget[p[0]] -= 1
            ev = self._evaluation(tuple(chosen), S, logdet)
            after = ev.criterion(criterion)
            steps.append(
                Step(
                    p,
                    self.sites[p[1]],
                    self.instrument[p[0]].quantities,
                    self._user(criterion, before),
                    after,
                    ev.worst,
                    ev.rms,
                    ev.logdet,
                )
            )
            line = (
                f"plan: step {k + 1}/{total}: {p[0]} at {p[1]} "
                f"({self.sites[p[1]][0] * 1e3:.0f}, {self.sites[p[1]][1] * 1e3:.0f}) mm: "
                f"{criterion} {self._user(criterion, before):.4g} -> {after:.4g}"
            )
            _log.info(line)
            if progress is not None:
                progress(line)
        return tuple(steps), self._evaluation(tuple(chosen), S, logdet)

    @staticmethod
    def _value(criterion, var, var_w, logdet):
        if criterion == "worst":
            return float(np.max(var))
        if criterion == "A":
            return float(np.mean(var))
        if criterion == "work":
            return float(np.max(var_w))
        return float(np.mean(logdet))

    @staticmethod
    def _user(criterion, value):
        """A :meth:`_value` in the criterion's user units (µm, µm/m; nats for D)."""
        return float(value) if criterion == "D" else float(np.sqrt(max(value, 0.0)))


def plan(
    machine,
    positions,
    *,
    instruments: Sequence[Instrument] | None = None,
    criterion: str = "worst",
    compare: Sequence[Placement] | None = None,
    start: Sequence[Placement] = (),
    rail_rms: float = 1e-6,
    runs: int = 5,
    bidirectional: bool = True,
    candidates: Sequence[str] | None = None,
    work_point: tuple[str, Sequence[str]] | None = None,
    knot_spacing: float | None = None,
    n_draws: int = 8,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> Plan:
    """Choose where to put the instruments (greedy, module docstring) and compare with a plan.

    Arguments:
        machine: :class:`~diffguide.machine.Machine` or :class:`~.structure.MachineFamily`
            (structure unknown, as ``diffguide fit`` estimates it) whose points are the
            candidate sites (and the work point, and the sites of ``compare``).
        positions: table positions read (m).
        instruments: available instrument types with their counts (default 4 two-axis levels
            and 1 angular interferometer reading pitch and yaw: the bundled data set).
        criterion: ``"worst"`` (default), ``"A"``, ``"D"`` or ``"work"`` (module docstring).
        compare: a user's plan, ``(kind, site)`` pairs, evaluated with the same prior.
        start: placements already decided (kept; the budget is spent on top of them).
        rail_rms: expected RMS of the rail profiles (m), sets the prior's λ.
        runs, bidirectional: runs per direction and whether backward runs are made (the merged
            σ per position is ``σ_reading/√(runs·directions)``).
        candidates: site names the greedy may use (default every point of the machine).
        work_point: ``(site, quantities)`` for the ``"work"`` criterion.
        knot_spacing: rail knot spacing (m), as the fit. n_draws, seed: prior rail draws at
            which the experiment is linearised (:class:`Planner`). progress: called with a
            line per stage.
    """
    import time

    t0 = time.perf_counter()
    if instruments is None:
        instruments = (Instrument("level", 4), Instrument("interferometer", 1))
    planner = Planner(
        machine,
        instruments,
        positions,
        runs=runs,
        bidirectional=bidirectional,
        rail_rms=rail_rms,
        candidates=candidates,
        work_point=work_point,
        knot_spacing=knot_spacing,
        n_draws=n_draws,
        seed=seed,
        progress=progress,
    )
    if criterion not in CRITERIA:
        raise ValueError(f"criterion must be one of {CRITERIA}, got {criterion!r}")
    steps, best = planner.greedy(None, criterion, start, progress)
    comp = planner.evaluate(compare) if compare is not None else None
    return Plan(
        criterion,
        planner.lam,
        float(rail_rms),
        steps,
        best,
        comp,
        planner.evaluate(()),
        planner.sites,
        planner.candidates,
        planner.instruments,
        planner,
        time.perf_counter() - t0,
    )


def grid_sites(length: float, width: float, nx: int, ny: int, margin: float = 0.05) -> dict:
    """``nx × ny`` candidate sites ``{"G<i>_<j>": (x, y)}`` (m) evenly over the table top
    ``length × width`` (m) centred on the origin, ``margin`` (m) from the edges."""
    if nx < 1 or ny < 1:
        raise ValueError(f"the site grid needs nx, ny >= 1, got {nx} x {ny}")
    xs = np.linspace(-length / 2 + margin, length / 2 - margin, nx) if nx > 1 else [0.0]
    ys = np.linspace(-width / 2 + margin, width / 2 - margin, ny) if ny > 1 else [0.0]
    return {
        f"G{i + 1}_{j + 1}": (float(np.round(x, 12)) + 0.0, float(np.round(y, 12)) + 0.0)
        for i, x in enumerate(xs)
        for j, y in enumerate(ys)
    }


__all__ = [
    "CRITERIA",
    "KINDS",
    "Evaluation",
    "Instrument",
    "Plan",
    "Planner",
    "Step",
    "gauge_projector",
    "grid_sites",
    "plan",
]
