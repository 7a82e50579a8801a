"""diffguide: a differentiable model of linear guideways under an elastic machine-tool table.

Rail straightness errors -> rolling-element approaches -> carriage motion -> table deformation ->
joint kinematic errors at points on the table (ISO 230-1), and back. SI units inside.
"""

from ._precision import enable_x64 as enable_x64, require_x64 as require_x64

__version__ = "0.1.0"
