r"""Merging the readings of a measurement into one value and σ per channel and position.

What a metrologist does with ISO 230-2 style runs, per channel = (point, quantity,
instrument) — so a level and an interferometer at one point are two channels, each with its own
zero — and position:

0. gross outliers are set aside: within each direction at a position, with at least
   :data:`MIN_RUNS_FOR_OUTLIERS` runs, a reading further than :data:`OUTLIER_Z` robust standard
   deviations from the median of the other readings (the scale: 1.4826 × the median of that
   same distance over the channel) is not used, and reported (:attr:`~.data.Measurements.rejected`);
1. the readings of each direction are averaged over the runs;
2. the value is the mean of the forward and backward means (so unequal run counts do not bias it;
   the reversal value, forward − backward, is kept for the report);
3. the standard uncertainty of one reading is, in this order: the ``sigma`` column; else the
   repeatability from the scatter — the pooled within-direction standard deviation over *all*
   positions of the channel, when it has at least :data:`MIN_SCATTER_DOF` degrees of freedom (a
   per-position scatter from five runs would be too noisy: its inverse square biases χ² by
   ν/(ν−2)), but never below the channel's *floor* (below); else the instrument default
   (:data:`DEFAULT_SIGMA`: 4 µm/m for levels, 2 µm/m for interferometers, 1 µm for linear
   interferometer optics);

   the floor is the larger of (a) the rounding of the written readings — half a unit of the last
   digit written, ``q/2``, uniform: ``q/√12`` (GUM F.2.2.1), ``q`` the finest step among the
   channel's readings (a writer that strips trailing zeros writes some readings coarser), in
   quadrature for a differential pair — and (b) :data:`SCATTER_FLOOR_FRACTION` (1/10) of the
   instrument default: 0.4 µm/m for a level, 0.2 µm/m for angular and 0.1 µm for linear
   interferometer optics, about the resolution class of these instruments and finer than any
   repeatability a machine tool's axis shows over runs. A smaller pooled scatter (runs that agree
   to rounding, or a resolution coarser than the file shows) is not a repeatability: it would
   give the channel a weight the data do not have. The rows are then marked ``"floor"`` in
   :attr:`~.data.Measurements.sigma_source` and a note names the channel;
4. the merged value's σ follows from step 2: ``σ_m² = ¼ (σ²/n_f + σ²/n_b)`` (``σ²/n`` with one
   direction) — except where a channel's runs are **identical at (nearly) every position**: in
   :data:`COPIES_FRACTION` (80 %) or more of its (position, direction) groups of more than one
   reading (copies of one
   run, perhaps with a reading edited, or a display coarser than the noise): their mean is no
   better than one reading and they say nothing of the repeatability, so each direction counts
   as one reading (``n = 1``) with the ``sigma`` column or else the instrument default (never
   below the readings' rounding); the rows' source then includes ``copies``
   (``"copies+default"``, ``"column+copies"``) and a note names the channel. (Copying one noisy
   run of the bundled data's yaw five times gave, with the floor, χ²/dof 1.9, no convergence
   and rails 5.6 µm off; merged as one run the fit is as good as with the real runs. Before the
   80 % rule, copies with one reading changed took the floor branch: 10–30× the weight of exact
   copies, for the same information.) Real runs agree exactly at a position only when their
   noise is below the display step; at 80 % of the positions it is well below it, and the
   rounding, which the runs share, then dominates the mean's error.

Before any of this, a file with more than :data:`MAX_POSITIONS` distinct table positions is
refused unless confirmed (``allow_many_positions``): the layouts of the paper and of ISO 230-2
read tens to a few hundred positions, and thousands — nearly one per reading — is what a file
with the position and value columns swapped looks like (each reading's value becomes a
position), which would otherwise run a fit of thousands of equilibria before failing.
"""

import math
from collections import defaultdict

import numpy as np

from .data import LINEAR, QUANTITIES, Measurements, Reading

#: Repeatability of one reading when the file gives no sigma and there are too few runs (SI).
DEFAULT_SIGMA = {("level", "angular"): 4e-6, ("interferometer", "angular"): 2e-6,
                 ("interferometer", "linear"): 1e-6}
