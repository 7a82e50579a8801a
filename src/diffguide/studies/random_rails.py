r"""Random rail profiles for tolerance studies: a stationary Gaussian process and mounting classes.

**Straightness** (:class:`GaussianRailModel`). Each rail's deviation in each of its planes is an
independent, zero-mean, stationary Gaussian process ``e(s)`` with covariance

.. math::

    \mathrm{SE}:\; k(τ) = σ^2 \exp\bigl(-τ^2 / (2ℓ^2)\bigr), \qquad
    \mathrm{Matérn}\,5/2:\; k(τ) = σ^2 \bigl(1 + \sqrt5 τ/ℓ + 5τ^2/(3ℓ^2)\bigr) e^{-\sqrt5 τ/ℓ},

``σ`` the RMS (the pointwise standard deviation, i.e. the ensemble RMS of the deviation) and
``ℓ`` the correlation length (at lag ``ℓ`` the correlation is ``e^{-1/2} ≈ 0.61`` for SE and
``≈ 0.52`` for Matérn 5/2). Rasmussen & Williams, *Gaussian Processes for Machine Learning*
(2006), eqs. 4.9 and 4.17.

The profile is represented as a :class:`~diffguide.SplineRail` on fixed knots covering the
visited rail range, so a batch of rails is a leading axis on coefficient arrays. The coefficient
covariance is the covariance of the least-squares spline projection of the process sampled on a
grid four times finer than the knots, ``Σ_c = P Σ Pᵀ``, ``P = (BᵀB)⁻¹Bᵀ``; coefficients are drawn
as ``L z`` with ``L Lᵀ = Σ_c``. With the knot spacing at most ``ℓ/4`` (the default) the spline
keeps the requested RMS and correlation to within a few per cent (checked statistically in the
tests). The RMS of *one* rail about its own mean line is smaller than ``σ`` when ``ℓ`` is not
small against the rail length (the line absorbs the longest wavelengths).

**Mounting** (:class:`MountingTolerance`). Rail 2 is mounted relative to rail 1 with a
parallelism deviation (horizontal) and a height difference (vertical). Each is modelled as a
straight line between its values at the two ends of the rail (knot range), drawn independently
and uniformly within the tolerance: horizontal end values in ``±P/2`` (so the distance between
the rails varies by at most ``P``), vertical end values in ``±S₁``. A constant offset between
the rails leaves every *relative* joint error unchanged; the slope difference does not (rails
not parallel squeeze the carriages across as the table travels; rails in a warped plane roll the
table in proportion to ``x``).

Catalogue classes (:data:`MOUNTING_CLASSES`), for size-25 ball rails: permissible parallelism
``P`` of the two rails and height difference ``S₁`` across them, by preload class. The values are
those published for HIWIN HG/QH 25 (parallelism 30 / 22 / 20 µm, height 130 / 85 / 70 µm for
preload ZO / ZA / ZB) and are representative of the size-25 catalogues (Rexroth, THK) of the same
classes; they bound service life, not accuracy, and are much looser than a precision machine's
assembly. ``"precision"`` is a machine-tool assembly target chosen here (5 µm, 10 µm), not a
catalogue value.
"""

import math
from types import MappingProxyType

import equinox as eqx
import numpy as np

from .._core.types import Array, Float
from ..guideway.rails import SplineRail, bspline_matrix, knot_centres, knot_grid

_KERNELS = ("squared_exponential", "matern52")


def correlation(tau, correlation_length: float, kernel: str = "squared_exponential"):
    """Correlation ``k(τ)/σ²`` of the stationary process at lags ``tau`` (m)."""
    if kernel not in _KERNELS:
        raise ValueError(f"kernel must be one of {_KERNELS}, got {kernel!r}")
    r = np.abs(np.asarray(tau, dtype=float)) / correlation_length
    if kernel == "squared_exponential":
        return np.exp(-0.5 * r**2)
    q = math.sqrt(5.0) * r
    return (1.0 + q + q**2 / 3.0) * np.exp(-q)


