"""Identification: rail straightness profiles from measured joint kinematic errors (SPEC §2.5).

:mod:`.basis` (unknowns, gauge, penalty) → :mod:`.fit` (regularised LM through the machine
model, GCV, posterior covariance) → :mod:`.identify` (what the data determine).
"""

from .basis import PROFILES as PROFILES, RailBasis as RailBasis, profile_label as profile_label
from .fit import RailFit as RailFit, fit_rails as fit_rails, visited_range as visited_range
from .identify import blind_wavelengths as blind_wavelengths, identifiability as identifiability
