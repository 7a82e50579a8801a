r"""Measurement planning: which instruments to place where on the table so that the data
determine the rails (and the table's structure) — before anything is measured.

**The linearised experiment.** Every candidate *placement* is an instrument (a level reading
pitch and/or roll, an angular interferometer reading pitch and/or yaw, straightness optics
reading EYX/EZX) at a candidate *site* ``(x, y)`` on the table top, read at the table positions
``x_1 … x_n`` with ``runs`` runs per direction. One forward-mode Jacobian of the model (the
same :func:`~diffguide.inverse.model._model` the fit evaluates, every equilibrium differentiated
implicitly) at straight rails and the prior structure gives each candidate channel ``c`` (site,
quantity) its rows

.. math::  J_c = \frac{1}{σ_c}\,(I - \tfrac{1}{n}\mathbf 1\mathbf 1^T)\,
           \frac{∂E_c(x_1 … x_n)}{∂(θ, q)},\qquad σ_c = \frac{σ_{reading}}{\sqrt{runs ·
           directions}},

with the channel's free zero projected out (the fit profiles each channel's zero out; for a
straightness channel its alignment slope too, ``1`` then spanning ``1`` and ``x − x̄``) and ``σ_c``
the merged σ :func:`~diffguide.inverse.merge.merge_readings` gives ``runs·directions`` readings of
σ ``σ_reading`` each. ``θ`` are the gauge-fixed rail coefficients (µm, ``c = Zθ``, as in
:func:`~diffguide.inverse.fit_rails`: the common slope of both planes is fixed, as straightness
channels carry a free alignment slope) and ``q`` the structural unknowns scaled by their prior σ.

**The prior.** ``θ ~ N(0, (λΩ)⁻¹)``, ``Ω = Zᵀ(Ω_curv + Ω_amp)Z``
(:mod:`~diffguide.inverse.basis`, ``κ = 1``), and ``q ~ N(0, I)``. λ is set from a physically
stated expected RMS ``ρ`` (µm) of the four gauge-fixed profiles over the visited length ``L``:

.. math::  ρ^2 = \frac{1}{4L}\,E\Bigl[\sum_k ∫ (Πe)_k^2\,ds\Bigr]
              = \frac{L^3}{4λ}\,\mathrm{tr}(A\,Ω^{-1}),\qquad A = (G_0 Π Z)^T(G_0 Π Z)
   \quad⇒\quad λ = \frac{L^3\,\mathrm{tr}(AΩ^{-1})}{4ρ^2},

(``‖G₀c‖² = Σ∫e²ds / L⁴``, :meth:`~diffguide.inverse.RailBasis.amplitude_factor`), so that
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
:meth:`~diffguide.inverse.RailBasis.gauge_fix` does with both slopes fixed; for plans without
straightness data it is the fit's own gauge), so the σ of different plans compare.

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
from collections.abc import Callable, Sequence

from .design import CRITERIA, Evaluation
from .greedy import Step
from .instruments import Instrument, Placement
from .planner import Planner, build_planner


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
        machine: :class:`~diffguide.machine.Machine` or :class:`~diffguide.inverse.MachineFamily`
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
            which the experiment is linearised (:func:`~.planner.build_planner`). progress:
            called with a line per stage.
    """
    import time

    t0 = time.perf_counter()
    if instruments is None:
        instruments = (Instrument("level", 4), Instrument("interferometer", 1))
    planner = build_planner(
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

