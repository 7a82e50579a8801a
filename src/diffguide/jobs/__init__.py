"""One entry point per command: typed settings in, a result out that writes the command's
files; the command line, notebooks and tests call the same functions.

- :func:`fit_job` (:class:`FitSettings` -> :class:`FitResult`): ``diffguide fit``.
- :func:`predict_job` (:class:`PredictSettings` -> :class:`PredictResult`):
  ``diffguide predict``.
- :func:`simulate_job` (:class:`SimulateSettings` -> :class:`SimulateResult`):
  ``diffguide simulate``, the cross table's too (the preset or the machine file deciding).
- :func:`montecarlo_job` (:class:`MontecarloSettings` -> :class:`MontecarloResult`):
  ``diffguide montecarlo``.
- :func:`tolerance_job` (:class:`ToleranceSettings` -> :class:`ToleranceResult`):
  ``diffguide tolerance``.
- :func:`import_job` (:class:`ImportSettings` -> :class:`ImportResult`): ``diffguide import``.
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
from .importing import ImportResult as ImportResult
from .importing import ImportSettings as ImportSettings
from .importing import import_job as import_job
from .montecarlo import MontecarloResult as MontecarloResult
from .montecarlo import MontecarloSettings as MontecarloSettings
from .montecarlo import montecarlo_job as montecarlo_job
from .plan import PlanResult as PlanResult
from .plan import PlanSettings as PlanSettings
from .plan import plan_job as plan_job
from .predict import PredictResult as PredictResult
from .predict import PredictSettings as PredictSettings
from .predict import predict_job as predict_job
from .simulate import SimulateResult as SimulateResult
from .simulate import SimulateSettings as SimulateSettings
from .simulate import simulate_job as simulate_job
from .tolerance import ToleranceResult as ToleranceResult
from .tolerance import ToleranceSettings as ToleranceSettings
from .tolerance import tolerance_job as tolerance_job

__all__ = [
    "DesignJobResult",
    "DesignSettings",
    "design_job",
    "FitResult",
    "FitSettings",
    "fit_job",
    "ImportResult",
    "ImportSettings",
    "import_job",
    "MontecarloResult",
    "MontecarloSettings",
    "montecarlo_job",
    "PlanResult",
    "PlanSettings",
    "plan_job",
    "PredictResult",
    "PredictSettings",
    "predict_job",
    "SimulateResult",
    "SimulateSettings",
    "simulate_job",
    "ToleranceResult",
    "ToleranceSettings",
    "tolerance_job",
]
