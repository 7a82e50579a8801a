r"""The battery's cases: truth rails, sensor layouts, readings as a CSV text, and the fit call.

A case (:class:`Case`) is made by one small function (its docstring's first line says what it
stresses; :data:`CASES` lists them). From a case:

1. :func:`truth_rails` — the truth, a :class:`TruthRail` per rail (not a spline): per plane

   .. math::  e(s) = k\Bigl[\sum_{j=0}^{3} a_j (s/1\,\mathrm{m})^j
              + \sum_k A_k \sin(2π s/λ_k + φ_k) + \tfrac{h}{2}\tanh\frac{s - s_0}{w}\Bigr]

   (µm; the tanh is a rail-joint step of height ``h`` whose 10–90 % rise takes ``2.2 w``), the
   scale ``k`` set so that the four profiles' RMS (each less its mean, over
   :data:`RMS_RANGE`) is ``Case.rms_um`` when that is given;
2. :func:`simulate_errors` — the joint errors of the truth on the *truth machine*:
   ``majda2012_machine(nx=40, ny=20, thickness=..., preload_fraction=..., points=...)``, finer
   than the fit's 20 × 10 mesh (built once per distinct structure and layout);
3. :func:`readings_csv` — the readings of ``Case.runs`` runs (forward and, unless
   unidirectional, backward), one row each, in the long format of
   :mod:`diffguide.io.measurements`, with Gaussian noise per reading (:data:`NOISE`: levels 4 µm/m,
   interferometer 2 µm/m, straightness optics 1 µm), optionally a linear drift in time over each
   run and gross outliers; fixed seeds;
4. :func:`measurements` — that text through ``parse_readings`` + ``merge_readings``;
5. :func:`run_fit` — **the one call of the fit** (switch it to a new API here).

Sensor layouts (point, x mm, y mm, instrument, quantities): :data:`BUNDLED` (levels at the four
corners reading pitch and roll, an interferometer at the centre reading pitch and yaw, as in the
bundled data set), :data:`LEVELS_ONLY`, :data:`INTERFEROMETER_ONLY`, :data:`WITH_STRAIGHTNESS`.
"""

import dataclasses
import json
import os
import time
from collections.abc import Callable

import jax.numpy as jnp
import numpy as np

from diffguide.guideway.rails import AbstractRailProfile

#: Readings' standard deviation per (instrument, kind): µm/m (angular), µm (linear).
NOISE = {
    ("level", "angular"): 4.0,
    ("interferometer", "angular"): 2.0,
    ("interferometer", "linear"): 1.0,
}
QUANTITIES = ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX")  # order of JointErrors.errors
LINEAR = ("EXX", "EYX", "EZX")
#: Rail range (m) over which a truth is scaled to its RMS (about what the elements visit).
RMS_RANGE = (-0.53, 0.53)
#: The fine (truth) mesh; the fit uses the preset's 20 × 10.
TRUTH_MESH = (40, 20)
#: Carriage-averaging and carriage-spacing blind wavelengths of ``majda2012`` (m):
#: ``n·p`` = 48 mm; ``l`` = 320 mm (pitch/yaw, ``l/k``); ``2l`` = 640 mm and ``2l/3`` = 213 mm
#: (roll, ``2l/(2k+1)``) — :func:`diffguide.inverse.blind_wavelengths`; checked by a test.
BLIND_WAVELENGTHS = (0.048, 0.320, 0.640, 0.640 / 3)
MAX_WAVES = 16  # sinusoids per profile (padded with zero amplitude: one compiled shape)

Sensor = tuple[str, float, float, str, tuple[str, ...]]
BUNDLED: tuple[Sensor, ...] = (
    ("P1", 450.0, 200.0, "level", ("EBX", "EAX")),
    ("P2", -450.0, 200.0, "level", ("EBX", "EAX")),
    ("P3", -450.0, -200.0, "level", ("EBX", "EAX")),
    ("P4", 450.0, -200.0, "level", ("EBX", "EAX")),
    ("P5", 0.0, 0.0, "interferometer", ("EBX", "ECX")),
)
LEVELS_ONLY = BUNDLED[:4]
INTERFEROMETER_ONLY = BUNDLED[4:]
WITH_STRAIGHTNESS = BUNDLED[:4] + (
    ("P5", 0.0, 0.0, "interferometer", ("EBX", "ECX", "EYX", "EZX")),
)

#: The bundled layout plus what ``diffguide plan`` adds to it for 8 more levels and 2 more
#: angular interferometers (``diffguide plan --preset majda2012 --start bundled --levels 8
#: --interferometers 2``: 7 × 3 sites, the structure unknown, criterion "worst"; in the order
#: chosen). Its predicted worst profile σ is 0.37 µm against the bundled layout's 0.56 µm.
PLANNED: tuple[Sensor, ...] = BUNDLED + tuple(
    (f"A{k + 1}", x, y, kind, ("EBX", "EAX") if kind == "level" else ("EBX", "ECX"))
    for k, (kind, x, y) in enumerate((
        ("level", 150.0, -200.0),
        ("interferometer", 300.0, 0.0),
        ("interferometer", -300.0, 0.0),
        ("level", 300.0, -200.0),
        ("level", -150.0, 200.0),
        ("level", -300.0, 200.0),
        ("level", 150.0, 200.0),
        ("level", 300.0, 200.0),
        ("level", -300.0, -200.0),
        ("level", -150.0, -200.0),
    ))
)


