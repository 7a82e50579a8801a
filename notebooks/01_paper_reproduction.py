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
# # The paper reproduced: joint kinematic errors depend on where you measure them
#
# Majda (Precision Engineering 36 (2012) 369–378) simulated a machining-centre table on four
# carriages whose rails have a geometric error, and showed that pitch and especially roll
# *measured at different places on the same table* differ in size and even in sign — so a roll
# curve measured at one spot is not the roll of the workpiece elsewhere. This notebook reproduces
# the paper's three variants (its Figs. 7–9) with diffguide's `majda2012` preset and compares the
# elastic table with an infinitely stiff one.
#
# Rail error (the paper's eq. 4): `i(s) = (Δ/2)·(s + s²)`, `s` in m, `Δ = 0.05 mm`, on
# 1. rail 1 vertical; 2. rail 1 horizontal; 3. rail 1 vertical and rail 2 horizontal.

# %%
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

# %%
results = {}
for v in (1, 2, 3):
    elastic = joint_errors(machine, paper_variant(v), positions)
    stiff = joint_errors(rigid, paper_variant(v), positions)
    assert bool(elastic.converged.all()) and bool(stiff.converged.all())
    results[v] = (elastic.user_units(), stiff.user_units())   # µm and µrad

# %% [markdown]
# ## Variant 1 — one rail with a vertical error
#
# Solid lines: elastic table; dashed: rigid table. EZX dominates the translations; roll (EAX) is
# the largest angular error and its size depends on the corner: the corners at +X (P1, P4) see
# about twice the roll of those at −X (P2, P3), while a rigid table gives every point the same
# roll. The elastic table also yaws a little, which a rigid one cannot.

# %%
fig = figure_of(plot_joint_errors(positions * 1e3, results[1][0], machine.point_names,
                        "variant 1: rail 1 vertical", compare=results[1][1]))

# %% [markdown]
# ## Variant 2 — one rail with a horizontal error
#
# EYX dominates. Roll at the centre P5 is close to zero while it is large at the corners, and it
# has opposite signs at P1 and P4: a rigid table has no roll at all here (dashed lines on zero).
# Yaw is nearly the same at all points — the table is stiff in its plane.

# %%
fig = figure_of(plot_joint_errors(positions * 1e3, results[2][0], machine.point_names,
                        "variant 2: rail 1 horizontal", compare=results[2][1]))

# %% [markdown]
# ## Variant 3 — rail 1 vertical, rail 2 horizontal

# %%
fig = figure_of(plot_joint_errors(positions * 1e3, results[3][0], machine.point_names,
                        "variant 3: rail 1 vertical, rail 2 horizontal", compare=results[3][1]))

# %% [markdown]
# ## The ranges side by side
#
# Peak-to-peak range of each error over the stroke, at each point (µm for EXX/EYX/EZX, µrad for
# EAX/EBX/ECX), elastic table vs rigid table.

# %%
for v in (1, 2, 3):
    el, rg = (np.ptp(r, axis=0) for r in results[v])
    print(f"variant {v}        " + "".join(f"{n:>14s}" for n in ERROR_NAMES))
    for j, p in enumerate(machine.point_names):
        print(f"  {p} elastic/rigid" + "".join(f"{el[j, k]:7.2f}/{rg[j, k]:<6.2f}" for k in range(6)))

# %% [markdown]
# ## What location-dependent roll means for compensation
#
# Volumetric compensation treats the table as a rigid body: the roll measured with a level at one
# point is applied everywhere. Suppose the roll curve is measured at the corner P1 and used to
# compensate. The roll left uncompensated at the other points is the difference of the curves —
# and it becomes a straightness error of a tool point above the table (an Abbe arm of, say,
# 300 mm turns 1 µrad into 0.3 µm).

# %%
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
