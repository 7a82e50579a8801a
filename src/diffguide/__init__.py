"""diffguide: a differentiable model of linear guideways under an elastic machine-tool table.

Rail straightness errors -> rolling-element approaches -> carriage motion -> table deformation ->
joint kinematic errors at points on the table (ISO 230-1), and back. SI units inside.

The layers, in data-flow order (each a subpackage; everything public is re-exported here):
:mod:`.contact` (contact laws) -> :mod:`.guideway` (rails, carriages) -> :mod:`.fe` (the table)
-> :mod:`.machine` (equilibrium, joint errors) -> :mod:`.inverse` (identification);
:mod:`.studies` (Monte Carlo, sensitivity, compensation) use them; :mod:`.io`, :mod:`.plotting`
and :mod:`.cli` are the edge. ``presets`` holds every value of the built-in machines.

The library never changes JAX's configuration on import: call :func:`enable_x64` first.
"""

from ._core import aliases as _aliases

_aliases.install()  # old module paths (diffguide 0.1), see diffguide._core.aliases

from ._core.precision import enable_x64 as enable_x64  # noqa: E402
from ._core.precision import require_x64 as require_x64  # noqa: E402
from .contact import AbstractContactLaw as AbstractContactLaw  # noqa: E402
from .contact import HertzBall as HertzBall  # noqa: E402
from .contact import PalmgrenRoller as PalmgrenRoller  # noqa: E402
from .contact import PowerLaw as PowerLaw  # noqa: E402
from .contact import RivinBall as RivinBall  # noqa: E402
from .guideway import AbstractRailProfile as AbstractRailProfile  # noqa: E402
from .guideway import BumpRail as BumpRail  # noqa: E402
from .guideway import Carriage as Carriage  # noqa: E402
from .guideway import CarriageSolution as CarriageSolution  # noqa: E402
from .guideway import PaperPolynomialRail as PaperPolynomialRail  # noqa: E402
from .guideway import SinusoidalRail as SinusoidalRail  # noqa: E402
from .guideway import SplineRail as SplineRail  # noqa: E402
from .guideway import StraightRail as StraightRail  # noqa: E402
from .guideway import four_row_carriage as four_row_carriage  # noqa: E402
from .guideway import majda2012_carriage as majda2012_carriage  # noqa: E402
from .guideway import roller25_carriage as roller25_carriage  # noqa: E402
from .guideway import solve_carriage as solve_carriage  # noqa: E402
from .guideway import static_characteristics as static_characteristics  # noqa: E402
from .inverse import fit_rails as fit_rails  # noqa: E402
from .inverse import identifiability as identifiability  # noqa: E402
from .io import default_config as default_config  # noqa: E402
from .io import load_config as load_config  # noqa: E402
from .io import read_rails_csv as read_rails_csv  # noqa: E402
from .machine import ERROR_NAMES as ERROR_NAMES  # noqa: E402
from .machine import JointErrors as JointErrors  # noqa: E402
from .machine import Machine as Machine  # noqa: E402
from .machine import MachineState as MachineState  # noqa: E402
from .machine import build_machine as build_machine  # noqa: E402
from .machine import equilibrium as equilibrium  # noqa: E402
from .machine import error_field as error_field  # noqa: E402
from .machine import joint_errors as joint_errors  # noqa: E402
from .machine import majda2012_machine as majda2012_machine  # noqa: E402
from .machine import paper_variant as paper_variant  # noqa: E402
from .io.measurements import read_measurements as read_measurements  # noqa: E402
from .studies import GaussianRailModel as GaussianRailModel  # noqa: E402
from .studies import MonteCarloResult as MonteCarloResult  # noqa: E402
from .studies import MountingTolerance as MountingTolerance  # noqa: E402
from .studies import RailBatch as RailBatch  # noqa: E402
from .studies import batched_sweep as batched_sweep  # noqa: E402
from .studies import compensation_table as compensation_table  # noqa: E402
from .studies import influence_map as influence_map  # noqa: E402
from .studies import location_warnings as location_warnings  # noqa: E402
from .studies import roll_spread as roll_spread  # noqa: E402
from .studies import sample_rails as sample_rails  # noqa: E402

__version__ = "0.1.0"

_aliases.forget()  # the package's own imports of old names leave no trace for users


def __getattr__(name: str):
    """``diffguide.kinematics`` etc. as attributes (old flat modules; deprecated)."""
    old = f"{__name__}.{name}"
    if old in _aliases.MOVED:
        import importlib

        _aliases.deprecated(old, stacklevel=2)
        return importlib.import_module(_aliases.MOVED[old])
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