def planned(case: "Case") -> "Case":
    """``case`` measured with the :data:`PLANNED` layout instead of its own (same name, truth,
    noise seed and fit)."""
    return dataclasses.replace(case, sensors=PLANNED)


# ----------------------------------------------------------------------------- truth rails


@dataclasses.dataclass(frozen=True)
class Plane:
    """One profile's truth (µm, m): polynomial ``a_j`` (µm per m^j), sinusoids ``(A µm, λ m,
    φ rad)``, a step ``(h µm, s₀ m, w m)`` (``h = 0``: none)."""

    poly: tuple[float, ...] = (0.0,)
    waves: tuple[tuple[float, float, float], ...] = ()
    step: tuple[float, float, float] = (0.0, 0.0, 1e-3)


@dataclasses.dataclass(frozen=True)
class Truth:
    """Four profiles: ``planes[(rail, plane)]``, rail 1 or 2, plane ``vertical``/``horizontal``."""

    planes: dict


def _evaluate(xp, s, poly, waves, step):
    """``e(s)`` (m) of the arrays of :class:`TruthRail` (one plane), numpy or jax.numpy."""
    x = s  # s / 1 m
    e = poly[0] + poly[1] * x + poly[2] * x**2 + poly[3] * x**3
    e = e + xp.sum(
        waves[:, 0] * xp.sin(2 * xp.pi * s[..., None] / waves[:, 1] + waves[:, 2]), axis=-1
    )
    e = e + 0.5 * step[0] * xp.tanh((s - step[1]) / step[2])
    return e * 1e-6


def _arrays(plane: Plane, scale: float):
    poly = np.zeros(4)
    poly[: len(plane.poly)] = plane.poly
    waves = np.zeros((MAX_WAVES, 3))
    waves[:, 1] = 1.0
    if plane.waves:
        waves[: len(plane.waves)] = plane.waves
    step = np.array(plane.step, float)
    return poly * scale, waves * [scale, 1.0, 1.0], step * [scale, 1.0, 1.0]


class TruthRail(AbstractRailProfile):
    """A truth rail: polynomial + sinusoids + a tanh step per plane (see the module docstring).

    Arrays (µm, m) with a leading plane axis (vertical, horizontal): ``poly`` ``(2, 4)``,
    ``waves`` ``(2, 16, 3)``, ``step`` ``(2, 3)``.
    """

    poly: jnp.ndarray
    waves: jnp.ndarray
    step: jnp.ndarray

    def __call__(self, s):
        s = jnp.asarray(s, dtype=float)
        v, h = (_evaluate(jnp, s, self.poly[k], self.waves[k], self.step[k]) for k in range(2))
        return h, v


def _scale(truth: Truth, rms_um: float | None) -> float:
    if rms_um is None:
        return 1.0
    s = np.linspace(*RMS_RANGE, 1001)
    e = np.array([_evaluate(np, s, *_arrays(p, 1.0)) for p in truth.planes.values()]) * 1e6
    e = e - e.mean(axis=1, keepdims=True)
    return rms_um / float(np.sqrt(np.mean(e**2)))


def _rail_arrays(case: "Case", rail: int):
    k = _scale(case.truth, case.rms_um)
    arrs = [_arrays(case.truth.planes[(rail, pl)], k) for pl in ("vertical", "horizontal")]
    return tuple(np.stack(a) for a in zip(*arrs))


def truth_rails(case: "Case") -> tuple[TruthRail, TruthRail]:
    """The case's truth as rail profiles (rail 1, rail 2) for the forward model."""
    return tuple(TruthRail(*(jnp.asarray(a) for a in _rail_arrays(case, r))) for r in (1, 2))


def truth_profiles(case: "Case", s) -> np.ndarray:
    """The truth at ``s`` (m): ``(2 rails, 2 planes [vertical, horizontal], len(s))`` (m)."""
    s = np.asarray(s, float)
    out = np.zeros((2, 2, len(s)))
    for r in (1, 2):
        poly, waves, step = _rail_arrays(case, r)
        for p in range(2):
            out[r - 1, p] = _evaluate(np, s, poly[p], waves[p], step[p])
    return out


# ----------------------------------------------------------------------------- cases


