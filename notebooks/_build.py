"""Write (and execute, saving outputs) the notebooks from their cell lists.

Usage: ``python notebooks/_build.py [NAME ...]`` — the notebooks are plain JSON afterwards and
are executed again by ``tests/test_notebooks.py`` so they cannot rot.
"""

import sys
from pathlib import Path

import nbformat
from nbclient import NotebookClient

HERE = Path(__file__).parent


def md(text):
    return nbformat.v4.new_markdown_cell(text.strip())


def code(text):
    return nbformat.v4.new_code_cell(text.strip())


NOTEBOOKS = {}

NOTEBOOKS["01_paper_reproduction"] = [
    md("""
# The paper reproduced: joint kinematic errors depend on where you measure them

Majda (Precision Engineering 36 (2012) 369–378) simulated a machining-centre table on four
carriages whose rails have a geometric error, and showed that pitch and especially roll
*measured at different places on the same table* differ in size and even in sign — so a roll
curve measured at one spot is not the roll of the workpiece elsewhere. This notebook reproduces
the paper's three variants (its Figs. 7–9) with diffguide's `majda2012` preset and compares the
elastic table with an infinitely stiff one.

Rail error (the paper's eq. 4): `i(s) = (Δ/2)·(s + s²)`, `s` in m, `Δ = 0.05 mm`, on
1. rail 1 vertical; 2. rail 1 horizontal; 3. rail 1 vertical and rail 2 horizontal.
"""),
    code("""
import jax
jax.config.update("jax_enable_x64", True)  # micrometres on metre-scale geometry need float64

import numpy as np
import matplotlib.pyplot as plt
plt.rcParams["figure.dpi"] = 110  # legible legends (60 dpi was not)
from diffguide.machine.majda2012 import majda2012_machine, paper_variant
from diffguide.machine.kinematics import joint_errors, ERROR_NAMES
from diffguide.plotting.errors import plot_joint_errors
from diffguide.plotting import figure_of

machine = majda2012_machine()            # 1000 x 500 x 50 mm cast-iron plate, 4 size-25 ball blocks
rigid = machine.with_rigid_table()       # the same machine with an infinitely stiff table
positions = np.linspace(-0.35, 0.35, 71)  # the 700 mm stroke (m)
print(machine.point_names, np.asarray(machine.points_xy) * 1e3, "mm")
"""),
    code("""
results = {}
for v in (1, 2, 3):
    elastic = joint_errors(machine, paper_variant(v), positions)
    stiff = joint_errors(rigid, paper_variant(v), positions)
    assert bool(elastic.converged.all()) and bool(stiff.converged.all())
    results[v] = (elastic.user_units(), stiff.user_units())   # µm and µrad
"""),
    md("""
## Variant 1 — one rail with a vertical error

Solid lines: elastic table; dashed: rigid table. EZX dominates the translations; roll (EAX) is
the largest angular error and its size depends on the corner: the corners at +X (P1, P4) see
about twice the roll of those at −X (P2, P3), while a rigid table gives every point the same
roll. The elastic table also yaws a little, which a rigid one cannot.
"""),
    code("""
fig = figure_of(plot_joint_errors(positions * 1e3, results[1][0], machine.point_names,
                        "variant 1: rail 1 vertical", compare=results[1][1]))
"""),
    md("""
## Variant 2 — one rail with a horizontal error

EYX dominates. Roll at the centre P5 is close to zero while it is large at the corners, and it
has opposite signs at P1 and P4: a rigid table has no roll at all here (dashed lines on zero).
Yaw is nearly the same at all points — the table is stiff in its plane.
"""),
    code("""
fig = figure_of(plot_joint_errors(positions * 1e3, results[2][0], machine.point_names,
                        "variant 2: rail 1 horizontal", compare=results[2][1]))
"""),
    md("## Variant 3 — rail 1 vertical, rail 2 horizontal"),
    code("""
fig = figure_of(plot_joint_errors(positions * 1e3, results[3][0], machine.point_names,
                        "variant 3: rail 1 vertical, rail 2 horizontal", compare=results[3][1]))
"""),
    md("""
## The ranges side by side

Peak-to-peak range of each error over the stroke, at each point (µm for EXX/EYX/EZX, µrad for
EAX/EBX/ECX), elastic table vs rigid table.
"""),
    code("""
for v in (1, 2, 3):
    el, rg = (np.ptp(r, axis=0) for r in results[v])
    print(f"variant {v}        " + "".join(f"{n:>14s}" for n in ERROR_NAMES))
    for j, p in enumerate(machine.point_names):
        print(f"  {p} elastic/rigid" + "".join(f"{el[j, k]:7.2f}/{rg[j, k]:<6.2f}" for k in range(6)))
"""),
    md("""
## What location-dependent roll means for compensation

Volumetric compensation treats the table as a rigid body: the roll measured with a level at one
point is applied everywhere. Suppose the roll curve is measured at the corner P1 and used to
compensate. The roll left uncompensated at the other points is the difference of the curves —
and it becomes a straightness error of a tool point above the table (an Abbe arm of, say,
300 mm turns 1 µrad into 0.3 µm).
"""),
    code("""
fig, axes = plt.subplots(1, 3, figsize=(13, 3.6), sharey=True, constrained_layout=True)
for ax, v in zip(axes, (1, 2, 3)):
    roll = results[v][0][:, :, 3]
    for j, p in enumerate(machine.point_names[1:], start=1):
        ax.plot(positions * 1e3, roll[:, j] - roll[:, 0], label=f"{p} − P1")
    ax.set_title(f"variant {v}: roll left after compensating with P1")
    ax.set_xlabel("table position (mm)")
    ax.grid(alpha=0.3)
axes[0].set_ylabel("µrad")
axes[0].legend()
residual = {v: np.abs(results[v][0][:, 1:, 3] - results[v][0][:, :1, 3]).max() for v in (1, 2, 3)}
print("largest roll left uncompensated (µrad):", {v: round(float(r), 1) for v, r in residual.items()})
"""),
]


