r"""Checks of a fit against what its data can carry, as structured warnings
(:class:`~diffguide.machine.validity.Validity`).

- **χ²/dof far from 1** (:func:`chi2_check`): outside the central :data:`CHI2_CENTRAL` of the
  distribution of ``χ²_ν/ν`` for ``ν`` = the fit's degrees of freedom (Wilson–Hilferty:
  ``χ²_ν/ν ≈ (1 − 2/(9ν) + z√(2/(9ν)))³``, ``z`` the normal quantile). Above: the model does
  not explain the data to their stated σ (the bands are widened by ``√(χ²/dof)``, but the
  profiles may be wrong); below: the stated σ are too large, or the data carry no noise.
- **Null data** (:func:`null_data`): every channel constant after its zero — the readings'
  scatter about the channel's mean below :data:`NULL_RATIO` × their stated σ. Such data
  carry no information on the rails; the profiles are the prior's.
- **Positions outside the measured range** (:func:`outside_measured`): results asked for at
  positions the data do not cover are extrapolations of the fitted model.
"""

import numpy as np

from ..machine.validity import SMALL_ANGLE as SMALL_ANGLE
from ..machine.validity import Validity, large_rotations
from .data import QUANTITIES

#: Central probability of ``χ²_ν/ν`` outside which χ²/dof is flagged.
CHI2_CENTRAL = 0.999
#: A channel whose scatter about its mean is below this fraction of its σ is constant.
NULL_RATIO = 1e-3
_Z = 3.2905  # the normal quantile of (1 + CHI2_CENTRAL)/2


def chi2_bounds(dof: float) -> tuple[float, float]:
    """``(lo, hi)``: the central :data:`CHI2_CENTRAL` interval of ``χ²_ν/ν`` (Wilson–Hilferty,
    module docstring)."""
    c = 2.0 / (9.0 * dof)
    return tuple(max(1.0 - c + s * _Z * np.sqrt(c), 0.0) ** 3 for s in (-1.0, 1.0))


def chi2_check(chi2_dof: float, dof: float) -> list[Validity]:
    """A warning when ``chi2_dof`` lies outside :func:`chi2_bounds` of ``dof``."""
    if not (np.isfinite(chi2_dof) and dof > 0):
        return []
    lo, hi = chi2_bounds(dof)
    if lo <= chi2_dof <= hi:
        return []
    if chi2_dof > hi:
        return [Validity(
            "chi2_high",
            f"χ²/dof = {chi2_dof:.3g} (dof {dof:.1f}) is above {hi:.3g}, the upper end of its "
            f"central {CHI2_CENTRAL:.1%} range: the model does not explain the data to their "
            "stated σ (the bands are widened by √(χ²/dof), the profiles may still be wrong)",
            "check fit.csv's residuals for a channel the model cannot follow, the units, and "
            "the stated σ")]
    return [Validity(
        "chi2_low",
        f"χ²/dof = {chi2_dof:.3g} (dof {dof:.1f}) is below {lo:.3g}, the lower end of its central "
        f"{CHI2_CENTRAL:.1%} range: the stated σ are larger than the data's scatter, or the "
        "data carry no noise (copies, synthetic values)",
        "check the stated σ and the data's source")]


def null_data(meas) -> list[Validity]:
    """A warning when every channel of ``meas`` is constant (module docstring)."""
    chan = meas.channel_index()
    value, sigma = np.asarray(meas.value, float), np.asarray(meas.sigma, float)
    for c in range(len(meas.channels)):
        v = value[chan == c]
        if v.size > 1 and np.std(v) > NULL_RATIO * float(np.median(sigma[chan == c])):
            return []
    return [Validity(
        "null_data",
        f"every one of the {len(meas.channels)} channels is constant (scatter below "
        f"{NULL_RATIO:g} × its stated σ once its zero is removed): the data carry no "
        "information on the rails; the profiles and their σ are the prior's",
        "check the measurement file (a constant channel is a stuck or disconnected instrument)")]


def outside_measured(meas, positions, what: str) -> list[Validity]:
    """A warning when ``positions`` (m) extend beyond the measured positions of ``meas``."""
    x = np.asarray(meas.position, float)
    p = np.asarray(positions, float)
    lo, hi = float(x.min()), float(x.max())
    if p.min() >= lo - 1e-9 and p.max() <= hi + 1e-9:
        return []
    return [Validity(
        "outside_measured_range",
        f"{what} covers [{p.min() * 1e3:g}, {p.max() * 1e3:g}] mm, the data only "
        f"[{lo * 1e3:g}, {hi * 1e3:g}] mm: beyond them it is the fitted model's extrapolation",
        "measure over the whole range, or use the results only within the measured one")]


def measured_rotations(meas) -> list[Validity]:
    """:func:`~diffguide.machine.validity.large_rotations` of the measured angular channels,
    each about its mean (an instrument's zero is not an error of the axis)."""
    chan = meas.channel_index()
    value = np.asarray(meas.value, float)
    angular = [QUANTITIES.index(q) for q in ("EAX", "EBX", "ECX")]
    dev = [value[chan == c] - value[chan == c].mean()
           for c, (_, q, _) in enumerate(meas.channels) if q in angular]
    if not dev:
        return []
    return large_rotations(np.concatenate(dev), "the measured rotations")


def fit_checks(fit, meas) -> list[Validity]:
    """The checks of a :class:`~.fit.RailFit` and its data: null data, χ²/dof, rotations."""
    return [*null_data(meas), *chi2_check(fit.chi2_dof, fit.dof), *measured_rotations(meas)]
