"""diffguide: a differentiable model of linear guideways under an elastic machine-tool table.

Rail straightness errors -> rolling-element approaches -> carriage motion -> table deformation ->
joint kinematic errors at points on the table (ISO 230-1), and back. SI units inside.

The library never changes JAX's configuration on import: call :func:`enable_x64` first.
"""

from ._precision import enable_x64 as enable_x64, require_x64 as require_x64
from .build import build_machine as build_machine
from .carriage_solve import (
    CarriageSolution as CarriageSolution,
    solve_carriage as solve_carriage,
    static_characteristics as static_characteristics,
)
from .compensation import compensation_table as compensation_table
from .config import default_config as default_config, load_config as load_config
from .contact import (
    HertzBall as HertzBall,
    PalmgrenRoller as PalmgrenRoller,
    PowerLaw as PowerLaw,
    RivinBall as RivinBall,
)
from .guideway import (
    Carriage as Carriage,
    four_row_carriage as four_row_carriage,
    majda2012_carriage as majda2012_carriage,
    roller25_carriage as roller25_carriage,
)
from .inverse import fit_rails as fit_rails, identifiability as identifiability
from .kinematics import (
    ERROR_NAMES as ERROR_NAMES,
    JointErrors as JointErrors,
    joint_errors as joint_errors,
)
from .machine import Machine as Machine, MachineState as MachineState, equilibrium as equilibrium
from .majda2012 import majda2012_machine as majda2012_machine, paper_variant as paper_variant
from .measurements import read_measurements as read_measurements
from .rails import (
    BumpRail as BumpRail,
    PaperPolynomialRail as PaperPolynomialRail,
    SinusoidalRail as SinusoidalRail,
    SplineRail as SplineRail,
    StraightRail as StraightRail,
)

__version__ = "0.1.0"
