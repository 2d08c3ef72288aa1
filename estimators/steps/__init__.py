"""Still/walk and step events from a head-worn IMU: the step stages of
:data:`estimators.stages.STEPS`, and the cadence of the detected steps.

* :mod:`~estimators.steps.zhang2021` — Zhang 2021's detector (Zhang, Chen & Gao 2021, eqs 15-16 on
  the specific-force norm): :class:`StepDetector` and its stage :class:`Zhang2021Steps`.
* :mod:`~estimators.steps.offline` — whole recordings with irregular timestamps:
  :func:`detect_steps`.
* :mod:`~estimators.steps.threshold` — a naive peak picker on ``|f|``, the floor.
* :mod:`~estimators.steps.nod_robust` — the world-vertical specific force with a rotation veto
  against nods.
* :mod:`~estimators.steps.lee2018` — Lee 2018 style: dips of the headset's tracked height.
* :mod:`~estimators.steps.cadence` — the cadence (steps/s) from step events.
* :mod:`~estimators.steps._kernel` — the package's compiled kernels and the stages Zhang 2021's
  family of detectors shares; each ``py_func`` is the readable reference.

Every step stage returns an :class:`estimators.stages.GaitChunk`.
"""

from estimators.registry import renamed_attributes
from estimators.steps.cadence import CadenceEstimator
from estimators.steps.lee2018 import Lee2018Params, Lee2018Steps
from estimators.steps.nod_robust import NodRobustParams, NodRobustSteps
from estimators.steps.offline import GaitResult, bin_average, detect_steps
from estimators.steps.threshold import ThresholdParams, ThresholdSteps
from estimators.steps.zhang2021 import GaitParams, StepDetector, Zhang2021Steps

__all__ = [
    "CadenceEstimator",
    "GaitParams",
    "GaitResult",
    "Lee2018Params",
    "Lee2018Steps",
    "NodRobustParams",
    "NodRobustSteps",
    "StepDetector",
    "ThresholdParams",
    "ThresholdSteps",
    "Zhang2021Steps",
    "bin_average",
    "detect_steps",
]

#: The earlier name, importable for one release with a deprecation warning.
__getattr__ = renamed_attributes(globals(), {"Seed000Steps": "Zhang2021Steps"})