class GaussianRailModel(eqx.Module):
    """Stationary Gaussian-process straightness error of a rail (see the module docstring).

    Arguments:
        rms: ``σ``, the RMS deviation (m), ≥ 0.
        correlation_length: ``ℓ`` (m), > 0.
        kernel: ``"squared_exponential"`` (default) or ``"matern52"``.
        planes: the planes that get the error: ``("vertical", "horizontal")`` (default), or one.
    """

    rms: float = eqx.field(static=True, converter=float)
    correlation_length: float = eqx.field(static=True, converter=float)
    kernel: str = eqx.field(static=True, default="squared_exponential")
    planes: tuple[str, ...] = eqx.field(
        static=True, default=("vertical", "horizontal"), converter=tuple
    )

    def __check_init__(self):
        if not (math.isfinite(self.rms) and self.rms >= 0):
            raise ValueError(f"rms must be a finite value >= 0 m, got {self.rms!r}")
        if not (math.isfinite(self.correlation_length) and self.correlation_length > 0):
            raise ValueError(f"correlation_length must be > 0 m, got {self.correlation_length!r}")
        if self.kernel not in _KERNELS:
            raise ValueError(f"kernel must be one of {_KERNELS}, got {self.kernel!r}")
        if not self.planes or any(p not in ("vertical", "horizontal") for p in self.planes):
            raise ValueError(
                "planes must be a non-empty subset of ('vertical', 'horizontal'), got "
                f"{self.planes!r}"
            )

    def coefficient_factor(self, start: float, spacing: float, n_coeffs: int) -> np.ndarray:
        """``L`` with ``L Lᵀ`` the covariance of the spline coefficients (m), ``(n, n)``."""
        lo, hi = start, start + (n_coeffs - 3) * spacing
        s = np.linspace(lo, hi, 4 * (n_coeffs - 3) + 1)
        B = bspline_matrix(s, start, spacing, n_coeffs)
        P = np.linalg.solve(B.T @ B, B.T)
        K = correlation(s[:, None] - s[None, :], self.correlation_length, self.kernel)
        cov = self.rms**2 * (P @ K @ P.T)
        cov = 0.5 * (cov + cov.T)
        # eigen-factor: robust for the near-singular covariances of long correlation lengths
        w, V = np.linalg.eigh(cov)
        return V * np.sqrt(np.clip(w, 0.0, None))


class MountingTolerance(eqx.Module):
    """Mounting tolerance of rail 2 relative to rail 1 (see the module docstring).

    Arguments:
        parallelism: ``P``, the permissible variation of the horizontal distance between the
            rails over their length (m), ≥ 0.
        height: ``S₁``, the permissible height difference between the rails (m), ≥ 0.
        name: a label.
    """

    parallelism: float = eqx.field(static=True, converter=float)
    height: float = eqx.field(static=True, converter=float)
    name: str = eqx.field(static=True, default="")

    def __check_init__(self):
        for field, v in (("parallelism", self.parallelism), ("height", self.height)):
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{field} must be a finite value >= 0 m, got {v!r}")


#: Mounting classes for size-25 rails (see the module docstring for sources): P and S₁ in m.
MOUNTING_CLASSES = MappingProxyType(
    {
        "none": MountingTolerance(0.0, 0.0, "none"),
        "precision": MountingTolerance(5e-6, 10e-6, "precision (assembly target)"),
        "size25-ZB": MountingTolerance(20e-6, 70e-6, "size 25, heavy preload (ZB)"),
        "size25-ZA": MountingTolerance(22e-6, 85e-6, "size 25, medium preload (ZA)"),
        "size25-ZO": MountingTolerance(30e-6, 130e-6, "size 25, light preload (ZO)"),
    }
)


class RailBatch(eqx.Module):
    """A batch of rail pairs as :class:`~diffguide.guideway.rails.SplineRail` coefficients.

    Attributes:
        start: first knot (m). spacing: knot spacing (m).
        vertical: ``e_z`` coefficients, ``(n_samples, 2, n)`` (rail 1, rail 2) (m).
        horizontal: ``e_y`` coefficients, same shape (m).
    """

    start: float = eqx.field(static=True)
    spacing: float = eqx.field(static=True)
    vertical: Float[Array, "b 2 n"]
    horizontal: Float[Array, "b 2 n"]

    def __check_init__(self):
        shape = np.shape(self.vertical)
        if len(shape) != 3 or shape[1] != 2 or shape[2] < 4 or np.shape(self.horizontal) != shape:
            raise ValueError(
                "vertical and horizontal must have the same shape (n_samples, 2, n >= 4), got "
                f"{np.shape(self.vertical)} and {np.shape(self.horizontal)}"
            )

    def __len__(self) -> int:
        return np.shape(self.vertical)[0]

    @property
    def n_coeffs(self) -> int:
        return np.shape(self.vertical)[2]

    @property
    def end(self) -> float:
        """Last knot (m)."""
        return self.start + (self.n_coeffs - 3) * self.spacing

    def rails(self, i: int) -> tuple[SplineRail, SplineRail]:
        """Sample ``i`` as the pair ``(rail 1, rail 2)``."""
        return rails_from_coefficients(
            self.start, self.spacing, self.vertical[i], self.horizontal[i]
        )

    def __getitem__(self, index) -> "RailBatch":
        """A sub-batch (slice or index array)."""
        v, h = self.vertical[index], self.horizontal[index]
        if np.ndim(v) != 3:
            raise ValueError("index a RailBatch with a slice or an index array; use .rails(i)")
        return RailBatch(self.start, self.spacing, v, h)


