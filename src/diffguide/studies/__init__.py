"""Studies built on the machine: Monte Carlo tolerance sweeps over random rails, sensitivity
(gradients, influence maps), CNC compensation tables, the fitted rails' straightness with its
uncertainty and verdict, the loosest rail grade for a stated error limit (tolerance
allocation), the design (thickness, carriage and rail spacing, preload, E) that minimises an
error statistic over random rails, or the fit's predicted σ for a measurement plan, within
bounds and constraints."""

from .compensation import compensation_table as compensation_table
from .compensation import location_warnings as location_warnings
from .design import DesignResult as DesignResult
from .design import design as design
from .design_plan import MeasurementPlan as MeasurementPlan
from .montecarlo import MonteCarloResult as MonteCarloResult
from .montecarlo import batched_sweep as batched_sweep
from .random_rails import GaussianRailModel as GaussianRailModel
from .random_rails import MountingTolerance as MountingTolerance
from .random_rails import RailBatch as RailBatch
from .random_rails import sample_rails as sample_rails
from .sensitivity import influence_map as influence_map
from .sensitivity import roll_spread as roll_spread
from .straightness import rail_straightness as rail_straightness
from .straightness import straightness as straightness
from .tolerance import ToleranceResult as ToleranceResult
from .tolerance import allocate_grade as allocate_grade
