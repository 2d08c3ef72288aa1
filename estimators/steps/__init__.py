"""Still/walk and step events from a head-worn IMU: the step stages of
:data:`estimators.stages.STEPS`, and the cadence of the detected steps.

* :mod:`~estimators.steps.zhang2021` — seed 000's detector (Zhang, Chen & Gao 2021, eqs 15-16 on
  the specific-force norm): :class:`StepDetector` and its stage :class:`Seed000Steps`.
* :mod:`~estimators.steps.offline` — whole recordings with irregular timestamps:
  :func:`detect_steps`.
* :mod:`~estimators.steps.threshold` — a naive peak picker on ``|f|``, the floor.
* :mod:`~estimators.steps.nod_robust` — the world-vertical specific force with a rotation veto
  against nods.
* :mod:`~estimators.steps.cadence` — the cadence (steps/s) from step events.
* :mod:`~estimators.steps._kernel` — the package's compiled kernels and the stages seed 000's
  family of detectors shares; each ``py_func`` is the readable reference.

Every step stage returns an :class:`estimators.stages.GaitChunk`.
"""

from estimators.steps.cadence import CadenceEstimator
from estimators.steps.nod_robust import NodRobustParams, NodRobustSteps
from estimators.steps.offline import GaitResult, bin_average, detect_steps
from estimators.steps.threshold import ThresholdParams, ThresholdSteps
from estimators.steps.zhang2021 import GaitParams, Seed000Steps, StepDetector

__all__ = [
    "CadenceEstimator",
    "GaitParams",
    "GaitResult",
    "NodRobustParams",
    "NodRobustSteps",
    "Seed000Steps",
    "StepDetector",
    "ThresholdParams",
    "ThresholdSteps",
    "bin_average",
    "detect_steps",
]
