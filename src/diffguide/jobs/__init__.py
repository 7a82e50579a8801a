"""One entry point per command: typed settings in, a result out that writes the command's
files; the command line, notebooks and tests call the same functions.

- :func:`fit_job` (:class:`FitSettings` -> :class:`FitResult`): ``diffguide fit``.

Nothing heavy (JAX, matplotlib) is imported until a job runs.
"""

from .fit import FitResult as FitResult
from .fit import FitSettings as FitSettings
from .fit import fit_job as fit_job

__all__ = ["FitResult", "FitSettings", "fit_job"]