@dataclasses.dataclass(frozen=True)
class Case:
    """One battery case.

    Attributes:
        name: short identifier. stresses: what it stresses (one line).
        truth: the rails' truth. rms_um: scale the truth to this RMS (µm), or keep it.
        sensors: the layout. n_positions: positions over the 700 mm stroke (±350 mm).
        runs: runs per direction. bidirectional: forward and backward runs, else forward only.
        thickness, preload: the truth machine's plate thickness (m) and preload (fraction of
            C); ``None`` = the preset's (50 mm, 8 %) — set for the wrong-structure cases.
        drift: RMS of a linear drift in time over each run, in reading σ per run (0: none).
        outliers: this many readings off by ``outlier_sigma`` reading σ (random sign).
        lead_um: the feed screw's lead error (µm) as a function of the position (mm), added to
            every EXX reading (the fitted model has no lead error). z_mm: ``(point, z)`` pairs:
            that point's optics sit ``z`` mm above the table top (Abbe: EXX + z·EBX,
            EYX − z·EAX), written in the ``z_mm`` column.
        seed: noise seed.
        joints_mm: rail joints the user states to the fit (``fit_rails(joints=...)``), on the
            rail coordinate (mm); none by default.
    """

    name: str
    stresses: str
    truth: Truth
    sensors: tuple[Sensor, ...] = BUNDLED
    rms_um: float | None = None
    n_positions: int = 36
    runs: int = 5
    bidirectional: bool = True
    thickness: float | None = None
    preload: float | None = None
    drift: float = 0.0
    outliers: int = 0
    outlier_sigma: float = 10.0
    lead_um: Callable | None = None
    z_mm: tuple[tuple[str, float], ...] = ()
    seed: int = 0
    joints_mm: tuple[float, ...] = ()

    @property
    def wrong_structure(self) -> bool:
        return self.thickness is not None or self.preload is not None

    def positions_mm(self) -> np.ndarray:
        return np.linspace(-350.0, 350.0, self.n_positions)

    def points(self) -> dict[str, tuple[float, float]]:
        """Sensor locations ``{name: (x, y)}`` (m)."""
        return {name: (x * 1e-3, y * 1e-3) for name, x, y, _, _ in self.sensors}


#: The bundled data set's truth (data/make_majda2012_measurements.py): quadratic + two sines.
BUNDLED_TRUTH = Truth(
    {
        (1, "vertical"): Plane((0.0, 2.0, 6.0), ((1.2, 0.85, 0.4), (0.5, 0.55, 2.1))),
        (1, "horizontal"): Plane((0.0, 1.0, -3.0), ((1.0, 1.10, 1.3), (0.4, 0.62, 0.2))),
        (2, "vertical"): Plane((0.0, -1.5, 4.0), ((1.0, 0.95, 2.6), (0.5, 0.60, 1.0))),
        (2, "horizontal"): Plane((0.0, 0.5, -2.0), ((0.8, 0.90, 2.9), (0.4, 0.70, 1.7))),
    }
)


def _case(fn: Callable, **kw) -> Case:
    return Case(name=fn.__name__, stresses=fn.__doc__.strip().splitlines()[0], **kw)


def baseline() -> Case:
    """Bundled-like layout and truth (quadratic + 2 sines, 36 positions): the reference."""
    return _case(baseline, truth=BUNDLED_TRUTH, seed=101)


def rich_truth() -> Case:
    """14 sinusoids per profile, 90–900 mm wavelengths, 71 positions."""
    rng = np.random.default_rng(202)
    planes = {}
    for key in BUNDLED_TRUTH.planes:
        lam = np.exp(rng.uniform(np.log(0.09), np.log(0.9), 14))
        amp = rng.normal(0.0, 1.0, 14) * lam / 0.9  # amplitudes falling with wavelength
        phase = rng.uniform(0.0, 2 * np.pi, 14)
        planes[key] = Plane((0.0,), tuple(zip(amp, lam, phase)))
    return _case(rich_truth, truth=Truth(planes), rms_um=1.0, n_positions=71, seed=202)


def rail_joint_step() -> Case:
    """A rail joint: rail 1 steps 3 µm vertically and 2 µm horizontally over ~5 mm at 137 mm."""
    planes = dict(BUNDLED_TRUTH.planes)
    for pl, h in (("vertical", 3.0), ("horizontal", 2.0)):
        planes[(1, pl)] = dataclasses.replace(planes[(1, pl)], step=(h, 0.137, 2.5e-3))
    return _case(rail_joint_step, truth=Truth(planes), seed=303, joints_mm=(137.0,))


def blind_wavelengths() -> Case:
    """Content at the blind wavelengths 48, 320, 640, 213 mm (0.4 µm each) on a small quadratic."""
    planes = {}
    for i, key in enumerate(BUNDLED_TRUTH.planes):
        waves = tuple((0.4, lam, 0.7 * i + 1.1 * j) for j, lam in enumerate(BLIND_WAVELENGTHS))
        planes[key] = Plane((0.0, 0.0, (2.0, -1.5, 1.0, -2.5)[i]), waves)
    return _case(blind_wavelengths, truth=Truth(planes), seed=404)


def levels_only() -> Case:
    """Levels at the four corners (pitch, roll) and no interferometer: no yaw at all."""
    return _case(levels_only, truth=BUNDLED_TRUTH, sensors=LEVELS_ONLY, seed=505)


def interferometer_only() -> Case:
    """One angular interferometer at the centre reading pitch and yaw only (no roll)."""
    return _case(interferometer_only, truth=BUNDLED_TRUTH, sensors=INTERFEROMETER_ONLY, seed=606)