NOTEBOOKS["02_fitting_rails"] = [
    md("""
# Fitting rail straightness to level and interferometer data

The product's main job: from pitch, roll and yaw curves measured at a few places on the table,
recover the straightness profiles of both rails — vertical and horizontal — with uncertainty,
through the elastic machine model. The bundled data set (`data/majda2012_measurements.csv`) is
synthetic but realistic: electronic levels at the four corners read pitch and roll, an angular
interferometer at the centre reads pitch and yaw, five bidirectional runs with 4 µm/m and 2 µm/m
noise. Its truth (`data/majda2012_truth.csv`) is a sum of sinusoids and a polynomial — not a
spline — simulated on a finer table mesh than the fit uses (`data/make_majda2012_measurements.py`).
"""),
    code("""
import jax
jax.config.update("jax_enable_x64", True)

import numpy as np
import matplotlib.pyplot as plt
plt.rcParams["figure.dpi"] = 110
from diffguide.machine.majda2012 import majda2012_machine
from diffguide.io.measurements import read_measurements
from diffguide.inverse import fit_rails, identifiability
from diffguide.plotting import figure_of
from diffguide.plotting.fit import plot_profiles

meas = read_measurements("../data/majda2012_measurements.csv")
print(len(meas.readings), "readings merged into", meas.n, "rows;",
      "points", dict(zip(meas.point_names, (np.asarray(meas.points_xy) * 1e3).tolist())))
"""),
    md("""
## The fit

Unknowns: four cubic B-spline profiles over the rail length the balls visit (knots every 48 mm,
the carriage's loaded length). Levenberg–Marquardt through the elastic model; a curvature
penalty weighted by generalised cross-validation; each instrument's zero is a nuisance
parameter. The classical alternative — a rigid-table inversion — runs on the same data.
"""),
    code("""
machine = majda2012_machine(points=dict(zip(meas.point_names, map(tuple, np.asarray(meas.points_xy)))))
fit = fit_rails(machine, meas)
rigid = fit_rails(machine.with_rigid_table(), meas, method="linear")
for name, f in (("elastic", fit), ("rigid table", rigid)):
    print(f"{name:12s} chi2/dof = {f.chi2_dof:.2f}, {f.edf:.1f} effective parameters, converged {f.converged}")
"""),
    md("""
The elastic model explains the data to the noise (χ²/dof ≈ 1); the rigid-table model cannot —
it has no way to make pitch and roll differ between the corners.

## The profiles, with ±2σ bands, against the truth

The truth is shown after removing what relative measurements cannot see (each profile's
offset, and the two rails' common slope in each plane): the same gauge the fit reports in.
"""),
    code("""
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
"""),
    md("""
## What the data determine — and what they cannot

The identifiability report says how many directions of the 98 unknowns the data determine
(the rest is the smoothness prior's), which gauge modes were fixed, and which wavelengths of the
rails' mean and difference the measurement leaves undetermined. A rigid table is blind to some
wavelengths outright: a carriage averages a sinusoid of wavelength n·p/m to zero, and two
carriages l = 320 mm apart cannot see pitch/yaw at l/k or roll differences at 2l/(2k+1).
"""),
    code("""
rep = identifiability(fit, machine)
reg = rep["regularisation"]
print(f"{reg['unknowns']} unknowns: {reg['data_determined_directions']} determined by the data, "
      f"{reg['prior_determined_directions']} by the smoothness prior (GCV, {reg['effective_parameters']:.1f} effective parameters)")
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
"""),
]


def build(name, execute=True):
    nb = nbformat.v4.new_notebook()
    nb.cells = NOTEBOOKS[name]
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    if execute:
        NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(HERE)}}).execute()
    nbformat.write(nb, HERE / f"{name}.ipynb")


if __name__ == "__main__":
    for name in sys.argv[1:] or NOTEBOOKS:
        build(name)
        print("wrote", name)
