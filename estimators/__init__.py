"""Estimators of the vrloco source papers: pure numpy (numba where measured), batched over a
leading dimension of B streams, with no knowledge of the environment.

One sub-package per estimation stage, over a shared ground floor; no stage package imports
another, and each keeps its compiled code in its own ``_kernel`` (each kernel's uncompiled
``py_func`` is the readable reference).

Ground floor:

* :mod:`estimators.stages` — the stage protocols (attitude, steps, hand, steering, locomotion),
  their contracts and their registries of named implementations;
  :mod:`estimators.registry` — the :class:`~estimators.registry.Registry` type and the
  ``"module:attr"`` plug-in loader; :mod:`estimators.checked` — the proxy that holds a plug-in to
  its contract; :mod:`estimators.stage_docs` — ``docs/protocols.md``, rendered from them.
* :mod:`estimators.rotations` — the one quaternion / rotation-matrix / ZYX-Euler module;
  :mod:`estimators.kernels` — what every compiled kernel shares (the batch driver, scalar
  rotations, named records).
* :mod:`estimators.batching` — dropping users mid-run; :mod:`estimators.validation` — every
  argument check, one error format.

Stages:

* :mod:`estimators.attitude` — head attitude: Zhang 2021's error-state EKF (streaming, and offline
  through its forward-backward smoother), BROAD's error metrics, VQF, Madgwick, Mahony and gyro
  integration.
* :mod:`estimators.steps` — Zhang 2021's still/walk and step detector, the other step stages and
  the cadence.
* :mod:`estimators.hand` — Yao 2023's hand-orientation pipeline (target selection, Holt
  smoothing, eq 1/2, Kalman + median) and the hand stages.
* :mod:`estimators.locomotion` — Zhang 2021's eq (17) virtual path, the smooth-locomotion paper's
smooth filter,
  cadence-proportional speed, and head or torso steering.
* :mod:`estimators.head_pose` — the helmet-tracking paper's strapdown inertial solution, OpenCV PnP
pose from
  landmarks, and the (adaptive) error-state Kalman filter fusing them.
* :mod:`estimators.io` — readers for the real recordings we validate against.
"""

from estimators.numba_cache import use_fingerprinted_cache as _use_fingerprinted_cache

_use_fingerprinted_cache()  # before any kernel is defined: numba's cache of these sources
