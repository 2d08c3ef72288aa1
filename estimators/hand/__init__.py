"""Hand orientation from Kinect v2 frames: Yao 2023's pipeline (Yao, Chen, Pan & Huang 2023) and
the hand stages of :data:`estimators.stages.HAND`.

* :mod:`~estimators.hand.pipeline` — :class:`HandPipeline`: target selection, joint smoothing,
  eq (1)/(2), Kalman and median for B users, frame by frame (:class:`HandFrame`), and
  :func:`estimate_hand_orientation` over whole sequences.
* :mod:`~estimators.hand.joint_smoothing` — the Kinect SDK's Holt joint filter with Yao 2023's
  weighted average (:class:`HoltSmoother`) and the One Euro filter (:class:`OneEuroFilter`).
* :mod:`~estimators.hand.angles` — the angle convention: eq (1)/(2) and the paper's axis names.
* :mod:`~estimators.hand.orientation` — the Kalman + median filter of the angles on its own
  (:class:`OrientationFilter`); :mod:`~estimators.hand.params` — its parameters and the pipeline's.
* :mod:`~estimators.hand.lag` — the lag metric (:func:`estimate_lag`).
* The hand stages: :mod:`~estimators.hand.pipeline_stages` (``yao2023``, ``raw``: the pipeline's
  own outputs), :mod:`~estimators.hand.one_euro` (``one_euro``), :mod:`~estimators.hand.adaptive`
  (``adaptive_kalman``).
* :mod:`~estimators.hand._kernel` — the compiled pipeline, stage by stage; each kernel's
  ``py_func`` is the readable reference.
"""

from estimators.hand.adaptive import AdaptiveKalmanHand, AdaptiveKalmanHandParams
from estimators.hand.angles import (
    PAPER_AXIS_NAMES,
    PAPER_SINGULARITY_THRESHOLD,
    paper_angles,
    paper_to_ypr,
    quat_to_euler_paper,
    unwrap_angles,
    ypr_to_paper,
)
from estimators.hand.joint_smoothing import (
    INFERRED,
    NOT_TRACKED,
    TRACKED,
    HoltParams,
    HoltSmoother,
    OneEuroFilter,
    OneEuroParams,
)
from estimators.hand.lag import estimate_lag
from estimators.hand.one_euro import OneEuroHand, OneEuroHandParams
from estimators.hand.orientation import OrientationFilter, OrientationFrame
from estimators.hand.params import KINECT_RATE_HZ, HandParams, KalmanParams
from estimators.hand.pipeline import (
    HandFrame,
    HandPipeline,
    check_hand_frames,
    estimate_hand_orientation,
)
from estimators.hand.pipeline_stages import RawHand, Yao2023Hand
from estimators.registry import renamed_attributes

__all__ = [
    "INFERRED",
    "KINECT_RATE_HZ",
    "NOT_TRACKED",
    "PAPER_AXIS_NAMES",
    "PAPER_SINGULARITY_THRESHOLD",
    "TRACKED",
    "AdaptiveKalmanHand",
    "AdaptiveKalmanHandParams",
    "HandFrame",
    "HandParams",
    "HandPipeline",
    "HoltParams",
    "HoltSmoother",
    "KalmanParams",
    "OneEuroFilter",
    "OneEuroHand",
    "OneEuroHandParams",
    "OneEuroParams",
    "OrientationFilter",
    "OrientationFrame",
    "RawHand",
    "Yao2023Hand",
    "check_hand_frames",
    "estimate_hand_orientation",
    "estimate_lag",
    "paper_angles",
    "paper_to_ypr",
    "quat_to_euler_paper",
    "unwrap_angles",
    "ypr_to_paper",
]

#: The earlier name, importable for one release with a deprecation warning.
__getattr__ = renamed_attributes(globals(), {"Seed003Hand": "Yao2023Hand"})
