"""diffguide: a differentiable model of linear guideways under an elastic machine-tool table.

Rail straightness errors -> rolling-element approaches -> carriage motion -> table deformation ->
joint kinematic errors at points on the table (ISO 230-1), and back. SI units inside.

The layers, in data-flow order (each a subpackage; everything public is re-exported here):
:mod:`.contact` (contact laws) -> :mod:`.guideway` (rails, carriages) -> :mod:`.fe` (the table)
-> :mod:`.machine` (equilibrium, joint errors) -> :mod:`.inverse` (identification) ->
:mod:`.planning` (measurement planning);
:mod:`.studies` (Monte Carlo, sensitivity, compensation) use them; :mod:`.io`, :mod:`.plotting`
and :mod:`.cli` are the edge. ``presets`` names the built-in machines and parts.

The library never changes JAX's configuration on import: call :func:`enable_x64` first.
"""

from importlib import import_module as _import_module

from ._core.version import __version__ as __version__

#: the public API: name -> the module that defines it, imported on first use (so that
#: ``import diffguide`` and ``diffguide --help`` do not import JAX)
_LAZY = {
    "enable_x64": "._core.precision",
    "require_x64": "._core.precision",
    "Caches": "._core.caches",
    "AbstractContactLaw": ".contact",
    "HertzBall": ".contact",
    "PalmgrenRoller": ".contact",
    "PowerLaw": ".contact",
    "RivinBall": ".contact",
    "AbstractRailProfile": ".guideway",
    "BumpRail": ".guideway",
    "Carriage": ".guideway",
    "CarriageSpec": ".guideway",
    "carriage_from_spec": ".guideway",
    "CarriageSolution": ".guideway",
    "CatalogueBlock": ".guideway",
    "calibrate_block": ".guideway",
    "catalogue_block": ".guideway",
    "datasheet_block": ".guideway",
    "known_blocks": ".guideway",
    "radial_rigidity": ".guideway",
    "PaperPolynomialRail": ".guideway",
    "SinusoidalRail": ".guideway",
    "SplineRail": ".guideway",
    "StraightRail": ".guideway",
    "four_row_carriage": ".guideway",
    "majda2012_carriage": ".guideway",
    "roller25_carriage": ".guideway",
    "solve_carriage": ".guideway",
    "static_characteristics": ".guideway",
    "fit_rails": ".inverse",
    "identifiability": ".inverse",
    "MachineFamily": ".inverse",
    "Prior": ".inverse",
    "StructurePriors": ".inverse",
    "plan": ".planning",
    "default_config": ".io",
    "load_config": ".io",
    "read_rails_csv": ".io",
    "spec_from_config": ".io",
    "config_from_spec": ".io",
    "config_machine": ".jobs.machine",
    "Material": ".fe",
    "TableSpec": ".fe",
    "GuidewaySpec": ".machine",
    "MachineSpec": ".machine",
    "ScrewSpec": ".machine",
    "table_from_spec": ".machine",
    "ERROR_NAMES": ".machine",
    "JointErrors": ".machine",
    "Machine": ".machine",
    "MachineState": ".machine",
    "build_machine": ".machine",
    "build_imported_machine": ".machine",
    "machine_from_table": ".machine",
    "equilibrium": ".machine",
    "error_field": ".machine",
    "joint_errors": ".machine",
    "majda2012_machine": ".machine",
    "paper_variant": ".machine",
    "CrossSpec": ".machine",
    "CrossMachine": ".machine",
    "CrossErrors": ".machine",
    "build_cross": ".machine",
    "cross_equilibrium": ".machine",
    "cross_errors": ".machine",
    "majda2012_cross_spec": ".machine",
    "load_cross_config": ".io",
    "read_measurements": ".io.measurements",
    "GaussianRailModel": ".studies",
    "MonteCarloResult": ".studies",
    "MountingTolerance": ".studies",
    "RailBatch": ".studies",
    "ToleranceResult": ".studies",
    "DesignResult": ".studies",
    "design": ".studies",
    "allocate_grade": ".studies",
    "batched_sweep": ".studies",
    "compensation_table": ".studies",
    "influence_map": ".studies",
    "location_warnings": ".studies",
    "roll_spread": ".studies",
    "sample_rails": ".studies",
}

__all__ = list(_LAZY)
#: the subpackages and modules, imported on first attribute access (``diffguide.presets``)
_SUBMODULES = ("cli", "contact", "fe", "guideway", "inverse", "io", "jobs", "machine", "planning",
               "plotting", "presets", "studies")


def __getattr__(name: str):
    """The public API (:data:`_LAZY`) and the subpackages (:data:`_SUBMODULES`), imported on
    first use."""
    if name in _LAZY:
        value = getattr(_import_module(_LAZY[name], __name__), name)
        globals()[name] = value
        return value
    if name in _SUBMODULES:
        return _import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY) | set(_SUBMODULES))
