"""Measurement planning: which instruments to place where on the table so that the data determine
the rails (and the table's structure) — before anything is measured.

:mod:`.instruments` (instrument kinds, what each reads, candidate sites) →
:mod:`.planner` (the linearised experiment over every candidate placement, built once) →
:mod:`.design` (the predicted posterior of a plan and the criteria that rank plans) →
:mod:`.greedy` (add placements one at a time) → :mod:`.plan` (the search as one call; its
docstring states the model). It sits on :mod:`diffguide.inverse`: the same forward model, rail
basis and gauge as the fit whose data it plans.
"""

from .design import CRITERIA as CRITERIA
from .design import N_S as N_S
from .design import Evaluation as Evaluation
from .greedy import Step as Step
from .instruments import DEFAULT_READING_SIGMA as DEFAULT_READING_SIGMA
from .instruments import KINDS as KINDS
from .instruments import Instrument as Instrument
from .instruments import Placement as Placement
from .instruments import grid_sites as grid_sites
from .plan import Plan as Plan
from .plan import plan as plan
from .planner import STRUCTURE_STEP as STRUCTURE_STEP
from .planner import Planner as Planner
from .planner import build_planner as build_planner
from .planner import expected_rms_lambda as expected_rms_lambda
from .planner import gauge_projector as gauge_projector

__all__ = [
    "CRITERIA",
    "DEFAULT_READING_SIGMA",
    "KINDS",
    "N_S",
    "STRUCTURE_STEP",
    "Evaluation",
    "Instrument",
    "Placement",
    "Plan",
    "Planner",
    "Step",
    "build_planner",
    "expected_rms_lambda",
    "gauge_projector",
    "grid_sites",
    "plan",
]
