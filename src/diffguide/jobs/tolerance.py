"""The tolerance job: the loosest rail straightness grade for which an error measure stays
within a limit at a stated probability, every output of ``diffguide tolerance``
(:func:`tolerance_job`; :func:`diffguide.studies.tolerance.allocate_grade`).

:class:`ToleranceSettings` holds every option (µm, µrad and mm, as the options);
:func:`tolerance_job` returns a :class:`ToleranceResult` holding the allocation, the report in
words and the JSON; :meth:`ToleranceResult.write` writes the JSON atomically. Nothing heavy is
imported until the job runs.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable
from pathlib import Path

from .outputs import write_files
from .positions import settle_mesh
from .study import check_study


@dataclasses.dataclass(frozen=True)
class ToleranceSettings:
    """Every option of ``diffguide tolerance``, with the command line's defaults: the
    ``measure`` (``roll_difference`` or ``range:ERR:POINT``) and its ``limit`` (µm or µrad, as
    the measure) at ``probability``; ``samples`` random rail pairs of the search (the same at
    every trial grade) and ``check_samples`` fresh ones for the check (0: none); the random
    rails' model and the sweep as :class:`~diffguide.jobs.MontecarloSettings`. Checked at
    construction (``ValueError`` naming the option)."""

    limit: float
    preset: str = "majda2012"
    config: str | None = None
    measure: str = "roll_difference"
    probability: float = 0.95
    samples: int = 256
    check_samples: int = 256
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

    def __post_init__(self):
        for name in ("config", "out"):
            v = getattr(self, name)
            object.__setattr__(self, name, None if v is None else str(v))
        if not 16 <= self.samples <= 1_000_000:
            raise ValueError(f"--samples must be in 16..1000000, got {self.samples}")
        if not 0 <= self.check_samples <= 1_000_000:
            raise ValueError(f"--check-samples must be in 0..1000000, got {self.check_samples}")
        if not (math.isfinite(self.limit) and self.limit > 0):
            raise ValueError(f"--limit must be a number > 0 (µm or µrad), got {self.limit}")
        if not 0 < self.probability < 1:
            raise ValueError(f"--probability must be in (0, 1), got {self.probability}")
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
class ToleranceResult:
    """What :func:`tolerance_job` computed: the allocation
    (:class:`~diffguide.studies.tolerance.GradeAllocation`, SI), the measure's unit (µm or
    µrad) and ``--out``'s JSON (:meth:`as_json`)."""

    settings: ToleranceSettings
    allocation: object
    unit: str

    def report(self) -> str:
        """The result in words (µm, µrad)."""
        return report(self.allocation, self.unit)

    def as_json(self) -> dict:
        """The result for ``--out`` (µm for grades; the measure's unit for its values)."""
        return as_json(self.allocation, self.unit)

    def json_text(self) -> str:
        return json.dumps(self.as_json(), indent=2) + "\n"

    def write(self, out: str | Path | None = None) -> list[str]:
        """Write the JSON to ``out`` (default: the settings' ``out``) atomically; returns the
        path."""
        out = self.settings.out if out is None else out
        if out is None:
            raise ValueError("no output file: give write() a path or ToleranceSettings(out=...)")
        return write_files({str(out): self.json_text()})


def tolerance_job(settings: ToleranceSettings, *,
                  progress: Callable[[str], None] | None = None) -> ToleranceResult:
    """Run ``diffguide tolerance``'s work for ``settings``: build the machine and search the
    grade (:func:`~diffguide.studies.tolerance.allocate_grade`), with its check. ``progress``
    receives the console's lines. ``ValueError`` for bad input, before any work."""
    from ..studies.tolerance import allocate_grade, measure_unit
    from .study import study_setup

    s = settings
    unit = measure_unit(s.measure)  # a malformed measure fails here, before any solve
    say = progress or (lambda text: None)
    _, machine, positions, model, knots = study_setup(s, 1e-6, say,
                                                      max(s.samples, s.check_samples))
    say(f"searching the grade: {s.samples} samples x {len(positions)} positions per trial "
        f"(the first compiles)")
    res = allocate_grade(
        machine, positions, measure=s.measure, limit=s.limit * 1e-6,
        probability=s.probability, correlation_length=model.correlation_length,
        kernel=model.kernel, planes=model.planes,
        mounting=None if s.mounting == "none" else s.mounting,
        n_samples=s.samples, check_samples=s.check_samples, seed=s.seed,
        knots=knots, chunk_size=s.chunk, progress=progress,
    )
    return ToleranceResult(s, res, unit)


def report(res, unit: str) -> str:
    """The allocation ``res`` in words (µm, µrad)."""
    lo, hi = res.interval
    lines = [f"rail straightness grade for {res.measure} <= {res.limit * 1e6:g} {unit} at "
             f"probability {res.probability:g}: {res.grade * 1e6:.3g} µm RMS per rail and plane "
             f"(95 % interval {lo * 1e6:.3g} .. {hi * 1e6:.3g} µm from {res.n_samples} samples; "
             f"{len(res.evaluations)} batched sweeps, {res.seconds:.0f} s)"]
    if res.failed:
        lines.append(f"  {res.failed} samples did not converge at that grade (counted as "
                     "breaking the limit)")
    if res.check is not None:
        c = res.check
        verdict = ("consistent" if c.holds else "NOT consistent: the search's samples are "
                   "not representative, use more --samples")
        lines.append(f"check on {c.n} fresh samples at that grade: {c.fraction:.1%} within the "
                     f"limit (95 % interval {c.interval[0]:.1%} .. {c.interval[1]:.1%}) against "
                     f"the search's {c.claimed[0]:.1%} .. {c.claimed[1]:.1%}: {verdict}")
    return "\n".join(lines)


def as_json(res, unit: str) -> dict:
    """The allocation ``res`` for ``--out`` (µm for grades; the measure's unit for its
    values)."""
    out = {"measure": res.measure, "unit": unit, "limit": res.limit * 1e6,
           "probability": res.probability, "grade_um": res.grade * 1e6,
           "interval_um": [v * 1e6 for v in res.interval], "samples": res.n_samples,
           "failed": res.failed, "seconds": res.seconds,
           "evaluations": [{"grade_um": s * 1e6, "quantile_low": lo * 1e6, "quantile": q * 1e6,
                            "quantile_high": hi * 1e6} for s, lo, q, hi in res.evaluations]}
    if res.check is not None:
        c = res.check
        out["check"] = {"samples": c.n, "seed": c.seed, "fraction": c.fraction,
                        "interval": list(c.interval), "claimed": list(c.claimed),
                        "holds": c.holds}
    return out
