"""diffguide: a differentiable model of linear guideways under an elastic machine-tool table.

Rail straightness errors -> rolling-element approaches -> carriage motion -> table deformation ->
joint kinematic errors at points on the table (ISO 230-1), and back. SI units inside.

The library never changes JAX's configuration on import: call :func:`enable_x64` first.
"""

from ._precision import enable_x64 as enable_x64
from ._precision import require_x64 as require_x64
from .build import build_machine as build_machine
from .carriage_solve import (
    CarriageSolution as CarriageSolution,
)
from .carriage_solve import (
    solve_carriage as solve_carriage,
)
from .carriage_solve import (
    static_characteristics as static_characteristics,
)
from .compensation import compensation_table as compensation_table
from .config import default_config as default_config
from .config import load_config as load_config
from .contact import (
    HertzBall as HertzBall,
)
from .contact import (
    PalmgrenRoller as PalmgrenRoller,
)
from .contact import (
    PowerLaw as PowerLaw,
)
from .contact import (
    RivinBall as RivinBall,
)
from .guideway import (
    Carriage as Carriage,
)
from .guideway import (
    four_row_carriage as four_row_carriage,
)
from .guideway import (
    majda2012_carriage as majda2012_carriage,
)
from .guideway import (
    roller25_carriage as roller25_carriage,
)
from .inverse import fit_rails as fit_rails
from .inverse import identifiability as identifiability
from .kinematics import (
    ERROR_NAMES as ERROR_NAMES,
)
from .kinematics import (
    JointErrors as JointErrors,
)
from .kinematics import (
    joint_errors as joint_errors,
)
from .machine import Machine as Machine
from .machine import MachineState as MachineState
from .machine import equilibrium as equilibrium
from .majda2012 import majda2012_machine as majda2012_machine
from .majda2012 import paper_variant as paper_variant
from .measurements import read_measurements as read_measurements
from .rails import (
    BumpRail as BumpRail,
)
from .rails import (
    PaperPolynomialRail as PaperPolynomialRail,
)
from .rails import (
    SinusoidalRail as SinusoidalRail,
)
from .rails import (
    SplineRail as SplineRail,
)
from .rails import (
    StraightRail as StraightRail,
)

__version__ = "0.1.0"
