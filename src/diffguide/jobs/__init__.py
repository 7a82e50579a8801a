"""One entry point per command: typed settings in, a result out that writes the command's
files; the command line, notebooks and tests call the same functions.

- :func:`fit_job` (:class:`FitSettings` -> :class:`FitResult`): ``diffguide fit``.
- :func:`plan_job` (:class:`PlanSettings` -> :class:`PlanResult`): ``diffguide plan``.
- :func:`design_job` (:class:`DesignSettings` -> :class:`DesignJobResult`): ``diffguide
  design``.

Nothing heavy (JAX, matplotlib) is imported until a job runs.
"""

from .design import DesignJobResult as DesignJobResult
from .design import DesignSettings as DesignSettings
from .design import design_job as design_job
from .fit import FitResult as FitResult
from .fit import FitSettings as FitSettings
from .fit import fit_job as fit_job
from .plan import PlanResult as PlanResult
from .plan import PlanSettings as PlanSettings
from .plan import plan_job as plan_job

__all__ = [
    "DesignJobResult",
    "DesignSettings",
    "FitResult",
    "FitSettings",
    "PlanResult",
    "PlanSettings",
    "design_job",
    "fit_job",
    "plan_job",
]