def with_straightness() -> Case:
    """Bundled layout plus straightness optics at the centre (EYX, EZX, 1 µm per reading)."""
    return _case(with_straightness, truth=BUNDLED_TRUTH, sensors=WITH_STRAIGHTNESS, seed=707)


def drift_and_outliers() -> Case:
    """A linear drift in time over each run (2 σ RMS) and 5 readings off by 10 σ.

    A drift linear in time over a forward + backward run cancels in the mean of the two
    directions (a constant, the channel's zero) but inflates the pooled repeatability; the merge
    does not reject outliers, so they enter the merged values and the scatter.
    """
    return _case(drift_and_outliers, truth=BUNDLED_TRUTH, drift=2.0, outliers=5, seed=808)


def unidirectional() -> Case:
    """Five forward runs only (no reversal)."""
    return _case(unidirectional, truth=BUNDLED_TRUTH, bidirectional=False, seed=909)


def positions_141() -> Case:
    """141 positions (every 5 mm) instead of 36."""
    return _case(positions_141, truth=BUNDLED_TRUTH, n_positions=141, seed=1010)


def rms_20um() -> Case:
    """The bundled truth scaled to 20 µm RMS, 8× the 2.5 µm preload approach: nonlinear."""
    return _case(rms_20um, truth=BUNDLED_TRUTH, rms_um=20.0, seed=1111)


def rms_0p2um() -> Case:
    """The bundled truth scaled to 0.2 µm RMS: the signal near the noise."""
    return _case(rms_0p2um, truth=BUNDLED_TRUTH, rms_um=0.2, seed=1212)


def thickness_30mm() -> Case:
    """Wrong structure: the truth table is 30 mm thick (the fit assumes 50 mm; −40 %)."""
    return _case(thickness_30mm, truth=BUNDLED_TRUTH, thickness=0.030, seed=1313)


def thickness_70mm() -> Case:
    """Wrong structure: the truth table is 70 mm thick (the fit assumes 50 mm; +40 %)."""
    return _case(thickness_70mm, truth=BUNDLED_TRUTH, thickness=0.070, seed=1414)


def preload_2pct() -> Case:
    """Wrong structure: the truth carriages have 2 % C preload (the fit assumes 8 %)."""
    return _case(preload_2pct, truth=BUNDLED_TRUTH, preload=0.02, seed=1515)


def preload_13pct() -> Case:
    """Wrong structure: the truth carriages have 13 % C preload (the fit assumes 8 %)."""
    return _case(preload_13pct, truth=BUNDLED_TRUTH, preload=0.13, seed=1616)


#: The bundled layout plus a laser reading positioning (EXX) at P6, its optics 100 mm above the
#: table, and a level beside the interferometer at the centre (two instruments reading pitch at
#: P5).
WITH_POSITIONING: tuple[Sensor, ...] = BUNDLED + (
    ("P5", 0.0, 0.0, "level", ("EBX",)),
    ("P6", 0.0, 150.0, "interferometer", ("EXX",)),
)


def positioning_lead_error() -> Case:
    """A positioning channel with the screw's lead error (12 µm over the stroke plus a 250 mm
    wave), optics 100 mm above the table, and a level and an interferometer both reading pitch
    at the centre: the lead term, the Abbe term and instrument-keyed channels."""
    def lead(x_mm):
        return 12.0 * (x_mm / 350.0) ** 2 + 2.0 * np.sin(2 * np.pi * x_mm / 250.0)

    return _case(positioning_lead_error, truth=BUNDLED_TRUTH, sensors=WITH_POSITIONING,
                 lead_um=lead, z_mm=(("P6", 100.0),), seed=1717)


#: A level (pitch, roll) and an angular interferometer (pitch, yaw) at each of the four corners:
#: 16 channels.
CORNERS_RICH: tuple[Sensor, ...] = tuple(
    s for lv in LEVELS_ONLY
    for s in (lv, (lv[0], lv[1], lv[2], "interferometer", ("EBX", "ECX")))
)


def rich_data() -> Case:
    """16 channels (a level and an interferometer at each corner) on the rich truth, 71 positions.

    The issue-28 data set: much data on rails with content from 90 to 900 mm (preload truth
    8 %), where Levenberg–Marquardt had stopped on its step limit and the preload came back
    2.7σ off.
    """
    return dataclasses.replace(rich_truth(), name="rich_data",
                               stresses=rich_data.__doc__.strip().splitlines()[0],
                               sensors=CORNERS_RICH, seed=1818)


def _plane_scaled(planes: dict, rms_um: dict[str, float]) -> dict:
    """``planes`` with each plane's two profiles scaled together so that their RMS (each less its
    mean, over :data:`RMS_RANGE`) is ``rms_um[plane]`` (µm): a truth whose vertical and
    horizontal content differ in size (``Case.rms_um`` scales all four profiles alike)."""
    s = np.linspace(*RMS_RANGE, 1001)
    out = dict(planes)
    for pl, target in rms_um.items():
        keys = [k for k in planes if k[1] == pl]
        e = np.array([_evaluate(np, s, *_arrays(planes[k], 1.0)) for k in keys]) * 1e6
        e = e - e.mean(axis=1, keepdims=True)
        k = target / float(np.sqrt(np.mean(e**2)))
        for key in keys:
            p = planes[key]
            out[key] = Plane(tuple(a * k for a in p.poly),
                             tuple((a * k, lam, ph) for a, lam, ph in p.waves),
                             (p.step[0] * k, p.step[1], p.step[2]))
    return out


