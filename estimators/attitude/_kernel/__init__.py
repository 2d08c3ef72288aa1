"""Compiled kernels of the attitude stages, one module per filter; the Python classes that drive
them are in :mod:`estimators.attitude`:

* :mod:`~estimators.attitude._kernel.ekf` — the error-state EKF (:data:`ekf_kernel`, for
  :class:`~estimators.attitude.ekf.AttitudeEKF`), its per-stream state and scratch records
  (:data:`STATE_FIELDS`, :data:`SCRATCH_FIELDS`);
* :mod:`~estimators.attitude._kernel.start` — how the reference stages start a stream: the
  attitude of one accelerometer (+ magnetometer) sample (:func:`quat_from_acc`,
  :func:`quat_from_acc_mag`, chosen by :func:`start_quat`) and the sample-validity test
  (:func:`usable3`);
* :mod:`~estimators.attitude._kernel.gyro` — gyro only (:data:`gyro_kernel`, for
  :mod:`estimators.attitude.gyro`);
* :mod:`~estimators.attitude._kernel.madgwick` — Madgwick's filter (:data:`madgwick_kernel`, for
  :mod:`estimators.attitude.madgwick`);
* :mod:`~estimators.attitude._kernel.mahony` — Mahony's filter (:data:`mahony_kernel`, for
  :mod:`estimators.attitude.mahony`).

Each kernel's uncompiled ``py_func`` is its readable source. Quaternions are Hamilton
``[w, x, y, z]``, sensor -> ENU world.
"""

from estimators.attitude._kernel.ekf import SCRATCH_FIELDS, STATE_FIELDS, ekf_kernel
from estimators.attitude._kernel.gyro import gyro_kernel
from estimators.attitude._kernel.madgwick import madgwick_kernel
from estimators.attitude._kernel.mahony import mahony_kernel
from estimators.attitude._kernel.start import quat_from_acc, quat_from_acc_mag, start_quat, usable3

__all__ = [
    "SCRATCH_FIELDS",
    "STATE_FIELDS",
    "ekf_kernel",
    "gyro_kernel",
    "madgwick_kernel",
    "mahony_kernel",
    "quat_from_acc",
    "quat_from_acc_mag",
    "start_quat",
    "usable3",
]