#: Degrees of freedom a channel's pooled scatter needs before it replaces the default σ.
MIN_SCATTER_DOF = 20
#: A channel whose runs are identical at this fraction of the positions read more than once (or
#: more) is merged as copies of one run (module docstring, step 4).
COPIES_FRACTION = 0.8
#: The pooled scatter's floor, as a fraction of :data:`DEFAULT_SIGMA` (module docstring, step 3;
#: the rounding of the written readings is the other floor).
SCATTER_FLOOR_FRACTION = 0.1
#: Readings per direction and position needed before a reading can be called an outlier.
MIN_RUNS_FOR_OUTLIERS = 3
#: Distance from the median of the other readings (robust σ) beyond which a reading is an outlier.
OUTLIER_Z = 6.0
#: Most distinct table positions (to 1 µm) merged without confirmation: the paper-scale and
#: ISO 230-2 layouts read tens to a few hundred (module docstring).
MAX_POSITIONS = 1000
#: Table positions closer than this (m) are one position (:func:`snap_positions`): a file in
#: inches written to 4 decimals puts 350 mm at 13.7795 in = 349.9993 mm (the rounding of
#: 0.0001 in is ±1.27 µm); measurement layouts space their positions by millimetres.
POSITION_TOL = 5e-6


def _roundness(x: float) -> int:
    """Decimals (0..9) needed to write ``x`` (m) in mm: fewer for a position as a person wrote
    it (350) than for one converted from inches (349.9993)."""
    mm = x * 1e3
    return next((d for d in range(10) if abs(mm - round(mm, d)) < 1e-9), 10)


def snap_positions(readings, notes: list | None = None, source: str = "<readings>"):
    """``readings`` with every position within :data:`POSITION_TOL` of another taken as one:
    positions sorted, each cluster grows while the next is within the tolerance of its first;
    the cluster's position is its member that is written with the fewest decimals in mm (the
    smallest on a tie). A line in ``notes`` per data set where positions were snapped."""
    import dataclasses

    xs = sorted({float(r.position) for r in readings})
    to: dict[float, float] = {}
    i = 0
    while i < len(xs):
        j = i
        while j + 1 < len(xs) and xs[j + 1] - xs[i] <= POSITION_TOL:
            j += 1
        members = xs[i:j + 1]
        rep = min(members, key=lambda v: (_roundness(v), v))
        to.update({v: rep for v in members})
        i = j + 1
    moved = [(x, rep) for x, rep in to.items() if x != rep]
    if not moved:
        return tuple(readings)
    if notes is not None:
        x, rep = max(moved, key=lambda m: abs(m[0] - m[1]))
        notes.append(f"{source}: {len(moved)} table positions within {POSITION_TOL * 1e6:g} µm "
                     f"of another taken as that one (the farthest: {x * 1e3:.6g} mm as "
                     f"{rep * 1e3:.6g} mm; positions in inches, or files written with other "
                     "decimals)")
    return tuple(r if to[float(r.position)] == r.position
                 else dataclasses.replace(r, position=to[float(r.position)]) for r in readings)


def check_grid(readings, source: str, allow_many_positions: bool = False) -> None:
    """Refuse (``ValueError``) more than :data:`MAX_POSITIONS` distinct positions (to 1 µm)
    among ``readings`` unless ``allow_many_positions``, saying what looks wrong."""
    if allow_many_positions:
        return
    n = len({round(r.position * 1e6) for r in readings})
    if n <= MAX_POSITIONS:
        return
    swapped = (" — nearly one per reading: are the position and value columns swapped?"
               if n >= 0.5 * len(readings) else "")
    raise ValueError(
        f"{source}: {n} distinct positions from {len(readings)} readings{swapped} "
        f"(measurement layouts read tens to a few hundred; more than {MAX_POSITIONS} is "
        "refused unless confirmed: --allow-many-positions, or allow_many_positions=True)"
    )


