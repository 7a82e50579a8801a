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
# # Design with gradients: a table whose corners roll together, at the same mass
#
# Notebook 4 asked how straight the rails of the `majda2012` machine must be for its corners to
# roll together. Here we turn the question round: **for the same table mass, where should the
# carriages go and how thick should the plate be**, so that random rails of a given grade spread
# the corners' roll least — and what rail grade does the re-designed machine then need?
#
# - *Objective*: the mean over random rails (σ = 1 µm RMS, ℓ = 200 mm, both rails and planes) of
#   the largest roll difference between two corners over the stroke, `max_x |EAX_i − EAX_j|`.
# - *Variables*: the plate thickness (30–80 mm) and the carriage spacing along each rail (within
#   the range where the table's mesh keeps its topology: the carriages' footprint lines move with
#   them, and may not pass another grid line).
# - *Constraint*: the plate's mass at most the original's, 180 kg.
#
# `diffguide.studies.design.design` draws the rails once and keeps them (common random numbers: the
# objective is then a smooth, deterministic function of the design), differentiates it exactly by
# forward-mode AD through the table's condensation and every equilibrium, and hands value and
# gradient to SciPy's SLSQP. A coarse 100 mm mesh (10 × 5) keeps the notebook quick and lets the
# carriage spacing range over 262–338 mm (the original: 320 mm).

# %%
import jax
jax.config.update("jax_enable_x64", True)  # micrometres on metre-scale geometry need float64

import time
import numpy as np
import matplotlib.pyplot as plt
from diffguide.machine.build import build_machine, with_overrides
from diffguide.machine.paper import majda2012_spec
from diffguide.plotting.design import plot_design_convergence
from diffguide.studies.design import design
from diffguide.studies.design_space import carriage_spacing_range, parse_constraint, table_mass
from diffguide.studies.tolerance import allocate_grade
# %matplotlib inline
plt.rcParams["figure.dpi"] = 110
t_start = time.perf_counter()

spec = with_overrides(majda2012_spec(), nx=10, ny=5)
positions = np.linspace(-0.35, 0.35, 15)       # the 700 mm stroke (m)
s_lo, s_hi = carriage_spacing_range(spec)
print(f"table mass {float(table_mass(spec)):.0f} kg; carriage spacing range "
      f"{s_lo * 1e3:.0f} .. {s_hi * 1e3:.0f} mm on this mesh")

# %% [markdown]
# ## The optimisation
#
# 48 random rail pairs per evaluation; each evaluation is one build of the table with its two
# derivatives and 48 sweeps of 15 positions with theirs. The first evaluation compiles.

# %%
res = design(spec, positions, variables=("thickness", "carriage_spacing"),
             bounds=[(0.03, 0.08), (s_lo, s_hi)], objective="roll_difference:mean",
             constraints=[parse_constraint("mass<=180")], rail_rms=1e-6,
             correlation_length=0.2, n_samples=48, check_samples=48, seed=0, progress=print)
for name, a, b, g in zip(res.variables, res.start, res.optimum, res.sensitivities):
    print(f"{name}: {a * 1e3:.1f} -> {b * 1e3:.1f} mm, d objective/d {name} at the optimum "
          f"{g * 1e3:+.3f} µrad/mm")
print("active:", [c[0] for c in res.constraints if c[2]], res.active_bounds)
fig = plot_design_convergence(res, "majda2012, mass <= 180 kg")


# %% [markdown]
# The plate keeps all the mass it may (the mass constraint is active: thickness stays at 50 mm)
# and the carriages move **closer together**, to the edge of the range this mesh allows — the
# gradient there still points further. Closer carriages sample each rail over a shorter stretch,
# over which two random rails of 200 mm correlation length differ less; that the twist this
# imposes on the table falls faster than the corners' overhang grows is what this model says for
# this machine, not a general rule.
#
# ## Is the improvement real? Fresh rails
#
# The optimum was found on 48 particular rails. `design` re-evaluates the start and the optimum on
# 48 *fresh* rails (another seed) and the difference on those same rails with a paired 95 %
# interval; it counts only if that interval lies above zero.

# %%
def show(label, e):
    print(f"{label:28s} {e.value * 1e6:6.2f} µrad  (95 % interval {e.interval[0] * 1e6:.2f} .. "
          f"{e.interval[1] * 1e6:.2f})")

show("original, fresh rails", res.fresh_before)
show("re-designed, fresh rails", res.fresh_after)
show("improvement (paired)", res.improvement)
print("improved beyond its interval:", res.improved)

# %% [markdown]
# ## The rail grade each machine needs
#
# The tolerance question of notebook 4 for both machines: the loosest rail RMS (ℓ = 200 mm) for
# which the corner roll difference stays within 5 µrad for 95 % of machines
# (`diffguide.studies.tolerance.allocate_grade`: a root-find on the Monte Carlo quantile, with its
# order-statistic interval).

# %%
machines = {"original": build_machine(spec),
            "re-designed": build_machine(spec, thickness=res.optimum[0],
                                         carriage_spacing=res.optimum[1])}
grades = {}
for name, m in machines.items():
    g = allocate_grade(m, positions, measure="roll_difference", limit=5e-6, probability=0.95,
                       correlation_length=0.2, n_samples=80, check_samples=0, seed=2)
    grades[name] = g
    print(f"{name:12s} rail grade {g.grade * 1e6:.3f} µm RMS (95 % interval "
          f"{g.interval[0] * 1e6:.3f} .. {g.interval[1] * 1e6:.3f})")
fig, ax = plt.subplots(figsize=(5, 3.2), constrained_layout=True)
names = list(grades)
vals = [grades[n].grade * 1e6 for n in names]
err = np.array([[grades[n].grade - grades[n].interval[0], grades[n].interval[1] - grades[n].grade]
                for n in names]).T * 1e6
ax.bar(names, vals, yerr=err, capsize=4, color=["C0", "C2"])
ax.set_ylabel("rail grade for 5 µrad at 95 % (µm RMS)")
ax.grid(alpha=0.3, axis="y")
print(f"notebook ran in {time.perf_counter() - t_start:.0f} s")

# %% [markdown]
# ## Conclusions (for this model and this mesh)
#
# - At the same mass, the corner roll difference of `majda2012` falls when the carriages move
#   closer together; the plate takes all the mass the constraint allows. The optimum sits at the
#   edge of the spacing range this mesh allows — a wider range needs the carriage positions to be
#   traceable beyond one mesh's topology.
# - The improvement holds on fresh rails beyond its paired 95 % interval. The rail grade for
#   5 µrad at 95 % loosens by about as much (the response is linear in σ), but with 80 samples
#   the two grades' intervals overlap: the grade gain is within their sampling error, the paired
#   improvement is not.
# - Each evaluation carries its exact gradient: a few evaluations replace a grid of tens
#   (`bench/bench_design.py` compares the two on this problem).