def large_rails_horizontal() -> Case:
    """Rich truth (14 sines, 90–900 mm) at 15 µm RMS vertical, 12 µm horizontal: rows unload."""
    planes = _plane_scaled(rich_truth().truth.planes, {"vertical": 15.0, "horizontal": 12.0})
    return _case(large_rails_horizontal, truth=Truth(planes), seed=1818)


def _random_planes(seed: int, correlation_length: float, shortest: float, longest: float = 0.9,
                   n: int = MAX_WAVES) -> dict:
    r"""Four profiles drawn from a stationary squared-exponential Gaussian process
    (:class:`diffguide.studies.GaussianRailModel`'s kernel) as a random-phase spectral sum of
    ``n`` sines per profile, wavelengths log-uniform over ``[shortest, longest]`` (m): with
    ``k = 2π/λ`` the process' spectral density is ``∝ exp(−(kℓ)²/2)``, and a log-uniform ``λ``
    samples ``dk = k d ln λ``, so each sine's amplitude is ``N(0, 1)·√(k exp(−(kℓ)²/2))`` (µm,
    scaled afterwards). Unlike :func:`rich_truth` (amplitudes falling with ``λ``) the short
    wavelengths carry as much as the process gives them."""
    rng = np.random.default_rng(seed)
    planes = {}
    for key in BUNDLED_TRUTH.planes:
        lam = np.exp(rng.uniform(np.log(shortest), np.log(longest), n))
        k = 2 * np.pi / lam
        amp = rng.normal(0.0, 1.0, n) * np.sqrt(k * np.exp(-0.5 * (k * correlation_length) ** 2))
        phase = rng.uniform(0.0, 2 * np.pi, n)
        planes[key] = Plane((0.0,), tuple(zip(amp, lam, phase)))
    return planes


def large_random_rails() -> Case:
    """Random rails (30 mm correlation length, content 90–900 mm) at 15 µm V / 12 µm H RMS."""
    planes = _plane_scaled(_random_planes(3939, 0.030, 0.090),
                           {"vertical": 15.0, "horizontal": 12.0})
    return _case(large_random_rails, truth=Truth(planes), seed=3939)


#: Wavelengths (m) that the :data:`PLANNED` layout leaves undetermined on the ``majda2012``
#: preset (its identifiability report lists 285–363 mm, around the carriage spacing).
UNDETERMINED_WAVELENGTHS = (0.285, 0.320, 0.363)


def planned_undetermined() -> Case:
    """Planned layout, 72 mm table, 4 % preload, 0.5 µm at 285/320/363 mm on the bundled truth."""
    planes = {}
    for i, (key, plane) in enumerate(BUNDLED_TRUTH.planes.items()):
        waves = tuple((0.5, lam, 0.9 * i + 1.3 * j)
                      for j, lam in enumerate(UNDETERMINED_WAVELENGTHS))
        planes[key] = dataclasses.replace(plane, waves=plane.waves + waves)
    return _case(planned_undetermined, truth=Truth(planes), sensors=PLANNED, thickness=0.072,
                 preload=0.04, seed=1919)


#: Every case, by name, in table order.
CASES: dict[str, Callable[[], Case]] = {
    f.__name__: f
    for f in (
        baseline,
        rich_truth,
        rail_joint_step,
        blind_wavelengths,
        levels_only,
        interferometer_only,
        with_straightness,
        drift_and_outliers,
        unidirectional,
        positions_141,
        rms_20um,
        rms_0p2um,
        positioning_lead_error,
        thickness_30mm,
        thickness_70mm,
        preload_2pct,
        preload_13pct,
        rich_data,
        large_rails_horizontal,
        large_random_rails,
        planned_undetermined,
    )
}


def command_line(ap, argv=None):
    """The bench scripts' command line: ``ap`` (an ``argparse.ArgumentParser`` with the script's
    own options) with a positional ``cases`` added, parsed; returns ``(args, names)``, the named
    cases in order (all of :data:`CASES` when none). An unknown case exits with the parser's
    usage error naming it and the cases there are."""
    ap.add_argument("cases", nargs="*", help=f"default all: {', '.join(CASES)}")
    args = ap.parse_args(argv)
    unknown = [n for n in args.cases if n not in CASES]
    if unknown:
        ap.error(f"unknown case(s) {', '.join(unknown)} (the cases: {', '.join(CASES)})")
    return args, list(args.cases) or list(CASES)


# ----------------------------------------------------------------------------- simulation

_MACHINES: dict = {}  # module-level cache: each distinct machine is built (condensed) once


def _points_key(points):
    return tuple((k, float(x), float(y)) for k, (x, y) in points.items())


