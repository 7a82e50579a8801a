"""The Monte Carlo job: joint-error distributions for random rail pairs, every output of
``diffguide montecarlo`` (:func:`montecarlo_job`).

:class:`MontecarloSettings` holds every option (µm and mm, as the options);
:func:`montecarlo_job` draws the rails, solves the sweep for each in batched, compiled chunks
(:func:`diffguide.studies.montecarlo.batched_sweep`) and returns a :class:`MontecarloResult`
holding the study, the CSV's text, the figure and the summary; :meth:`MontecarloResult.write`
writes the files, each atomically. Spreading the sweep over CPU devices is the caller's
(the command line sets it before JAX starts). Nothing heavy is imported until the job runs.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path

from .outputs import Figure, renamed, write_files
from .positions import settle_mesh
from .study import check_study

#: Exit status when no sample converged.
EXIT_NOT_CONVERGED = 3


@dataclasses.dataclass(frozen=True)
class MontecarloSettings:
    """Every option of ``diffguide montecarlo``, with the command line's defaults:
    ``samples`` random rail pairs of RMS ``rail_rms_um`` (µm) per rail and plane, correlation
    length ``corr_mm`` (mm), ``kernel`` (se, matern52), ``planes`` (both, vertical,
    horizontal), rail 2's ``mounting`` class; the sweep's ``positions`` (``START:STOP:COUNT``,
    mm; default the whole stroke at 71), mesh (``nx``/``ny``, ``mesh`` its text), rigid
    table; ``chunk`` samples per compiled call, ``seed``; ``cpu_devices`` is the command
    line's (read before JAX starts). Checked at construction (``ValueError`` naming the
    option)."""

    preset: str = "majda2012"
    config: str | None = None
    samples: int = 1000
    rail_rms_um: float = 5.0
    corr_mm: float = 200.0
    kernel: str = "se"
    planes: str = "both"
    mounting: str = "none"
    positions: str | None = None
    rigid_table: bool = False
    mesh: str | None = None
    nx: int | None = None
    ny: int | None = None
    chunk: int | None = None
    seed: int = 0
    cpu_devices: int | None = None
    out: str | None = None
    plot: str | None = None

    def __post_init__(self):
        from .._core.limits import MAX_SAMPLES, check_range

        for name in ("config", "out", "plot"):
            v = getattr(self, name)
            object.__setattr__(self, name, None if v is None else str(v))
        check_range(self.samples, 1, MAX_SAMPLES, "--samples", "about 4 kB of memory per sample")
        if not (math.isfinite(self.rail_rms_um) and 0 <= self.rail_rms_um <= 1e4):
            raise ValueError(f"--rail-rms-um must be in 0..10000 µm, got {self.rail_rms_um}")
        check_study(self)
        settle_mesh(self)
        if self.positions is not None:
            from .positions import parse_positions

            parse_positions(self.positions)

    @classmethod
    def fields(cls) -> tuple[str, ...]:
        """The settings' names (the options' destinations)."""
        return tuple(f.name for f in dataclasses.fields(cls))


@dataclasses.dataclass
class MontecarloResult:
    """What :func:`montecarlo_job` computed: the study
    (:class:`~diffguide.studies.montecarlo.MonteCarloResult`, SI), the positions (m), the
    files (``{path: text or Figure}``: the CSV first, then the figure) and the machine's
    name."""

    settings: MontecarloSettings
    result: object
    positions: object
    files: dict
    name: str

    @property
    def n_failed(self) -> int:
        """The samples that did not converge (left out of the statistics and the figure)."""
        return int((~self.result.converged).sum())

    @property
    def exit_code(self) -> int:
        """``diffguide montecarlo``'s exit status: 3 where no sample converged, else 0."""
        return EXIT_NOT_CONVERGED if self.n_failed == self.result.n_samples else 0

    def summary(self) -> str:
        """Percentiles (5, 50, 95 %) of the ranges at each point and of the corner roll
        differences (:func:`summary`)."""
        return summary(self.result)

    def write(self, out: str | Path | None = None) -> list[str]:
        """Write the CSV to ``out`` (default: the settings' ``out``) and the figure, each
        atomically; returns the paths."""
        if out is None and self.settings.out is None:
            raise ValueError("no output file: give write() a path or "
                             "MontecarloSettings(out=...)")
        return write_files(renamed(self.files, out))


def montecarlo_job(settings: MontecarloSettings, *,
                   progress: Callable[[str], None] | None = None,
                   sample_progress: Callable[[int, int], None] | None = None
                   ) -> MontecarloResult:
    """Run ``diffguide montecarlo``'s work for ``settings``: build the machine, draw the rails,
    solve the sweeps and compute the CSV and the figure. ``progress`` receives the console's
    lines, ``sample_progress(done, total)`` the samples done after each chunk. ``ValueError``
    for bad input, before any work."""
    import jax

    from ..studies.montecarlo import batched_sweep
    from ..studies.random_rails import sample_rails
    from .study import study_setup

    s, say = settings, progress or (lambda text: None)
    name, machine, positions, model, knots = study_setup(s, s.rail_rms_um * 1e-6, say,
                                                         s.samples)
    rails = sample_rails(s.seed, s.samples, model, s.mounting, knots=knots)
    say(f"{s.samples} samples x {len(positions)} positions, rails σ = {s.rail_rms_um:g} µm, "
        f"ℓ = {s.corr_mm:g} mm ({s.kernel}, {s.planes}), mounting {s.mounting}; "
        f"{len(jax.devices())} device(s) ({jax.devices()[0].platform}); the first chunk compiles")
    result = batched_sweep(machine, rails, positions, chunk_size=s.chunk,
                           progress=sample_progress)
    files: dict = {s.out: result.to_csv()}
    if s.plot:
        from ..plotting import figure_of
        from ..plotting.montecarlo import plot_monte_carlo

        table = "rigid table" if s.rigid_table else "elastic table"
        title = (f"{name}, {table}: rails σ = {s.rail_rms_um:g} µm, ℓ = {s.corr_mm:g} mm "
                 f"({s.kernel}, {s.planes}), mounting {s.mounting}, {len(positions)} positions")
        files[s.plot] = Figure(figure_of(plot_monte_carlo(result, title)), 110)
    return MontecarloResult(s, result, positions, files, name)


def summary(result) -> str:
    """Percentiles (5, 50, 95 %) of the ranges at each point and of the corner roll differences
    of a :class:`~diffguide.studies.montecarlo.MonteCarloResult` (µm, µrad)."""
    import numpy as np

    from ..machine.errors import ERRORS

    ok = result.converged
    lines = ["percentiles over converged samples (5 % / 50 % / 95 %):"]
    lines.append("  point " + "".join(f"{e.name + ' ' + e.unit:>24}" for e in ERRORS))
    for j, p in enumerate(result.point_names):
        cells = []
        for k in range(6):
            values = result.ranges[ok, j, k] * 1e6
            q = np.percentile(values, [5, 50, 95]) if ok.any() else [np.nan] * 3
            cells.append(f"{q[0]:7.3g}/{q[1]:7.3g}/{q[2]:7.3g}")
        lines.append(f"  {p:5} " + "".join(f"{c:>24}" for c in cells))
    if result.pairs and ok.any():
        q = np.percentile(result.max_roll_difference[ok] * 1e6, [5, 50, 95])
        lines.append(
            f"  largest roll difference between corners: {q[0]:.3g} / {q[1]:.3g} / {q[2]:.3g} µrad"
        )
    return "\n".join(lines)