def quantity_kind(quantity: str) -> str:
    """``"linear"`` (EXX, EYX, EZX) or ``"angular"``."""
    return "linear" if quantity in LINEAR else "angular"


def user_unit(quantity: str) -> str:
    """The unit a person reads ``quantity`` in: ``"µm"`` or ``"µm/m"``."""
    return "µm" if quantity in LINEAR else "µm/m"


def reject_outliers(groups) -> set[int]:
    """``id``s of gross outliers (module docstring, step 0). The statistic of a reading is its
    distance from the median of the *other* readings of its direction at that position; its
    robust scale, pooled over the channel, is 1.4826 × the median of the same statistic, so the
    ratio is a standard normal deviate for clean data whatever the run count."""
    dev = defaultdict(list)
    stats = []  # (channel, rows, statistics) of every group with enough runs
    for (p, q, inst, _), dirs in groups.items():
        for rows in dirs.values():
            if len(rows) >= MIN_RUNS_FOR_OUTLIERS:
                d = leave_one_out_deviation(np.array([r.value for r in rows]))
                dev[(p, q, inst)].append(d)
                stats.append(((p, q, inst), rows, d))
    scale = {k: 1.4826 * float(np.median(np.concatenate(d))) for k, d in dev.items()
             if sum(map(len, d)) >= 10}
    out = set()
    for key, rows, d in stats:
        sc = scale.get(key)
        if sc:
            out.update(id(r) for r, dk in zip(rows, d) if dk > OUTLIER_Z * sc)
    return out


