"""Identification: rail straightness profiles from measured joint kinematic errors.

:mod:`.basis` (rail unknowns, gauge, penalty), :mod:`.structure` (table thickness and preload as
unknowns with priors), :mod:`.weight` (the smoothness weight: marginal likelihood or GCV) →
:mod:`.fit` (regularised LM through the machine model, joint posterior covariance) →
:mod:`.identify` (what the data determine).
"""

from .basis import PROFILES as PROFILES
from .basis import RailBasis as RailBasis
from .basis import profile_label as profile_label
from .fit import RailFit as RailFit
from .fit import fit_rails as fit_rails
from .fit import visited_range as visited_range
from .identify import blind_wavelengths as blind_wavelengths
from .identify import identifiability as identifiability
from .structure import MachineFamily as MachineFamily
from .structure import Prior as Prior
from .structure import StructurePriors as StructurePriors
from .weight import WeightChoice as WeightChoice
from .weight import choose_weight as choose_weight
