"""Head pose of the helmet-tracking paper (a helmet's inertial and visual pose): strapdown inertial
navigation, PnP pose from image landmarks, and the (adaptive) error-state Kalman filter fusing them.

* :mod:`~estimators.head_pose.strapdown` — the strapdown solution (:class:`Strapdown`), coarse
  alignment and the static gyro bias.
* :mod:`~estimators.head_pose.pnp` — OpenCV PnP poses from landmarks (:func:`solve_pose`,
  :func:`solve_poses`), camera intrinsics and the camera/body mounting.
* :mod:`~estimators.head_pose.visual_inertial` — the visual-inertial filter
  (:class:`VisualInertialFilter`, :class:`VioConfig`).
* :mod:`~estimators.head_pose._kernel` — the package's compiled kernels (the one strapdown
  mechanisation, the filter's prediction and update); each ``py_func`` is the readable reference.
"""

from estimators.head_pose.pnp import (
    CAMERA_FROM_BODY,
    CAMERA_FROM_BODY_QUAT,
    REASON_BEHIND_CAMERA,
    REASON_OK,
    REASON_RANSAC_FAILED,
    REASON_TOO_FEW_INLIERS,
    REASON_TOO_FEW_LANDMARKS,
    CameraIntrinsics,
    NotEnoughLandmarks,
    VisualPose,
    VisualPoseBatch,
    body_pose_to_camera,
    camera_pose_to_body,
    project_points,
    solve_pose,
    solve_poses,
)
from estimators.head_pose.strapdown import (
    Strapdown,
    StrapdownTrajectory,
    coarse_alignment,
    set_nominal_state,
    static_gyro_bias,
)
from estimators.head_pose.visual_inertial import (
    STATUS_ACCEPTED,
    STATUS_FORCED,
    STATUS_REJECTED,
    STATUS_SKIPPED,
    VioConfig,
    VisualInertialFilter,
)

__all__ = [
    "CAMERA_FROM_BODY",
    "CAMERA_FROM_BODY_QUAT",
    "REASON_BEHIND_CAMERA",
    "REASON_OK",
    "REASON_RANSAC_FAILED",
    "REASON_TOO_FEW_INLIERS",
    "REASON_TOO_FEW_LANDMARKS",
    "STATUS_ACCEPTED",
    "STATUS_FORCED",
    "STATUS_REJECTED",
    "STATUS_SKIPPED",
    "CameraIntrinsics",
    "NotEnoughLandmarks",
    "Strapdown",
    "StrapdownTrajectory",
    "VioConfig",
    "VisualInertialFilter",
    "VisualPose",
    "VisualPoseBatch",
    "body_pose_to_camera",
    "camera_pose_to_body",
    "coarse_alignment",
    "project_points",
    "set_nominal_state",
    "solve_pose",
    "solve_poses",
    "static_gyro_bias",
]