def leave_one_out_deviation(v) -> np.ndarray:
    """``|v_k − median(v without v_k)|`` for every ``k``, without a median per ``k``: the median
    of the other ``n − 1`` values is one order statistic of ``v`` (two, averaged, when ``n − 1``
    is even), the ``j``-th of the others being the ``j``-th of ``v`` below ``v_k``'s rank and
    the ``(j+1)``-th from it on."""
    v = np.asarray(v, dtype=float)
    n = v.size
    order = np.argsort(v, kind="stable")
    s = v[order]
    rank = np.empty(n, dtype=int)
    rank[order] = np.arange(n)

    def others(j: int) -> np.ndarray:
        return s[np.where(j < rank, j, j + 1)]

    m = n - 1
    med = others((m - 1) // 2) if m % 2 else 0.5 * (others(m // 2 - 1) + others(m // 2))
    return np.abs(v - med)


def _points(readings) -> tuple[list, list]:
    """The points' names in order of first appearance, and their (x, y) (m)."""
    names, xy = [], []
    for r in readings:
        if r.point not in names:
            names.append(r.point)
            xy.append(r.xy)
    return names, xy


def _groups(readings, names) -> dict:
    """``{(point, quantity, instrument, position µm): {direction: [Reading]}}``, outliers
    (step 0) removed, and the set of their ``id``s. Positions are grouped on a 1 µm grid (files
    often print 100.0 and 100.0001)."""
    groups: dict[tuple, dict[str, list[Reading]]] = defaultdict(lambda: {"forward": [],
                                                                         "backward": []})
    for r in readings:
        key = (names.index(r.point), QUANTITIES.index(r.quantity), r.instrument,
               round(r.position * 1e6))
        groups[key][r.direction].append(r)
    rejected = reject_outliers(groups)
    if rejected:
        for dirs in groups.values():
            for d in dirs:
                dirs[d] = [r for r in dirs[d] if id(r) not in rejected]
    return groups, rejected


def _scatter_sums(groups):
    """Per channel: the within-direction sum of squares and its degrees of freedom, the
    (position, direction) groups read more than once, how many of them are alike, and the
    largest range (max − min) of one group."""
    ss, dof = defaultdict(float), defaultdict(int)
    repeated, same, spread = defaultdict(int), defaultdict(int), defaultdict(float)
    for (p, q, inst, _), dirs in groups.items():
        for rows in dirs.values():
            if len(rows) > 1:
                v = np.array([r.value for r in rows])
                ss[(p, q, inst)] += float(np.sum((v - v.mean()) ** 2))
                dof[(p, q, inst)] += len(rows) - 1
                repeated[(p, q, inst)] += 1
                same[(p, q, inst)] += int(np.ptp(v) == 0.0)
                spread[(p, q, inst)] = max(spread[(p, q, inst)], float(np.ptp(v)))
    return ss, dof, repeated, same, spread


def _note_copies(copies, groups, repeated, same, names, source, notes) -> None:
    """A note per channel merged as copies of one run (step 4)."""
    for p, q, inst in sorted(copies):
        quantity = QUANTITIES[q]
        stated = any(r.sigma is not None for (pp, qq, ii, _), dirs in groups.items()
                     if (pp, qq, ii) == (p, q, inst) for rows in dirs.values() for r in rows)
        one = ("its sigma column" if stated else
               f"the instrument's default "
               f"{DEFAULT_SIGMA[(inst, quantity_kind(quantity))] * 1e6:g} "
               f"{user_unit(quantity)} (or the readings' rounding, if coarser)")
        where = ("every position read more than once" if same[(p, q, inst)] == repeated[
            (p, q, inst)] else f"{same[(p, q, inst)]} of the {repeated[(p, q, inst)]} "
            "position-and-direction groups read more than once")
        notes.append(f"{source}: {quantity} at {names[p]} ({inst}): the runs are identical at "
                     f"{where} (copies of one run, or a display coarser than the noise?): "
                     f"merged as one run, σ of one reading {one}")


def _finest_rounding(groups) -> dict:
    """Per channel, the finest rounding step written (absent: unknown)."""
    res = {}
    for (p, q, inst, _), dirs in groups.items():
        for rows in dirs.values():
            for r in rows:
                if r.resolution > 0:
                    res[(p, q, inst)] = min(res.get((p, q, inst), math.inf), r.resolution)
    return res


def _alike_to_written_digits(spread: float, rounding: float) -> bool:
    """Whether readings whose largest range at one position and direction is ``spread`` are
    identical as far as the file tells: no range above one step ``q = √12 · rounding`` of the
    written digits (``rounding`` = ``q/√12``, 0: unknown, then only exact equality)."""
    return spread <= math.sqrt(12.0) * rounding * (1 + 1e-9) + 1e-18


def _pooled_scatter(ss, dof, copies, res, names, source, notes, spread=None):
    """Per channel with enough degrees of freedom (and not copies): the pooled σ of one
    reading, raised to its floor (step 3); and the channels raised. The note asks "identical
    runs?" only where the runs agree to the written digits at every position
    (:func:`_alike_to_written_digits`); a genuine repeatability finer than the floor (runs
    that differ by more than a written step) is named as that."""
    scatter, floored = {}, set()
    for ch in sorted(dof):
        if dof[ch] < MIN_SCATTER_DOF or ch in copies:
            continue
        p, q, inst = ch
        quantity = QUANTITIES[q]
        s = math.sqrt(ss[ch] / dof[ch])
        floor = max(res.get(ch, 0.0),
                    SCATTER_FLOOR_FRACTION * DEFAULT_SIGMA[(inst, quantity_kind(quantity))])
        if s < floor:
            floored.add(ch)
            if notes is not None:
                u = user_unit(quantity)
                alike = _alike_to_written_digits((spread or {}).get(ch, 0.0), res.get(ch, 0.0))
                why = ("identical runs? (they differ by at most one written digit)" if alike
                       else "a repeatability finer than the instrument class")
                notes.append(
                    f"{source}: {quantity} at {names[p]} ({inst}): the runs' pooled scatter "
                    f"{s * 1e6:.3g} {u} ({dof[ch]} degrees of freedom) is below the floor "
                    f"{floor * 1e6:.3g} {u} (the larger of the readings' rounding and "
                    f"{SCATTER_FLOOR_FRACTION:g} × the instrument's default σ): {why}; "
                    "σ of one reading set to the floor"
                )
            s = floor
        scatter[ch] = s
    return scatter, floored


def _merge_group(dirs, ch, scatter, floored, copies, res):
    """One (channel, position): the direction means, the merged value's variance terms per
    direction and the σ sources (steps 1–4)."""
    p, q, inst = ch
    means, var = [], []
    sources = set()
    for d in ("forward", "backward"):
        rs = dirs[d]
        if not rs:
            continue
        n = len(rs)
        means.append(float(np.mean([r.value for r in rs])))
        sig = []
        for r in rs:
            if r.sigma is not None:
                sig.append(r.sigma)
                sources.add("column")
            elif ch in scatter:
                sig.append(scatter[ch])
                sources.add("floor" if ch in floored else "scatter")
            else:
                default = DEFAULT_SIGMA[(inst, quantity_kind(QUANTITIES[q]))]
                sig.append(max(default, res.get(ch, 0.0)) if ch in copies else default)
                sources.add("default")
        if ch in copies:  # one reading's worth: the mean of copies is no better than one
            sources.add("copies")
            var.append(float(np.mean(np.square(sig))))
        else:
            var.append(float(np.sum(np.square(sig))) / n**2)
    return means, var, sources


def _check_one_height(rows, names, key, source) -> None:
    p, q, inst, _ = key
    if len({round(r.z * 1e6) for r in rows}) > 1:
        r0 = rows[-1]
        raise ValueError(
            f"{source}:{r0.line}: field 'z_mm': {names[p]} {QUANTITIES[q]} ({inst}) at "
            f"{r0.position * 1e3:g} mm is read at several heights (allowed: one height per "
            "point, quantity and instrument; use another point name)"
        )


def _rows(groups, names, scatter, floored, copies, res, source):
    """The merged rows' columns, and the merged row of each reading (by ``id``)."""
    keys = sorted((k for k, d in groups.items() if d["forward"] or d["backward"]),
                  key=lambda k: (k[0], k[1], k[2], k[3]))
    cols = defaultdict(list)
    row_of = {}
    for k, key in enumerate(keys):
        p, q, inst, _ = key
        dirs = groups[key]
        rows = dirs["forward"] + dirs["backward"]
        _check_one_height(rows, names, key, source)
        means, var, sources = _merge_group(dirs, (p, q, inst), scatter, floored, copies, res)
        cols["position"].append(rows[0].position)
        cols["point"].append(p)
        cols["quantity"].append(q)
        cols["value"].append(float(np.mean(means)))
        cols["sigma"].append(math.sqrt(sum(var)) / len(var))  # > 0: every σ above is
        cols["n"].append(len(rows))
        cols["reversal"].append(means[0] - means[1] if len(means) == 2 else math.nan)
        cols["instrument"].append(inst)
        cols["source"].append("+".join(sorted(sources)))
        cols["z"].append(rows[0].z)
        for r in rows:
            row_of[id(r)] = k
    return cols, row_of


#: Two files of one channel disagree in sign when, over at least :data:`CONFLICT_MIN` common
#: positions, the slope of one's values on the other's is negative by more than this many of
#: its standard errors (and their correlation is below −0.5): a reversed sensor, the commonest
#: setup slip. Two files of pure noise pass (a t of 4 on 6 degrees of freedom: p ≈ 0.004).
CONFLICT_Z = 4.0
CONFLICT_MIN = 8


def file_conflicts(readings) -> list[str]:
    """Per channel (point, quantity, instrument) read by several files: each pair of files
    with at least :data:`CONFLICT_MIN` positions in common whose values (the mean over runs
    and directions at each position) have opposite signs — the slope ``b`` of one file's
    values on the other's negative by more than :data:`CONFLICT_Z` standard errors,
    correlation below −0.5. A line per conflict, naming both files, the channel and
    ``b ± σ_b``."""
    by: dict = defaultdict(lambda: defaultdict(list))
    for r in readings:
        if r.source:
            by[(r.point, r.quantity, r.instrument)][r.source].append(r)
    out = []
    for (point, quantity, inst), files in by.items():
        names = sorted(files)
        means = {}
        for f in names:
            acc = defaultdict(list)
            for r in files[f]:
                acc[round(r.position * 1e6)].append(r.value)
            means[f] = {k: float(np.mean(v)) for k, v in acc.items()}
        for i, fa in enumerate(names):
            for fb in names[i + 1:]:
                common = sorted(means[fa].keys() & means[fb].keys())
                if len(common) < CONFLICT_MIN:
                    continue
                a = np.array([means[fa][k] for k in common])
                b = np.array([means[fb][k] for k in common])
                da, db = a - a.mean(), b - b.mean()
                saa = float(da @ da)
                if not saa > 0 or not float(db @ db) > 0:
                    continue
                slope = float(da @ db) / saa
                res = db - slope * da
                se = math.sqrt(float(res @ res) / (len(common) - 2) / saa)
                corr = float(da @ db) / math.sqrt(saa * float(db @ db))
                if slope + CONFLICT_Z * se < 0 and corr < -0.5:
                    out.append(
                        f"{quantity} at {point} ({inst}) has opposite signs in {fa} and {fb}: "
                        f"over their {len(common)} common positions the one is {slope:.3g} ± "
                        f"{se:.2g} × the other (correlation {corr:.2f}): a reversed sensor or "
                        "sign convention")
    return out


def merge_readings(readings, source: str = "<readings>", notes: list | None = None, *,
                   allow_many_positions: bool = False,
                   allow_conflicts: bool = False) -> Measurements:
    """Merge runs and directions (see the module docstring) into :class:`~.data.Measurements`.

    More than :data:`MAX_POSITIONS` distinct positions raise ``ValueError`` before any merging
    unless ``allow_many_positions`` (:func:`check_grid`).

    ``notes`` (a list) receives a line for every channel whose pooled scatter was raised to its
    floor (step 3) and for every channel merged as copies of one run (step 4). Files that
    read a channel with opposite signs (:func:`file_conflicts`) raise ``ValueError`` naming
    both, unless ``allow_conflicts`` (then a note each)."""
    readings = tuple(readings)
    if not readings:
        raise ValueError(f"{source}: no measurements")
    readings = snap_positions(readings, notes, source)
    conflicts = file_conflicts(readings)
    if conflicts and not allow_conflicts:
        raise ValueError(f"{conflicts[0]}; merged, they would cancel. Fix the sign of one file "
                         "(a profile's sign), or merge them anyway: --accept-file-conflicts "
                         "(allow_conflicts=True)"
                         + (f" ({len(conflicts) - 1} more such channel(s))"
                            if len(conflicts) > 1 else ""))
    if notes is not None:
        notes.extend(f"{c} (merged anyway: --accept-file-conflicts)" for c in conflicts)
    check_grid(readings, source, allow_many_positions)
    names, xy = _points(readings)
    groups, rejected = _groups(readings, names)
    ss, dof, repeated, same, spread = _scatter_sums(groups)
    # runs identical at (nearly) every position: copies of one run (or a display coarser than
    # the noise), which carry the information of one run — merged as one reading per direction
    copies = {ch for ch in dof if same[ch] >= COPIES_FRACTION * repeated[ch]}
    if notes is not None:
        _note_copies(copies, groups, repeated, same, names, source, notes)
    res = _finest_rounding(groups)
    scatter, floored = _pooled_scatter(ss, dof, copies, res, names, source, notes, spread)
    cols, row_of = _rows(groups, names, scatter, floored, copies, res, source)
    return Measurements(
        point_names=tuple(names),
        points_xy=np.array(xy, float),
        position=np.array(cols["position"]),
        point=np.array(cols["point"], int),
        quantity=np.array(cols["quantity"], int),
        value=np.array(cols["value"]),
        sigma=np.array(cols["sigma"]),
        n_readings=np.array(cols["n"], int),
        reversal=np.array(cols["reversal"]),
        instrument=tuple(cols["instrument"]),
        sigma_source=tuple(cols["source"]),
        z=np.array(cols["z"]),
        readings=readings,
        row_of_reading=np.array([row_of.get(id(r), -1) for r in readings], int),
        rejected=tuple(sorted(r.line for r in readings if id(r) in rejected)),
        source=source,
    )
