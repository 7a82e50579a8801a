r"""Each measurement file's χ² against a fit of the merged data: how well the fitted model, fitted
to every file at once, explains the readings of one file.

Several files of one channel are merged into one value per position (:mod:`.merge`); where two
of them disagree (a reversed sensor accepted with ``--accept-file-conflicts``) the merged value
sits between them and the fit's χ² alone does not say which file is off. Per file ``f`` and
merged row ``k`` it reads, the file's own value ``m_fk`` (the mean of its forward and backward
means, as the merge forms the row's value) is compared with the fitted value ``ŷ_k``:

.. math::  χ²_f = \sum_k \left(\frac{m_{fk} - ŷ_k}{σ_{fk}}\right)^2, \qquad
           σ_{fk} = σ_k \sqrt{n_k / n_{fk}},

``σ_k`` the merged row's standard uncertainty from ``n_k`` readings, ``n_fk`` of them the file's
(the σ of a mean of fewer readings; a row merged as copies of one run, whose σ does not shrink
with the readings, keeps ``σ_k``). Rows the fit gave zero weight (outliers) are left out. The
degrees of freedom are the file's share of the fit's: ``ν_f = N_f · ν / N`` (``N`` the used rows,
``N_f`` the file's), so that ``χ²_f / ν_f`` is about 1 for a file the model explains to its σ.
"""

from collections import defaultdict

import numpy as np


def file_chi2(meas, fitted, outliers=(), dof: float | None = None) -> list[dict]:
    """Per source file of ``meas.readings`` (one entry per file, in name order; empty when the
    readings name fewer than two files): ``{"file", "rows", "readings", "chi2", "dof",
    "chi2_per_dof"}`` against ``fitted`` (the fitted value of every merged row, SI), the rows
    ``outliers`` left out; ``dof`` the fit's degrees of freedom (default: the used rows)."""
    files = sorted({r.source for r in meas.readings if r.source})
    if len(files) < 2 or len(meas.row_of_reading) != len(meas.readings):
        return []
    fitted = np.asarray(fitted, float)
    skip = set(int(i) for i in np.asarray(outliers, int).ravel())
    used = meas.n - len(skip)
    share = (used if dof is None else float(dof)) / max(used, 1)
    acc = defaultdict(lambda: {"forward": [], "backward": []})  # (file, row) -> values
    for r, k in zip(meas.readings, meas.row_of_reading):
        if k >= 0 and int(k) not in skip and r.source:
            acc[(r.source, int(k))][r.direction].append(r.value)
    out = []
    for f in files:
        chi2, rows, n = 0.0, 0, 0
        for (g, k), dirs in acc.items():
            if g != f:
                continue
            means = [np.mean(v) for v in dirs.values() if v]
            n_f = sum(map(len, dirs.values()))
            copies = "copies" in meas.sigma_source[k]
            sig = meas.sigma[k] * (1.0 if copies else np.sqrt(meas.n_readings[k] / n_f))
            chi2 += float((np.mean(means) - fitted[k]) / sig) ** 2
            rows += 1
            n += n_f
        nu = rows * share
        out.append({"file": f, "rows": rows, "readings": n, "chi2": chi2, "dof": nu,
                    "chi2_per_dof": chi2 / nu if nu > 0 else None})
    return out
