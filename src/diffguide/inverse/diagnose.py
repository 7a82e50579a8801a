r"""Why a fit does not follow its data: when ``χ²/dof`` is far above 1, the normalised residuals
``z_i = (y_i − m_i)/σ_i`` of each channel are examined for the signature of a likely cause, and
each cause found is named with what to do.

Per channel ``c`` (its used rows sorted by position ``x``), with ``n_c`` rows:

- **normalised RMS** ``ρ_c = (Σ z²/n_c)^½`` (≈ 1 where σ is right and the model fits);
- **linear trend**: the least-squares line ``a + b(x − x̄)``; its share of the channel's
  ``Σ z²`` and its significance ``F = SS_line / s²`` (``s²`` the rest per degree of freedom;
  ≈ 2 for white residuals);
- **spectral peak**: on the detrended residual, the sinusoid ``A sin(2πx/λ) + B cos(2πx/λ)``
  that explains most of it over wavelengths from twice the position step to the measured span
  (a least-squares periodogram, Lomb–Scargle style, valid for uneven positions); its
  significance ``F = SS_peak / s²`` (for white residuals, the largest of about ``n_c/2``
  χ²₂ values: below :data:`PEAK_F` but for one case in ~10⁴).

The causes, checked in this order (several may be reported):

1. **a channel's σ understated** — one channel's ``ρ_c`` at least :data:`SIGMA_RATIO` × the
   median of the others, its residuals white (no significant trend or peak): that channel's
   σ is too small by about that ratio;
2. **a missing nuisance** — a channel whose residual is mostly a significant straight line
   (share ≥ :data:`TREND_SHARE`): a drift, an alignment or a reference the model has no term
   for;
3. **knots too coarse** — significant spectral peaks in the channels carrying most of the
   ``χ²``, at a common wavelength ``λ*`` shorter than :data:`KNOT_WAVELENGTHS` knot
   spacings: a cubic B-spline with knot spacing ``h`` does not follow content much shorter
   than ``3h``; refit with the knot spacing ``max(default, λ*/4)``, rounded down to a mm;
4. **the model** — structured residuals at wavelengths the knots do resolve: the machine model
   (structure, geometry, mesh) does not explain the data;
5. **σ understated everywhere** — white residuals of similar ``ρ_c`` in every channel: every
   σ stated too small by about ``(χ²/dof)^½`` (a sheet's σ column, or the scatter of too few
   runs).
"""

import dataclasses

import numpy as np

#: ``χ²/dof`` above which the residuals are examined.
MISFIT_CHI2 = 2.0
#: A channel ``ρ_c`` at least this many times the others' median: its σ looks understated.
SIGMA_RATIO = 2.0
#: A line's significance (``F``, 2 parameters) beyond which a trend is real.
TREND_F = 30.0
#: Share of a channel's ``Σz²`` that a real trend must carry to be named the cause.
TREND_SHARE = 0.5
#: A spectral peak's significance (``F``) beyond which the residual has structure.
PEAK_F = 30.0
#: Content at wavelengths shorter than this many knot spacings: the knots are too coarse.
KNOT_WAVELENGTHS = 3.0


@dataclasses.dataclass(frozen=True)
class Finding:
    """One likely cause of a misfit.

    Attributes:
        cause: ``"sigma"`` (a channel's σ understated), ``"nuisance"`` (a trend the model has
            no term for), ``"knots"`` (knots too coarse), ``"model"`` (structured residuals the
            knots resolve), ``"sigma_all"`` (every σ understated).
        channels: the channels concerned (indices). message: what the residuals show, in
            words. action: what to do. values: the numbers behind it (``ratio``, ``share``,
            ``wavelength_mm``, ``suggested_knot_spacing_mm``, …).
    """

    cause: str
    channels: tuple[int, ...]
    message: str
    action: str
    values: dict = dataclasses.field(default_factory=dict)

    def as_dict(self) -> dict:
        return {"cause": self.cause, "channels": list(self.channels), "message": self.message,
                "action": self.action, **self.values}


@dataclasses.dataclass(frozen=True)
class ChannelStats:
    """The residual statistics of one channel (module docstring): rows ``n``, normalised RMS
    ``rms``, trend share and ``F``, slope (σ per m), spectral peak wavelength (m), share and
    ``F``."""

    n: int
    chi2: float
    rms: float
    trend_share: float
    trend_f: float
    slope: float
    peak_wavelength: float
    peak_share: float
    peak_f: float
    peak_ss: np.ndarray  # explained SS per trial wavelength (for the common peak)

    @property
    def trend(self) -> bool:
        return self.trend_f > TREND_F

    @property
    def structured(self) -> bool:
        return self.peak_f > PEAK_F

    @property
    def white(self) -> bool:
        return not (self.trend or self.structured)


