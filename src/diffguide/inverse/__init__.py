"""Identification: rail straightness profiles from measured joint kinematic errors (SPEC §2.5).

:mod:`.basis` (unknowns, gauge, penalty) → :mod:`.fit` (regularised LM through the machine
model, GCV, posterior covariance) → :mod:`.identify` (what the data determine).
"""

from .basis import PROFILES as PROFILES
from .basis import RailBasis as RailBasis
from .basis import profile_label as profile_label
from .fit import RailFit as RailFit
from .fit import fit_rails as fit_rails
from .fit import visited_range as visited_range
from .identify import blind_wavelengths as blind_wavelengths
from .identify import identifiability as identifiability
