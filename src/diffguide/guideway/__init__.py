"""Guideway layer: rail error profiles, a rigid carriage on its rail (rows of preloaded
elements), the paper's and a roller runner block, catalogue runner blocks calibrated to their
published rigidity, and one carriage's equilibrium and static characteristic."""

from .blocks import ball_block_25 as ball_block_25
from .blocks import majda2012_carriage as majda2012_carriage
from .blocks import roller25_carriage as roller25_carriage
from .blocks import roller_block_25 as roller_block_25
from .carriage import Carriage as Carriage
from .carriage import CarriageSpec as CarriageSpec
from .carriage import carriage_from_spec as carriage_from_spec
from .carriage import element_offsets as element_offsets
from .carriage import four_row_carriage as four_row_carriage
from .carriage import row_layout as row_layout
from .catalogue import CatalogueBlock as CatalogueBlock
from .catalogue import calibrate_block as calibrate_block
from .catalogue import catalogue_block as catalogue_block
from .catalogue import datasheet_block as datasheet_block
from .catalogue import known_blocks as known_blocks
from .catalogue import radial_rigidity as radial_rigidity
from .rails import AbstractRailProfile as AbstractRailProfile
from .rails import BumpRail as BumpRail
from .rails import PaperPolynomialRail as PaperPolynomialRail
from .rails import SinusoidalRail as SinusoidalRail
from .rails import SplineRail as SplineRail
from .rails import SteppedRail as SteppedRail
from .rails import StraightRail as StraightRail
from .solve import CarriageSolution as CarriageSolution
from .solve import solve_carriage as solve_carriage
from .solve import static_characteristics as static_characteristics