def trial_wavelengths(position) -> np.ndarray:
    """Log-spaced wavelengths (m) from twice the smallest position step to the span."""
    x = np.unique(np.asarray(position, float))
    if len(x) < 4:
        return np.zeros(0)
    step = float(np.min(np.diff(x)))
    span = float(x[-1] - x[0])
    lo = max(2.0 * step * 1.05, 1e-6)
    return np.geomspace(lo, span, 80) if span > lo else np.zeros(0)


def channel_stats(z, x, wavelengths) -> ChannelStats:
    """:class:`ChannelStats` of the normalised residuals ``z`` at positions ``x`` (m)."""
    z, x = np.asarray(z, float), np.asarray(x, float)
    n = len(z)
    chi2 = float(z @ z)
    rms = float(np.sqrt(chi2 / n)) if n else float("nan")
    if n < 6 or chi2 <= 0:
        return ChannelStats(n, chi2, rms, 0.0, 0.0, 0.0, float("nan"), 0.0, 0.0,
                            np.zeros(len(wavelengths)))
    u = x - x.mean()
    A = np.column_stack([np.ones(n), u])
    coef, *_ = np.linalg.lstsq(A, z, rcond=None)
    line = A @ coef
    rest = z - line
    ss_line = float(line @ line)
    s2 = max(float(rest @ rest) / max(n - 2, 1), 1e-300)
    ss = np.zeros(len(wavelengths))
    for k, lam in enumerate(wavelengths):
        B = np.column_stack([np.sin(2 * np.pi * x / lam), np.cos(2 * np.pi * x / lam),
                             np.ones(n), u])
        c, *_ = np.linalg.lstsq(B, rest, rcond=None)
        fit = B @ c
        ss[k] = float(fit @ fit)
    k = int(np.argmax(ss)) if len(ss) else 0
    rr = float(rest @ rest)
    peak = float(ss[k]) if len(ss) else 0.0
    s2_peak = max((rr - peak) / max(n - 4, 1), 1e-300)
    return ChannelStats(
        n, chi2, rms, ss_line / chi2, ss_line / s2, float(coef[1]),
        float(wavelengths[k]) if len(ss) else float("nan"),
        peak / chi2, peak / s2_peak, ss)


def diagnose(z, chan, position, *, chi2_dof: float, knot_spacing: float,
             default_spacing: float | None = None, labels=None,
             threshold: float = MISFIT_CHI2) -> list[Finding]:
    """The likely causes of a misfit (module docstring), from the normalised residuals.

    Arguments:
        z: normalised residuals ``(y − m)/σ`` of the used rows (outliers left out).
        chan: each row's channel (integers). position: each row's table position (m).
        chi2_dof: the fit's ``χ²/dof``; below ``threshold`` nothing is examined (``[]``).
        knot_spacing: the fit's knot spacing (m). default_spacing: the default (m; the
            carriage's loaded length), the finest spacing suggested; default ``knot_spacing/2``.
        labels: each channel's name for the messages (default ``channel k``).

    Returns:
        The :class:`Finding` list, the most specific first; empty when ``χ²/dof`` is below
        ``threshold``.
    """
    z, chan, x = (np.asarray(a) for a in (z, chan, position))
    if not (np.isfinite(chi2_dof) and chi2_dof > threshold) or z.size == 0:
        return []
    channels = [int(c) for c in np.unique(chan)]
    label = (lambda c: labels[c]) if labels is not None else (lambda c: f"channel {c}")
    wl = trial_wavelengths(x)
    stats = {c: channel_stats(z[chan == c], x[chan == c], wl) for c in channels}
    total = sum(s.chi2 for s in stats.values())
    out = [f for f in (_sigma_finding(stats, label), *_trend_findings(stats, label))
           if f is not None]
    named = {c for f in out for c in f.channels}
    rest = {c: s for c, s in stats.items() if c not in named}
    structural = _structure_finding(rest, total, wl, knot_spacing,
                                    default_spacing or knot_spacing / 2, label)
    if structural is not None:
        out.append(structural)
    elif not out and all(s.white for s in stats.values()):
        ratio = float(np.sqrt(chi2_dof))
        out.append(Finding(
            "sigma_all", tuple(channels),
            f"chi2/dof {chi2_dof:.3g}: the residuals of every channel are white, of similar "
            f"size: every sigma looks understated about {ratio:.2g}x",
            "check the stated sigma (a sigma column; the scatter of too few runs), or accept "
            "the bands, which are widened by sqrt(chi2/dof)", {"ratio": ratio}))
    return out


