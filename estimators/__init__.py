"""Estimators of the vrloco source papers: pure numpy (numba where measured), batched over a
leading dimension of B streams, with no knowledge of the environment.

Modules:

* :mod:`estimators.rotations` — the one quaternion / rotation-matrix / ZYX-Euler module.
* :mod:`estimators.attitude` — seed 000's error-state attitude EKF (streaming and offline).
* :mod:`estimators.gait` — seed 000's still/walk and step detector; step F1.
* :mod:`estimators.dead_reckoning` — seed 000's eq (17) virtual path.
* :mod:`estimators.locomotion` — seed 001's smooth-locomotion filter (continuous virtual motion).
* :mod:`estimators.joint_smoothing`, :mod:`estimators.hand` — seed 003's hand-orientation
  pipeline (target selection, Holt smoothing, eq 1/2, Kalman + median) and a One Euro filter.
* :mod:`estimators.strapdown`, :mod:`estimators.visual_pose`, :mod:`estimators.visual_inertial`
  — seed 004's strapdown inertial solution, OpenCV PnP pose from landmarks, and the (adaptive)
  error-state Kalman filter fusing them.
* :mod:`estimators.io_broad`, :mod:`estimators.io_oxford`, :mod:`estimators.io_kinect` — readers
  for the real recordings we validate against.
"""
