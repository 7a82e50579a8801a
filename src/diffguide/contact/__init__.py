"""Contact layer: rolling-element contact laws (Hertz ball, Rivin form, Palmgren roller), the
exact elliptical Hertz solution, and the C¹ compression-only smoothing."""

from .laws import AbstractContactLaw as AbstractContactLaw
from .laws import HertzBall as HertzBall
from .laws import PalmgrenRoller as PalmgrenRoller
from .laws import PowerLaw as PowerLaw
from .laws import RivinBall as RivinBall
