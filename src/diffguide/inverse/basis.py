r"""The unknowns of the identification: rail profiles as uniform cubic B-splines, the gauge the
data cannot fix, and the smoothness penalty.

Unknown vector ``c`` (µm): the B-spline coefficients of the four profiles, in the order of
:data:`PROFILES` — rail 1 vertical, rail 1 horizontal, rail 2 vertical, rail 2 horizontal — each
on the same knot grid ``s₀ + i·h`` that covers exactly the rail length the elements visit,
``[x_min + min X_c + min ξ, x_max + max X_c + max ξ]``.

Gauge: joint errors are relative (to ``x_ref``, and each measured channel has its own
zero), so

- a constant offset of each profile moves the table the same way at every ``x``: invisible
  (4 modes);
- a common slope ``a·s`` of both rails in one plane translates the table by ``a·x`` and tilts it
  by a constant ``a``: invisible to angular data, seen only as a linear trend in straightness
  (EZX for the vertical, EYX for the horizontal plane), which the fit gives to each straightness
  channel's alignment slope (:func:`~.fit.fit_rails`): 2 modes.

They are fixed explicitly by linear constraints on the profiles over the visited length: each
profile has zero mean, and (where ``fix_slope``; the fit fixes both planes) the two rails' mean
least-squares slopes sum to zero. The unknowns are ``c = Z θ`` with ``Z`` an orthonormal basis of
the constraints' null space, so the fit is well posed and the profiles it reports are the
representative with that gauge. To compare with a known truth, apply :meth:`RailBasis.gauge_fix`
to it.

Penalty: :math:`\sum_{profiles} ∫ e''(s)^2\,ds + ℓ^{-4}∫ e(s)^2\,ds` (``ℓ`` the visited
length), exact for cubic splines (``e''`` is piecewise linear: two-point Gauss per knot interval
is exact for its square; ``e²`` is a sextic, approximated by three-point Gauss, error ~1e-4). The
small amplitude term makes the prior proper where data and curvature leave a linear mode free.
"""

import equinox as eqx
import numpy as np

from ..guideway.rails import bspline_matrix

#: The profiles, in the order of the unknowns: (rail index, plane).
PROFILES = ((0, "vertical"), (0, "horizontal"), (1, "vertical"), (1, "horizontal"))
PLANES = ("vertical", "horizontal")


def profile_label(k: int) -> str:
    rail, plane = PROFILES[k]
    return f"rail {rail + 1} {plane}"


