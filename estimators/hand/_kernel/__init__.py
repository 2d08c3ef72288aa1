"""Yao 2023's hand pipeline, compiled (:mod:`estimators.hand`), in the order of its stages:

* :mod:`~estimators.hand._kernel.joints` — stages 1 and 2: target selection, the Kinect SDK's
  Holt joint filter and the weighted average (:data:`holt_kernel` runs stage 2 alone, for
  :class:`~estimators.hand.joint_smoothing.HoltSmoother`);
* :mod:`~estimators.hand._kernel.orientation` — stage 3: eq (1)/(2), the Kalman filter and the
  median (:data:`filter_kernel` and :data:`angles_kernel` run it alone, for
  :class:`~estimators.hand.orientation.OrientationFilter`);
* :mod:`~estimators.hand._kernel.pipeline` — the whole pipeline per user and frame
  (:data:`hand_kernel`, for :class:`~estimators.hand.pipeline.HandPipeline`), its input checks
  (:func:`validate`) and state (:func:`new_state`).

The stages are the same scalar functions wherever they run, so the parts give the whole's
numbers bit for bit; each kernel's ``py_func`` is the readable uncompiled source.
"""

from estimators.hand._kernel.joints import (
    JOINT_FIELDS,
    RING_FIELDS,
    holt_kernel,
    new_holt_state,
)
from estimators.hand._kernel.orientation import (
    AXIS_FIELDS,
    MIN_QUAT_NORM,
    USER_FIELDS,
    angles_kernel,
    filter_kernel,
    new_filter_state,
    shared_layout,
)
from estimators.hand._kernel.pipeline import (
    ERR_DUPLICATE_ID,
    ERR_JOINTS_INF,
    ERR_NEGATIVE_ID,
    ERR_QUAT_INF,
    ERR_STATE_RANGE,
    PARAM_FIELDS,
    forget_kernel,
    hand_kernel,
    new_state,
    validate,
)

__all__ = [
    "AXIS_FIELDS",
    "ERR_DUPLICATE_ID",
    "ERR_JOINTS_INF",
    "ERR_NEGATIVE_ID",
    "ERR_QUAT_INF",
    "ERR_STATE_RANGE",
    "JOINT_FIELDS",
    "MIN_QUAT_NORM",
    "PARAM_FIELDS",
    "RING_FIELDS",
    "USER_FIELDS",
    "angles_kernel",
    "filter_kernel",
    "forget_kernel",
    "hand_kernel",
    "holt_kernel",
    "new_filter_state",
    "new_holt_state",
    "new_state",
    "shared_layout",
    "validate",
]
