# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.7
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Fitting rail straightness to level and interferometer data
#
# The product's main job: from pitch, roll and yaw curves measured at a few places on the table,
# recover the straightness profiles of both rails — vertical and horizontal — with uncertainty,
# through the elastic machine model. The bundled data set (`data/majda2012_measurements.csv`) is
# synthetic but realistic: electronic levels at the four corners read pitch and roll, an angular
# interferometer at the centre reads pitch and yaw, five bidirectional runs with 4 µm/m and 2 µm/m
# noise. Its truth (`data/majda2012_truth.csv`) is a sum of sinusoids and a polynomial — not a
# spline — simulated on a finer table mesh than the fit uses (`data/make_majda2012_measurements.py`).

# %%
import jax
jax.config.update("jax_enable_x64", True)

import numpy as np
import matplotlib.pyplot as plt
plt.rcParams["figure.dpi"] = 110
from diffguide.io.measurements import read_measurements
from diffguide.plotting import figure_of
from diffguide.plotting.fit import plot_profiles

meas = read_measurements("../data/majda2012_measurements.csv")
print(len(meas.readings), "readings merged into", meas.n, "rows;",
      "points", dict(zip(meas.point_names, (np.asarray(meas.points_xy) * 1e3).tolist())))

# %% [markdown]
# ## The fit
#
# Unknowns: four cubic B-spline profiles over the rail length the balls visit (knots every 48 mm,
# the carriage's loaded length). Levenberg–Marquardt through the elastic model; a curvature
# penalty weighted by the marginal likelihood; each instrument's zero is a nuisance parameter.
# The classical alternative — a rigid-table inversion — runs on the same data.
#
# The fit is `diffguide fit`'s job, called as a library function: `diffguide.jobs.fit_job` takes
# the command's options as typed settings (`FitSettings`, the options by their names) and returns
# the fits, the report and the text of every output file; `res.write(out)` writes the command's
# output folder, byte for byte what
# `diffguide fit --measurements ../data/majda2012_measurements.csv --structure fixed --rigid
# --truth ../data/majda2012_truth.csv --no-plots --out OUT` writes (timing fields aside). Here the
# table's thickness and the preload are held at the machine's values (`structure="fixed"`; the
# command's default estimates them with the rails), and the notebook draws its own figures.

# %%
import tempfile
from diffguide.jobs import FitSettings, fit_job

settings = FitSettings(measurements=("../data/majda2012_measurements.csv",), structure="fixed",
                       rigid=True, truth="../data/majda2012_truth.csv", no_plots=True)
res = fit_job(settings)
out = tempfile.mkdtemp(prefix="diffguide-fit-")
print("wrote", ", ".join(res.write(out)))
fit, rigid = res.fits[""], res.fits["_rigid"]
for name, f in (("elastic", fit), ("rigid table", rigid)):
    print(f"{name:12s} chi2/dof = {f.chi2_dof:.2f}, {f.edf:.1f} effective parameters, converged {f.converged}")

# %% [markdown]
# The elastic model explains the data to the noise (χ²/dof ≈ 1); the rigid-table model cannot —
# it has no way to make pitch and roll differ between the corners.
#
# ## The profiles, with ±2σ bands, against the truth
#
# The truth is shown after removing what relative measurements cannot see (each profile's
# offset, and the two rails' common slope in each plane): the same gauge the fit reports in.

# %%
import csv
s = np.linspace(fit.basis.start, fit.basis.end, 300)
rows = [r for r in csv.DictReader(l for l in open("../data/majda2012_truth.csv") if not l.startswith("#"))]
truth = np.zeros((2, 2, s.size))
for r in (1, 2):
    a = np.array(sorted((float(q["s_mm"]), float(q["vertical_um"]), float(q["horizontal_um"]))
                        for q in rows if int(q["rail"]) == r))
    truth[r - 1, 0] = np.interp(s * 1e3, a[:, 0], a[:, 1]) * 1e-6
    truth[r - 1, 1] = np.interp(s * 1e3, a[:, 0], a[:, 2]) * 1e-6
truth = fit.basis.gauge_fix(s, truth.reshape(4, -1), fit.fix_slope).reshape(2, 2, -1)
profiles = {"elastic": fit.profiles(s), "rigid table": rigid.profiles(s)}
fig = figure_of(plot_profiles(s, profiles, truth=truth))
for name, (val, sig) in profiles.items():
    err = val - truth
    print(f"{name:12s} RMS error {np.sqrt(np.mean(err**2)) * 1e6:.3f} µm "
          f"(truth RMS {np.sqrt(np.mean(truth**2)) * 1e6:.2f} µm), "
          f"truth inside ±2σ at {np.mean(np.abs(err) <= 2 * sig) * 100:.0f} % of points")

# %% [markdown]
# ## What the data determine — and what they cannot
#
# The identifiability report (the fit job's, `report.json`'s `identifiability`) says how many directions of the 98 unknowns the data determine
# (the rest is the smoothness prior's), which gauge modes were fixed, and which wavelengths of the
# rails' mean and difference the measurement leaves undetermined. A rigid table is blind to some
# wavelengths outright: a carriage averages a sinusoid of wavelength n·p/m to zero, and two
# carriages l = 320 mm apart cannot see pitch/yaw at l/k or roll differences at 2l/(2k+1).

# %%
rep = res.report["identifiability"]
reg = rep["regularisation"]
print(f"{reg['unknowns']} unknowns: {reg['data_determined_directions']} determined by the data, "
      f"{reg['prior_determined_directions']} by the smoothness prior ({reg['criterion']}, "
      f"{reg['effective_parameters']:.1f} effective parameters)")
print("gauge fixed:", "; ".join(rep["gauge"]["fixed_modes"]))
for combo in rep["wavelengths"]:
    bad = [w["wavelength_mm"] for w in combo["transfer"] if w["transfer"] < rep["threshold"]]
    print(f"{combo['combination']:40s} undetermined {min(bad):.0f}–{max(bad):.0f} mm" if bad
          else f"{combo['combination']:40s} all wavelengths determined")
print("rigid-table blind wavelengths (mm): carriage averaging",
      rep["rigid_table_blind_wavelengths_mm"]["carriage_averaging_mm"],
      "; pitch/yaw", [round(v) for v in rep["rigid_table_blind_wavelengths_mm"]["pitch_yaw_mean_mm"][:4]])
sv = np.asarray(rep["singular_values"]["whitened_gauge_fixed"])
fig, ax = plt.subplots(figsize=(6, 3))
ax.semilogy(sv, ".")
ax.set_xlabel("index"); ax.set_ylabel("singular value (whitened)"); ax.grid(alpha=0.3)
ax.set_title("singular values of the gauge-fixed, noise-whitened Jacobian")