def truth_machine(case: Case):
    """The machine that makes the data: 40 × 20 mesh, the case's thickness and preload."""
    from diffguide.machine.majda2012 import majda2012_machine

    key = ("truth", case.thickness, case.preload, _points_key(case.points()))
    if key not in _MACHINES:
        _MACHINES[key] = majda2012_machine(
            nx=TRUTH_MESH[0],
            ny=TRUTH_MESH[1],
            thickness=case.thickness,
            preload_fraction=case.preload,
            points=case.points(),
        )
    return _MACHINES[key]


#: The fit's structural priors: what a user who knows nothing about the table would state
#: (the defaults of ``diffguide fit``): thickness 50 mm in [25, 100] mm, preload 8 % of C in
#: [2, 16] %.
FIT_PRIORS = ((0.05, 0.025, 0.10), (0.08, 0.02, 0.16))


def fit_machine(points: dict[str, tuple[float, float]]):
    """The fit's machine: the ``majda2012`` preset (20 × 10 mesh) at ``points``, with the table
    thickness and the preload as unknowns (:data:`FIT_PRIORS`)."""
    from diffguide.inverse import MachineFamily, Prior, StructurePriors
    from diffguide.machine.majda2012 import majda2012_machine

    key = ("fit", _points_key(points))
    if key not in _MACHINES:
        t, p = FIT_PRIORS
        _MACHINES[key] = MachineFamily.build(
            lambda **kw: majda2012_machine(points=points, **kw),
            StructurePriors(Prior(*t), Prior(*p)))
    return _MACHINES[key]


def simulate_errors(case: Case) -> np.ndarray:
    """Noise-free joint errors ``(n_pos, n_points, 6)`` of the truth, in µm and µm/m."""
    from diffguide.machine.kinematics import joint_errors

    je = joint_errors(truth_machine(case), truth_rails(case), case.positions_mm() * 1e-3)
    if not bool(np.all(np.asarray(je.converged))):
        raise RuntimeError(f"{case.name}: the truth's forward model did not converge")
    return np.asarray(je.errors) * 1e6


def _sigma(instrument: str, quantity: str) -> float:
    return NOISE[(instrument, "linear" if quantity in LINEAR else "angular")]


def readings_csv(case: Case, errors: np.ndarray | None = None, noise: bool = True) -> str:
    """The case's readings as a long-format measurement CSV text (µm, µm/m).

    Time runs through each run: the forward pass then (if bidirectional) the backward pass,
    one position per time step; a run's drift is ``rate · t/T`` (``T`` the run's duration),
    ``rate ~ N(0, (drift·σ)²)`` per run and channel. ``noise=False``: exact values (no noise,
    drift or outliers).
    """
    if errors is None:
        errors = simulate_errors(case)
    rng = np.random.default_rng(case.seed)
    pos = case.positions_mm()
    n = len(pos)
    dirs = ("forward", "backward") if case.bidirectional else ("forward",)
    steps = n * len(dirs)
    names = list(case.points())  # the model's points (a point may carry several instruments)
    channels = [
        (names.index(name), name, x, y, inst, q)
        for name, x, y, inst, qs in case.sensors
        for q in qs
    ]
    rows = []
    for run in range(1, case.runs + 1):
        rate = rng.normal(0.0, case.drift, len(channels))
        t = 0
        for d in dirs:
            order = range(n) if d == "forward" else range(n - 1, -1, -1)
            for i in order:
                for c, (p, name, x, y, inst, q) in enumerate(channels):
                    sig = _sigma(inst, q)
                    v = errors[i, p, QUANTITIES.index(q)]
                    z = dict(case.z_mm).get(name, 0.0)
                    if q == "EXX":  # µm + mm · µm/m · 1e-3
                        v += z * 1e-3 * errors[i, p, QUANTITIES.index("EBX")]
                        if case.lead_um is not None:
                            v += case.lead_um(pos[i])
                    elif q == "EYX":
                        v -= z * 1e-3 * errors[i, p, QUANTITIES.index("EAX")]
                    if noise:
                        v += sig * (rng.normal() + rate[c] * t / max(steps - 1, 1))
                    unit = "um" if q in LINEAR else "um/m"
                    rows.append([pos[i], name, x, y, q, v, unit, run, d, inst, sig, z])
                t += 1
    if noise and case.outliers:
        for k in rng.choice(len(rows), case.outliers, replace=False):
            rows[k][5] += case.outlier_sigma * rows[k][10] * rng.choice((-1.0, 1.0))
    lines = [
        "# diffguide battery case " + case.name,
        "position_mm,point,x_mm,y_mm,quantity,value,unit,run,direction,instrument,z_mm",
    ]
    for p, name, x, y, q, v, unit, run, d, inst, _, z in rows:
        lines.append(f"{p:.3f},{name},{x:.1f},{y:.1f},{q},{v:.5f},{unit},{run},{d},{inst},"
                     f"{z:g}")
    return "\n".join(lines) + "\n"


def measurements(case: Case, errors: np.ndarray | None = None, noise: bool = True):
    """The case's readings through the input path: ``parse_readings`` + ``merge_readings``."""
    from diffguide.io.measurements import merge_readings, parse_readings

    text = readings_csv(case, errors, noise)
    return merge_readings(parse_readings(text, case.name), source=case.name)


