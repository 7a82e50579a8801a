"""Machine layer: the condensed table on its carriages, rails, screw and gravity; equilibrium at
every table position; joint kinematic errors at points on the table; the ``majda2012`` machine;
the cross table (table on a saddle on the bed) and its errors relative to the bed."""

from .._core.result import RESULTS as RESULTS
from .build import build_machine as build_machine
from .build import layout_ranges as layout_ranges
from .build import machine_from_table as machine_from_table
from .build import table_from_spec as table_from_spec
from .build import with_overrides as with_overrides
from .cross import CrossMachine as CrossMachine
from .cross import build_cross as build_cross
from .cross_equilibrium import CrossState as CrossState
from .cross_equilibrium import cross_equilibrium as cross_equilibrium
from .cross_spec import CrossSpec as CrossSpec
from .equilibrium import DOF_SCALE as DOF_SCALE
from .equilibrium import Machine as Machine
from .equilibrium import MachineState as MachineState
from .equilibrium import equilibrium as equilibrium
from .equilibrium import node_motion as node_motion
from .equilibrium import point_motion as point_motion
from .equilibrium import rigid_body_map as rigid_body_map
from .imported import ImportedTable as ImportedTable
from .imported import build_imported_machine as build_imported_machine
from .imported import imported_table as imported_table
from .imported import interface_names as interface_names
from .imported import machine_from_imported as machine_from_imported
from .imported import machine_of_source as machine_of_source
from .kinematics import ERROR_NAMES as ERROR_NAMES
from .kinematics import JointErrors as JointErrors
from .kinematics import error_field as error_field
from .kinematics import joint_errors as joint_errors
from .majda2012 import majda2012_machine as majda2012_machine
from .majda2012 import majda2012_spec as majda2012_spec
from .majda2012 import majda2012_table as majda2012_table
from .majda2012 import paper_variant as paper_variant
from .paper_cross import majda2012_cross_spec as majda2012_cross_spec
from .morph import LAYOUT_VARIABLES as LAYOUT_VARIABLES
from .morph import GeometryRangeError as GeometryRangeError
from .morph import apply_layout as apply_layout
from .spec import GuidewaySpec as GuidewaySpec
from .spec import MachineSpec as MachineSpec
from .spec import ScrewSpec as ScrewSpec
from .volumetric import TABLE_ERROR_NAMES as TABLE_ERROR_NAMES
from .volumetric import CrossErrors as CrossErrors
from .volumetric import cross_error_field as cross_error_field
from .volumetric import cross_errors as cross_errors
