"""Estimators of the vrloco source papers: pure numpy (numba where measured), batched over a
leading dimension of B streams, with no knowledge of the environment.

Modules:

* :mod:`estimators.stages` — the stage protocols (attitude, steps, hand, steering, locomotion)
  and their registries of named implementations; ``"module:attr"`` plug-ins.
* :mod:`estimators.rotations` — the one quaternion / rotation-matrix / ZYX-Euler module.
* :mod:`estimators.attitude` — seed 000's error-state attitude EKF (streaming; offline through
  :mod:`estimators.attitude.offline`, the forward-backward smoother);
  :mod:`estimators.attitude.errors` — BROAD's orientation error metrics;
  :mod:`estimators.attitude.vqf`, :mod:`estimators.attitude.madgwick`,
  :mod:`estimators.attitude.mahony`, :mod:`estimators.attitude.gyro` — the other attitude stages.
* :mod:`estimators.steps.zhang2021` — seed 000's still/walk and step detector; step F1;
  :mod:`estimators.steps.threshold`, :mod:`estimators.steps.nod_robust` — other step stages;
  :mod:`estimators.steps.cadence` — cadence from step events.
* :mod:`estimators.locomotion.steering` — head and torso steering, the torso's yaw from the
  shoulders.
* :mod:`estimators.locomotion.dead_reckoning` — seed 000's eq (17) virtual path.
* :mod:`estimators.locomotion` — seed 001's smooth-locomotion filter (continuous virtual motion);
  :mod:`estimators.locomotion.cadence_speed` — speed proportional to the cadence.
* :mod:`estimators.hand.joint_smoothing`, :mod:`estimators.hand` — seed 003's hand-orientation
  pipeline (target selection, Holt smoothing, eq 1/2, Kalman + median) and a One Euro filter;
  :mod:`estimators.hand.one_euro` — the One Euro hand stage.
* :mod:`estimators.head_pose.strapdown`, :mod:`estimators.head_pose.pnp`,
  :mod:`estimators.head_pose.visual_inertial` — seed 004's strapdown inertial solution, OpenCV PnP
  pose from landmarks, and the (adaptive) error-state Kalman filter fusing them.
* :mod:`estimators.io.broad`, :mod:`estimators.io.oxford`, :mod:`estimators.io.kinect` — readers
  for the real recordings we validate against.
"""