# ----------------------------------------------------------------------------- the fit


def run_fit(case: Case, meas=None):
    """Fit the case's data (``meas``, default :func:`measurements`) with the preset's model —
    **the one place the battery calls the fit**.

    Today: the ``majda2012`` preset (20 × 10 mesh, 50 mm plate, 8 % preload) at the measured
    points, ``fit_rails(machine, meas)``. The structure-as-unknowns fit will take the machine
    family here. Returns an object with ``profiles(s)``, ``basis``, ``fix_slope``,
    ``converged`` and ``chi2_dof``.
    """
    from diffguide.inverse import fit_rails

    if meas is None:
        meas = measurements(case)
    points = dict(zip(meas.point_names, map(tuple, np.asarray(meas.points_xy, float))))
    return fit_rails(fit_machine(points), meas, joints=np.asarray(case.joints_mm) * 1e-3)


def oracle_machine(case: Case, points: dict[str, tuple[float, float]]):
    """The fit's model (the preset's 20 × 10 mesh) told the truth machine's structure: the
    case's thickness and preload (the preset's where the case keeps them), held fixed."""
    from diffguide.machine.majda2012 import majda2012_machine

    key = ("oracle", case.thickness, case.preload, _points_key(points))
    if key not in _MACHINES:
        _MACHINES[key] = majda2012_machine(
            points=points, thickness=case.thickness, preload_fraction=case.preload
        )
    return _MACHINES[key]


_ORACLES: dict = {}


def oracle_score(name: str):
    """Score of the **oracle** fit of case ``name``: the same data and fit, but with the truth's
    structure known (:func:`oracle_machine`) — what the layout and noise allow when nothing
    about the machine is unknown, the reference for what estimating the structure costs."""
    from diffguide.inverse import fit_rails

    from .score import score_fit

    if name not in _ORACLES:
        res = result(name)
        case = res.case
        meas = measurements(case)
        points = dict(zip(meas.point_names, map(tuple, np.asarray(meas.points_xy, float))))
        fit = fit_rails(oracle_machine(case, points), meas)
        _ORACLES[name] = score_fit(fit, lambda s: truth_profiles(case, s))
    return _ORACLES[name]


_TRUTH_MODEL_FITS: dict = {}


def truth_model_fit(name: str):
    """Case ``name``'s data fitted with **the machine that made them** (:func:`truth_machine`:
    the 40 × 20 mesh, the case's thickness and preload, held fixed) — nothing unknown but the
    rails: what these data hold at best, whatever the fit's model and structure estimate."""
    from diffguide.inverse import fit_rails

    if name not in _TRUTH_MODEL_FITS:
        case = result(name).case
        _TRUTH_MODEL_FITS[name] = fit_rails(truth_machine(case), measurements(case))
    return _TRUTH_MODEL_FITS[name]


@dataclasses.dataclass
class CaseResult:
    """A case run end to end: the fit (``None`` when it raised: ``error``) and its score."""

    case: Case
    fit: object | None
    error: str | None
    score: object | None
    seconds: float  # simulation excluded: readings → merged → fit → score


def run_case(case: Case) -> CaseResult:
    """Simulate, read, fit and score one case; an exception of the fit is recorded."""
    from .score import score_fit

    errors = simulate_errors(case)
    t0 = time.perf_counter()
    meas = measurements(case, errors)
    try:
        fit = run_fit(case, meas)
    except Exception as exc:  # noqa: BLE001 — recorded, reported in the table and the tests
        return CaseResult(
            case, None, f"{type(exc).__name__}: {exc}", None, time.perf_counter() - t0
        )
    score = score_fit(fit, lambda s: truth_profiles(case, s))
    return CaseResult(case, fit, None, score, time.perf_counter() - t0)


_RESULTS: dict[str, CaseResult] = {}


def result(name: str) -> CaseResult:
    """:func:`run_case` of ``CASES[name]``, run once per process (module-level cache)."""
    if name not in _RESULTS:
        res = _RESULTS[name] = run_case(CASES[name]())
        row = {"error": res.error, "seconds": res.seconds}
        if res.fit is not None:
            sc, st = res.score, res.fit.structure or {}
            row.update(chi2_dof=float(res.fit.chi2_dof), converged=bool(res.fit.converged),
                       knot_spacing=float(res.fit.basis.spacing),
                       **{k: getattr(sc, k) for k in ("rms_um", "rel", "sigma_rms_um",
                                                      "coverage", "overall_rms_um",
                                                      "overall_rel", "overall_sigma_rms_um",
                                                      "overall_coverage")},
                       structure={k: [float(v["value"]), float(v["sigma"])]
                                  for k, v in st.items()})
        _record("fit", name, row)
    return _RESULTS[name]


# ----------------------------------------------------------------------------- prediction

#: Points where no instrument of any layout stands (mm): the prediction's test points.
UNMEASURED = {"U1": (300.0, 100.0), "U2": (-300.0, 100.0), "U3": (-300.0, -100.0),
              "U4": (300.0, -100.0)}


