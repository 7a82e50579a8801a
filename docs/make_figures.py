"""Regenerate the README figure: the paper's variant 2, elastic vs rigid table.

Run: ``python docs/make_figures.py`` (writes docs/variant2.png).
"""

from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from diffguide.io import atomic_savefig  # noqa: E402
from diffguide.machine.kinematics import joint_errors  # noqa: E402
from diffguide.machine.majda2012 import majda2012_machine, paper_variant  # noqa: E402
from diffguide.plotting import figure_of  # noqa: E402
from diffguide.plotting.errors import plot_joint_errors  # noqa: E402

machine = majda2012_machine()
x = np.linspace(-0.35, 0.35, 71)
elastic = joint_errors(machine, paper_variant(2), x).user_units()
rigid = joint_errors(machine.with_rigid_table(), paper_variant(2), x).user_units()
title = "majda2012, variant 2 (rail 1 horizontal): elastic table (solid) vs rigid (dashed)"
fig = figure_of(plot_joint_errors(x * 1e3, elastic, machine.point_names, title, compare=rigid))
atomic_savefig(fig, Path(__file__).parent / "variant2.png", dpi=80)
