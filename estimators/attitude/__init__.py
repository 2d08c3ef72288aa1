"""Head attitude from a head-worn IMU: the attitude stages of :data:`estimators.stages.ATTITUDE`.

* :mod:`~estimators.attitude.ekf` — Zhang 2021's error-state EKF (Zhang, Chen & Gao 2021, corrected
  with Trawny & Roumeliotis 2005): :class:`AttitudeEKF`, its parameters and its stages.
* :mod:`~estimators.attitude.offline` — whole recordings: :func:`estimate_attitude`, causal or
  smoothed forward-backward (:func:`smooth_attitude`).
* :mod:`~estimators.attitude.errors` — BROAD's orientation error metrics.
* :mod:`~estimators.attitude.vqf`, :mod:`~estimators.attitude.madgwick`,
  :mod:`~estimators.attitude.mahony`, :mod:`~estimators.attitude.gyro` — the reference stages
  (VQF through the ``vqf`` package; Madgwick, Mahony and gyro integration on the shell of
  :mod:`~estimators.attitude.base`).
* :mod:`~estimators.attitude._kernel` — the package's compiled kernels, one module per filter
  (the EKF and the reference filters) and one for the reference filters' start convention; each
  ``py_func`` is the readable reference.
"""

from estimators.attitude.base import QuaternionStage
from estimators.attitude.ekf import (
    MAX_GYR_NORM,
    MIN_ACC_NORM,
    AttitudeEKF,
    AttitudeParams,
    EkfStage,
    f_zero_ekf,
    paper_literal_ekf,
)
from estimators.attitude.errors import heading_twist, orientation_errors
from estimators.attitude.gyro import GyroOnly, GyroOnlyParams
from estimators.attitude.madgwick import Madgwick, MadgwickParams
from estimators.attitude.mahony import Mahony, MahonyParams
from estimators.attitude.offline import UNKNOWN_VAR, estimate_attitude, smooth_attitude
from estimators.attitude.vqf import VqfParams, VqfStage

__all__ = [
    "MAX_GYR_NORM",
    "MIN_ACC_NORM",
    "UNKNOWN_VAR",
    "AttitudeEKF",
    "AttitudeParams",
    "EkfStage",
    "GyroOnly",
    "GyroOnlyParams",
    "Madgwick",
    "MadgwickParams",
    "Mahony",
    "MahonyParams",
    "QuaternionStage",
    "VqfParams",
    "VqfStage",
    "estimate_attitude",
    "f_zero_ekf",
    "heading_twist",
    "orientation_errors",
    "paper_literal_ekf",
    "smooth_attitude",
]