class _GaugeFixed(AbstractRailProfile):
    """A truth rail less the common slope per plane the fit's gauge removes (m/m)."""

    rail: AbstractRailProfile
    slope_h: float
    slope_v: float

    def __call__(self, s):
        h, v = self.rail(s)
        return h - self.slope_h * s, v - self.slope_v * s


def gauge_fixed_truth_rails(case: Case, fit) -> tuple:
    """The truth rails with the common slope of each plane removed as
    ``RailBasis.gauge_fix`` removes it over the fit's knot range (offsets do not change the
    errors relative to the reference position)."""
    s = np.linspace(fit.basis.start, fit.basis.end, 801)
    e = truth_profiles(case, s)  # (2, 2, n): planes (vertical, horizontal)
    sc = s - s.mean()
    slope = [np.mean([sc @ (e[r, p] - e[r, p].mean()) / (sc @ sc) for r in range(2)])
             for p in range(2)]
    return tuple(_GaugeFixed(rail, float(slope[1]), float(slope[0]))
                 for rail in truth_rails(case))


def truth_at_unmeasured(case: Case, fit) -> np.ndarray:
    """The truth's errors at :data:`UNMEASURED` over the case's positions ``(n_pos, 4, 6)``
    (m, rad) on the truth machine, in the fit's gauge; EXX with the case's lead error
    (relative to x = 0, as the errors)."""
    from diffguide.machine.kinematics import joint_errors
    from diffguide.machine.majda2012 import majda2012_machine

    pts = {k: (x * 1e-3, y * 1e-3) for k, (x, y) in UNMEASURED.items()}
    key = ("truth", case.thickness, case.preload, _points_key(pts))
    if key not in _MACHINES:
        _MACHINES[key] = majda2012_machine(nx=TRUTH_MESH[0], ny=TRUTH_MESH[1],
                                           thickness=case.thickness,
                                           preload_fraction=case.preload, points=pts)
    x_mm = case.positions_mm()
    je = joint_errors(_MACHINES[key], gauge_fixed_truth_rails(case, fit), x_mm * 1e-3)
    e = np.array(je.errors)
    if case.lead_um is not None:
        e[:, :, 0] += (case.lead_um(x_mm) - case.lead_um(0.0))[:, None] * 1e-6
    return e


@dataclasses.dataclass
class PredictionScore:
    """The fit's prediction at :data:`UNMEASURED` against the truth, over the case's positions:
    ``coverage`` the fraction of (position, point, quantity) inside ±2σ; per quantity (EXX …
    ECX) ``coverage_q``, ``rel_q`` the RMS error over the truth's RMS (points and positions
    together), ``rms_um`` the RMS error (µm, µrad), ``sigma_um`` the RMS σ; ``seconds``."""

    coverage: float
    coverage_q: np.ndarray
    rel_q: np.ndarray
    rms_um: np.ndarray
    sigma_um: np.ndarray
    seconds: float


_PREDICTIONS: dict = {}


def prediction_score(name: str) -> PredictionScore:
    """Case ``name``'s fit (:func:`result`) predicting at :data:`UNMEASURED`
    (:func:`diffguide.inverse.predict.predict`) scored against :func:`truth_at_unmeasured`;
    once per process."""
    from diffguide.inverse.predict import predict
    from diffguide.machine.majda2012 import majda2012_spec

    if name not in _PREDICTIONS:
        res = result(name)
        case, fit = res.case, res.fit
        t0 = time.perf_counter()
        pts = {k: (x * 1e-3, y * 1e-3) for k, (x, y) in UNMEASURED.items()}
        pr = predict(fit, majda2012_spec(), pts, case.positions_mm() * 1e-3,
                     measured_points=case.points())
        seconds = time.perf_counter() - t0
        truth = truth_at_unmeasured(case, fit)
        err, sig = (pr.errors - truth) * 1e6, pr.sigma * 1e6
        inside = np.abs(err) <= 2 * sig
        _PREDICTIONS[name] = PredictionScore(
            coverage=float(inside.mean()), coverage_q=inside.mean(axis=(0, 1)),
            rel_q=np.sqrt(np.mean(err**2, axis=(0, 1)) / np.mean((truth * 1e6) ** 2,
                                                                  axis=(0, 1))),
            rms_um=np.sqrt(np.mean(err**2, axis=(0, 1))),
            sigma_um=np.sqrt(np.mean(sig**2, axis=(0, 1))), seconds=seconds)
        _record("prediction", name, dataclasses.asdict(_PREDICTIONS[name]))
    return _PREDICTIONS[name]


#: Environment variable naming a JSON-lines file to which every case's scores are appended as
#: they are computed (the test suite's run then yields the battery's tables: bench/
#: battery_from_log.py), unset: nothing is written.
LOG_ENV = "DIFFGUIDE_BATTERY_LOG"


def _record(kind: str, name: str, values: dict) -> None:
    path = os.environ.get(LOG_ENV)
    if not path:
        return
    row = {"kind": kind, "name": name}
    row.update({k: v if isinstance(v, (dict, str, type(None))) else np.asarray(v).tolist()
                for k, v in values.items()})
    with open(path, "a", encoding="utf-8") as fh:
        fh.write(json.dumps(row) + "\n")