class RailBasis(eqx.Module):
    """A uniform cubic B-spline grid over ``[start, end]`` (m): ``n_coeffs`` coefficients.

    Arguments:
        start: first knot (m). spacing: knot spacing (m), > 0. n_coeffs: coefficients per
            profile (knot intervals + 3), >= 4.
    """

    start: float = eqx.field(static=True)
    spacing: float = eqx.field(static=True)
    n_coeffs: int = eqx.field(static=True)

    def __check_init__(self):
        if not self.spacing > 0:
            raise ValueError(f"spacing must be > 0 m, got {self.spacing!r}")
        if self.n_coeffs < 4:
            raise ValueError(f"n_coeffs must be >= 4, got {self.n_coeffs!r}")

    @classmethod
    def covering(cls, lo: float, hi: float, spacing: float) -> "RailBasis":
        """Knots from ``lo`` to ``hi`` (m), spacing the largest ≤ ``spacing`` (m) that fits."""
        if not spacing > 0:
            raise ValueError(f"knot spacing must be > 0 m, got {spacing!r}")
        if not hi > lo:
            raise ValueError(f"the rail range must have hi > lo, got [{lo}, {hi}] m")
        n_seg = max(int(np.ceil((hi - lo) / spacing - 1e-9)), 1)
        return cls(float(lo), float((hi - lo) / n_seg), n_seg + 3)

    @property
    def end(self) -> float:
        return self.start + (self.n_coeffs - 3) * self.spacing

    @property
    def size(self) -> int:
        """Length of the unknown vector (4 profiles)."""
        return 4 * self.n_coeffs

    def matrix(self, s) -> np.ndarray:
        """Collocation matrix ``(len(s), n_coeffs)`` of one profile at ``s`` (m)."""
        return bspline_matrix(np.asarray(s, float), self.start, self.spacing, self.n_coeffs)

    def second_derivative_matrix(self, s) -> np.ndarray:
        """``d²B/ds²`` at ``s`` (m) inside ``[start, end]``, ``(len(s), n_coeffs)`` (1/m²)."""
        u = (np.asarray(s, float) - self.start) / self.spacing
        i = np.clip(np.floor(u), 0, self.n_coeffs - 4).astype(int)
        t = u - i
        w = np.stack([1 - t, 3 * t - 2, 1 - 3 * t, t], axis=-1) / self.spacing**2
        D = np.zeros((len(u), self.n_coeffs))
        for k in range(4):
            np.add.at(D, (np.arange(len(u)), i + k), w[:, k])
        return D

    def penalty_factor(self) -> np.ndarray:
        """``G`` with ``‖G c‖² = Σ_profiles ∫ e''² ds`` for ``c`` the 4 stacked profiles."""
        g = np.array([0.5 - 0.5 / np.sqrt(3), 0.5 + 0.5 / np.sqrt(3)])
        s = self.start + self.spacing * (np.arange(self.n_coeffs - 3)[:, None] + g).ravel()
        one = self.second_derivative_matrix(s) * np.sqrt(0.5 * self.spacing)
        return np.kron(np.eye(4), one)

    def amplitude_factor(self) -> np.ndarray:
        """``G₀`` with ``‖G₀ c‖² = Σ_profiles ∫ e² ds / ℓ⁴``, ``ℓ = end − start`` (m).

        Added to the curvature penalty it makes the prior proper: a straight line over the
        rail length costs what a curvature of the same size over that length costs. It only
        matters for components the data and the curvature penalty both leave free (e.g. the
        difference of the two rails' horizontal slopes under a rigid table).
        """
        g = np.array([0.5 - np.sqrt(0.15), 0.5, 0.5 + np.sqrt(0.15)])
        wq = np.array([5.0, 8.0, 5.0]) / 18.0  # 3-point Gauss per knot interval
        s = self.start + self.spacing * (np.arange(self.n_coeffs - 3)[:, None] + g).ravel()
        w = np.tile(wq, self.n_coeffs - 3) * self.spacing
        ell = self.end - self.start
        one = self.matrix(s) * np.sqrt(w)[:, None] / ell**2
        return np.kron(np.eye(4), one)

    def grid(self, n: int = 400) -> np.ndarray:
        return np.linspace(self.start, self.end, n)

    def gauge_functionals(self, fix_slope: tuple[bool, bool]) -> tuple[np.ndarray, list[str]]:
        """Constraint rows ``C`` (on the stacked coefficients) and their names.

        ``fix_slope[plane]``: add the common-slope constraint in that plane (vertical,
        horizontal).
        """
        s = self.grid(801)
        B = self.matrix(s)
        mean = B.mean(axis=0)
        sc = s - s.mean()
        slope = sc @ B / (sc @ sc)
        n = self.n_coeffs
        rows, names = [], []
        for k in range(4):
            r = np.zeros(4 * n)
            r[k * n:(k + 1) * n] = mean
            rows.append(r)
            names.append(f"offset of {profile_label(k)}")
        for p, plane in enumerate(PLANES):
            if fix_slope[p]:
                r = np.zeros(4 * n)
                for k, (_, pl) in enumerate(PROFILES):
                    if pl == plane:
                        r[k * n:(k + 1) * n] = slope
                rows.append(r)
                names.append(f"common {plane} slope of both rails")
        return np.array(rows), names

    def gauge_fix(self, s, profiles, fix_slope: tuple[bool, bool]) -> np.ndarray:
        """Remove the gauge from sampled profiles: ``profiles`` ``(4, len(s))`` at uniform ``s``
        covering ``[start, end]``; returns the profiles minus their means and (where fixed) minus
        the common least-squares slope of each plane — what a fit can recover."""
        s = np.asarray(s, float)
        e = np.array(profiles, float)
        e = e - e.mean(axis=1, keepdims=True)
        sc = s - s.mean()
        for p, plane in enumerate(PLANES):
            if fix_slope[p]:
                ks = [k for k, (_, pl) in enumerate(PROFILES) if pl == plane]
                a = np.mean([sc @ e[k] / (sc @ sc) for k in ks])
                for k in ks:
                    e[k] = e[k] - a * sc
        return e


def null_space_basis(C: np.ndarray, size: int) -> np.ndarray:
    """Orthonormal basis ``Z`` ``(size, size − rank C)`` of ``{c : C c = 0}``."""
    if C.size == 0:
        return np.eye(size)
    _, sv, Vt = np.linalg.svd(C)
    rank = int(np.sum(sv > 1e-10 * sv[0]))
    return Vt[rank:].T