def rails_from_coefficients(start, spacing, vertical, horizontal) -> tuple[SplineRail, SplineRail]:
    """``(rail 1, rail 2)`` from coefficient arrays ``(2, n)`` (works under ``vmap``)."""
    return (
        SplineRail(start, spacing, vertical[0], horizontal[0]),
        SplineRail(start, spacing, vertical[1], horizontal[1]),
    )


def default_knots(
    correlation_length: float | None = None,
    *,
    start: float = -0.6,
    end: float = 0.6,
    spacing: float = 0.025,
) -> tuple[float, float, int]:
    """Knots ``(start, spacing, n_coeffs)`` covering ``[start, end]`` (m) at ``spacing`` (m),
    refined to at most ``ℓ/4`` for short correlation lengths ``ℓ`` (m).

    The default range ±0.6 m covers what the ``majda2012`` elements visit over the ±350 mm
    stroke (±0.532 m).
    """
    if correlation_length is not None:
        spacing = min(spacing, correlation_length / 4)
    return knot_grid(start, end, spacing)


def linear_coefficients(start: float, spacing: float, n_coeffs: int, a, b):
    """Coefficients of the straight line ``a + (b − a)(s − s₀)/(s_end − s₀)`` (cubic B-splines
    reproduce lines exactly: coefficient ``k`` is the line at ``s₀ + (k − 1)h``).

    ``a``, ``b``: end values, any leading shape ``(...)``; returns ``(..., n_coeffs)``.
    """
    length = (n_coeffs - 3) * spacing
    t = (knot_centres(start, spacing, n_coeffs) - start) / length
    a = np.asarray(a, dtype=float)[..., None]
    b = np.asarray(b, dtype=float)[..., None]
    return a + (b - a) * t


#: memory (bytes) of one sample beyond its rails: its statistics, columns and CSV row (measured
#: ~3 kB for the nine points of majda2012, with a margin)
SAMPLE_OUTPUT_BYTES = 4096


def study_bytes(n_samples: int, n_coeffs: int) -> int:
    """About the memory (bytes) a study of ``n_samples`` random rail pairs holds at once: each
    sample's rails (two rails, two planes, ``n_coeffs`` float64 coefficients each) and its
    outputs (:data:`SAMPLE_OUTPUT_BYTES`)."""
    return int(n_samples) * (2 * 2 * int(n_coeffs) * 8 + SAMPLE_OUTPUT_BYTES)


def sample_rails(
    rng: np.random.Generator | int,
    n_samples: int,
    model: GaussianRailModel | None = None,
    mounting: MountingTolerance | str | None = None,
    *,
    knots: tuple[float, float, int] | None = None,
) -> RailBatch:
    """Draw ``n_samples`` independent rail pairs.

    Both rails get independent straightness errors from ``model`` (in ``model.planes``); rail 2
    is then mounted with a random parallelism and height deviation within ``mounting``.

    Arguments:
        rng: a NumPy generator or a seed.
        n_samples: batch size, ≥ 1.
        model: straightness model; ``None`` for straight rails.
        mounting: a :class:`MountingTolerance`, a key of :data:`MOUNTING_CLASSES`, or ``None``.
        knots: ``(start, spacing, n_coeffs)`` (m, m, -); default :func:`default_knots` for the
            model's correlation length.

    Returns:
        a :class:`RailBatch` (float64 NumPy arrays, m; kept on the host so that no float32
        conversion can happen before the solver checks for float64).
    """
    if int(n_samples) != n_samples or n_samples < 1:
        raise ValueError(f"n_samples must be an integer >= 1, got {n_samples!r}")
    if isinstance(mounting, str):
        if mounting not in MOUNTING_CLASSES:
            raise ValueError(f"mounting must be one of {tuple(MOUNTING_CLASSES)}, got {mounting!r}")
        mounting = MOUNTING_CLASSES[mounting]
    rng = np.random.default_rng(rng)
    if knots is None:
        knots = default_knots(None if model is None else model.correlation_length)
    start, spacing, n = knots
    shape = (n_samples, 2, n)
    coeffs = {"vertical": np.zeros(shape), "horizontal": np.zeros(shape)}
    if model is not None and model.rms > 0:
        L = model.coefficient_factor(start, spacing, n)
        for plane in ("vertical", "horizontal"):  # fixed order: reproducible draws
            z = rng.standard_normal(shape)
            if plane in model.planes:
                coeffs[plane] = z @ L.T
    if mounting is not None:
        ends_h = rng.uniform(-0.5, 0.5, (n_samples, 2)) * mounting.parallelism
        ends_v = rng.uniform(-1.0, 1.0, (n_samples, 2)) * mounting.height
        coeffs["horizontal"][:, 1] += linear_coefficients(start, spacing, n, *ends_h.T)
        coeffs["vertical"][:, 1] += linear_coefficients(start, spacing, n, *ends_v.T)
    return RailBatch(start, spacing, coeffs["vertical"], coeffs["horizontal"])