def _sigma_finding(stats, label) -> Finding | None:
    """One white channel far above the others (cause 1)."""
    if len(stats) < 2:
        return None
    c = max(stats, key=lambda k: stats[k].rms)
    s = stats[c]
    others = float(np.median([t.rms for k, t in stats.items() if k != c]))
    ratio = s.rms / max(others, 1e-300)
    if not (ratio >= SIGMA_RATIO and s.white):
        return None
    return Finding(
        "sigma", (c,),
        f"{label(c)}: white residuals {ratio:.2g}x the other channels' (normalised RMS "
        f"{s.rms:.3g} against {others:.3g}): its sigma looks understated about {ratio:.2g}x",
        f"check {label(c)}'s instrument and its stated sigma (the sigma column); give it its "
        "own sigma or leave it out", {"ratio": ratio, "rms": s.rms, "others_rms": others})


def _trend_findings(stats, label) -> list[Finding]:
    """Channels whose residual is mostly a real straight line (cause 2)."""
    out = []
    for c, s in stats.items():
        if s.trend and s.trend_share >= TREND_SHARE:
            out.append(Finding(
                "nuisance", (c,),
                f"{label(c)}: a linear trend in position carries {100 * s.trend_share:.0f} % "
                f"of its residual ({s.slope * 1e-3:.3g} sigma per mm): a drift over the runs, "
                "a misalignment or a reference the model has no term for",
                f"check {label(c)} for drift (bidirectional runs cancel a drift linear in "
                "time in their mean) and its mounting; remove the trend or give the channel "
                "its own term", {"share": s.trend_share, "slope_sigma_per_mm": s.slope * 1e-3}))
    return out


def _structure_finding(stats, total, wl, h, h_default, label) -> Finding | None:
    """Structured residuals in the channels carrying most of χ² (causes 3 and 4)."""
    structured = [c for c, s in stats.items() if s.structured]
    share = sum(stats[c].chi2 for c in structured) / max(total, 1e-300)
    if not structured or share < 0.5 or not len(wl):
        return None
    common = np.sum([stats[c].peak_ss for c in structured], axis=0)
    lam = float(wl[int(np.argmax(common))])
    values = {"wavelength_mm": lam * 1e3, "share": share, "knot_spacing_mm": h * 1e3}
    names = ", ".join(label(c) for c in structured[:4]) + (" ..." if len(structured) > 4 else "")
    if lam < KNOT_WAVELENGTHS * h:
        suggest = max(h_default, lam / 4)
        suggest_mm = max(np.floor(suggest * 1e3), 1.0)
        if suggest_mm < h * 1e3 - 0.5:
            values["suggested_knot_spacing_mm"] = float(suggest_mm)
            return Finding(
                "knots", tuple(structured),
                f"structured residuals ({names}; {100 * share:.0f} % of chi2) with content at "
                f"about {lam * 1e3:.0f} mm, shorter than {KNOT_WAVELENGTHS:g}x the knot "
                f"spacing {h * 1e3:.0f} mm: the knots are too coarse to follow the rails",
                f"refit with --knot-spacing-mm {suggest_mm:g}", values)
    return Finding(
        "model", tuple(structured),
        f"structured residuals ({names}; {100 * share:.0f} % of chi2) at about "
        f"{lam * 1e3:.0f} mm, which the knots ({h * 1e3:.0f} mm) resolve: the machine model "
        "(structure, geometry, instruments' points) does not explain the data",
        "check the machine file (thickness, carriage spacing, preload) and the points' "
        "coordinates; widen the structure's prior", values)


def diagnose_fit(fit, meas, default_spacing: float | None = None,
                 threshold: float = MISFIT_CHI2) -> list[Finding]:
    """:func:`diagnose` of a :class:`~.fit.RailFit` on its merged measurements ``meas``
    (outliers left out; ``default_spacing`` the default knot spacing, m)."""
    sigma = np.asarray(meas.sigma, float)
    used = np.ones(meas.n, bool)
    used[np.asarray(fit.outliers, int)] = False
    z = np.asarray(fit.residual, float) / sigma
    chan = meas.channel_index()
    labels = [meas.channel_label(c) for c in range(len(meas.channels))]
    return diagnose(z[used], chan[used], np.asarray(meas.position)[used],
                    chi2_dof=fit.chi2_dof, knot_spacing=fit.basis.spacing,
                    default_spacing=default_spacing, labels=labels, threshold=threshold)
