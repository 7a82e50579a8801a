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

Rail joints: where the user states that the rails are joined (two segments meeting at ``s_j``),
each profile gains one more unknown, the height of a step there
(:func:`~diffguide.guideway.rails.joint_ramp`, smoothed over ``joint_width``): a step the knot
grid cannot hold (it would ring over several knot spacings) and the curvature penalty does not
charge for (the step is what the data say; only the amplitude term bounds it). Each profile's
unknowns are its ``n_coeffs`` spline coefficients followed by its step heights:
``per_profile = n_coeffs + len(joints)``.
"""

import equinox as eqx
import numpy as np

from ..guideway.rails import JOINT_WIDTH, basis_rail, bspline_matrix, joint_ramp

#: The profiles, in the order of the unknowns: (rail index, plane).
PROFILES = ((0, "vertical"), (0, "horizontal"), (1, "vertical"), (1, "horizontal"))
PLANES = ("vertical", "horizontal")


def profile_label(k: int) -> str:
    rail, plane = PROFILES[k]
    return f"rail {rail + 1} {plane}"


class RailBasis(eqx.Module):
    """A uniform cubic B-spline grid over ``[start, end]`` (m): ``n_coeffs`` coefficients, and
    a step at each rail joint.

    Arguments:
        start: first knot (m). spacing: knot spacing (m), > 0. n_coeffs: spline coefficients
            per profile (knot intervals + 3), >= 4. joints: rail joint positions (m), strictly
            inside ``(start, end)``, increasing. joint_width: the steps' rise (m), > 0.
    """

    start: float = eqx.field(static=True)
    spacing: float = eqx.field(static=True)
    n_coeffs: int = eqx.field(static=True)
    joints: tuple[float, ...] = eqx.field(static=True, default=())
    joint_width: float = eqx.field(static=True, default=JOINT_WIDTH)

    def __check_init__(self):
        if not self.spacing > 0:
            raise ValueError(f"spacing must be > 0 m, got {self.spacing!r}")
        if self.n_coeffs < 4:
            raise ValueError(f"n_coeffs must be >= 4, got {self.n_coeffs!r}")
        check_joints(self.joints, self.joint_width, self.start, self.end)

    @classmethod
    def covering(cls, lo: float, hi: float, spacing: float, joints=(),
                 joint_width: float = JOINT_WIDTH) -> "RailBasis":
        """Knots from ``lo`` to ``hi`` (m), spacing the largest ≤ ``spacing`` (m) that fits;
        ``joints``, ``joint_width`` (m) as the class's."""
        if not spacing > 0:
            raise ValueError(f"knot spacing must be > 0 m, got {spacing!r}")
        if not hi > lo:
            raise ValueError(f"the rail range must have hi > lo, got [{lo}, {hi}] m")
        n_seg = max(int(np.ceil((hi - lo) / spacing - 1e-9)), 1)
        return cls(float(lo), float((hi - lo) / n_seg), n_seg + 3,
                   tuple(float(j) for j in joints), float(joint_width))

    @property
    def end(self) -> float:
        return self.start + (self.n_coeffs - 3) * self.spacing

    @property
    def per_profile(self) -> int:
        """Unknowns per profile: the spline's coefficients, then one step height per joint."""
        return self.n_coeffs + len(self.joints)

    @property
    def size(self) -> int:
        """Length of the unknown vector (4 profiles)."""
        return 4 * self.per_profile

    def matrix(self, s) -> np.ndarray:
        """Collocation matrix ``(len(s), per_profile)`` of one profile at ``s`` (m): the
        B-splines, then the joints' unit steps."""
        s = np.asarray(s, float)
        B = bspline_matrix(s, self.start, self.spacing, self.n_coeffs)
        if not self.joints:
            return B
        return np.hstack([B, joint_ramp(s, self.joints, self.joint_width, xp=np)])

    def rails(self, coeffs) -> tuple:
        """The two rails of coefficients ``(2 rails, 2 planes, per_profile)`` (m), as
        :func:`~diffguide.guideway.rails.basis_rail` lays them out."""
        return tuple(basis_rail(self.start, self.spacing, coeffs[r, 0], coeffs[r, 1],
                                self.joints, self.joint_width) for r in range(2))

    def second_derivative_matrix(self, s) -> np.ndarray:
        """``d²B/ds²`` of the spline at ``s`` (m) inside ``[start, end]``,
        ``(len(s), per_profile)`` (1/m²); the steps' columns are zero (not charged)."""
        u = (np.asarray(s, float) - self.start) / self.spacing
        i = np.clip(np.floor(u), 0, self.n_coeffs - 4).astype(int)
        t = u - i
        w = np.stack([1 - t, 3 * t - 2, 1 - 3 * t, t], axis=-1) / self.spacing**2
        D = np.zeros((len(u), self.per_profile))
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
        n = self.per_profile
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


def check_joints(joints, width: float, start: float, end: float) -> None:
    """Rail joints (m) must be finite, increasing, at least ``width`` (m) apart and inside
    ``(start, end)`` (m) by half a width: ``ValueError`` naming the joint otherwise."""
    if not (np.isfinite(width) and width > 0):
        raise ValueError(f"joint_width must be a finite width > 0 m, got {width!r}")
    prev = -np.inf
    for k, s in enumerate(joints):
        if not (np.isfinite(s) and start + width / 2 < s < end - width / 2):
            raise ValueError(
                f"rail joint {k + 1} at {s!r} m ({s * 1e3:g} mm) is not inside the fitted rail "
                f"range ({start * 1e3:.1f} .. {end * 1e3:.1f} mm) by half the step width "
                f"({width * 1e3:g} mm)")
        if s - prev < width:
            raise ValueError(
                f"rail joints must increase by at least the step width {width * 1e3:g} mm; "
                f"joint {k + 1} at {s * 1e3:g} mm follows {prev * 1e3:g} mm")
        prev = s


def null_space_basis(C: np.ndarray, size: int) -> np.ndarray:
    """Orthonormal basis ``Z`` ``(size, size − rank C)`` of ``{c : C c = 0}``."""
    if C.size == 0:
        return np.eye(size)
    _, sv, Vt = np.linalg.svd(C)
    rank = int(np.sum(sv > 1e-10 * sv[0]))
    return Vt[rank:].T
