"""Parameters of Yao 2023's hand pipeline: the Kalman filter of the Euler angles, the pipeline's
own fields, and the kernels' parameter records built from them.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from estimators.hand._kernel import AXIS_FIELDS, PARAM_FIELDS, shared_layout
from estimators.hand.angles import PAPER_SINGULARITY_THRESHOLD
from estimators.hand.joint_smoothing import INFERRED, TRACKED, HoltParams
from estimators.kernels.records import param_record, record_dtype
from estimators.validation import (
    check_condition,
    check_in_range,
    check_instance,
    check_numbers,
    value_repr,
)

__all__ = [
    "KINECT_RATE_HZ",
    "HandParams",
    "KalmanParams",
    "kalman_constants",
    "kernel_params",
]

#: Kinect v2 frame rate, Hz (Kinect for Windows SDK 2.0; Yao 2023, section 2.2).
KINECT_RATE_HZ = 30.0

# Kinect v2 JointType indices (Kinect for Windows SDK 2.0), as defaults; the environment's
# vrloco_env.user.skeleton.Joint holds the same numbers.
_SPINE_BASE, _SPINE_MID, _WRIST_RIGHT, _SPINE_SHOULDER = 0, 1, 10, 20


def _per_axis(value: float | Sequence[float]) -> NDArray[np.float64]:
    """A validated field that is a number or one per axis, as a (3,) array."""
    return np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)).copy()


@dataclass(frozen=True)
class KalmanParams:
    """Kalman filter on each Euler angle: constant-rate model with adaptive process noise.

    Yao 2023 gives the generic equations (3)-(8) but neither its model nor its noise values. We
    choose per axis the state ``[angle, rate]`` with ``A = [[1, dt], [0, 1]]``, ``H = [1, 0]``,
    driven by white angular acceleration of spectral density ``q`` (``Q = q [[dt^3/3, dt^2/2],
    [dt^2/2, dt]]``). A constant-rate model follows a steady rotation without lag, which a
    random-walk (A = 1) model cannot.

    A fixed ``q`` forces a choice between smoothing a still hand (small ``q``) and following a
    turning one (large ``q``); variance alone rewards the first (SPEC section 3). So ``q`` adapts:
    with ``nis`` the normalised innovation squared ``y^2 / S`` low-passed with time constant
    ``adapt_time``, ``q = accel_psd * clip(nis, 1, .)^2``, capped at ``max_accel_psd``. At rest
    ``nis`` is about 1 (strong smoothing); when the hand accelerates the innovations grow and the
    filter opens within a few frames (the noise-level adjustment of Bar-Shalom, Li, Kirubarajan,
    "Estimation with Applications to Tracking and Navigation", 2001, ch. 11: adjustable
    process noise level).
    ``max_accel_psd == accel_psd`` gives the plain Kalman filter. The innovation is wrapped to
    (-pi, pi] and the angle state kept unwrapped, so crossing +-180 deg gives no 360 deg jump.

    Yao 2023 states no values; ``accel_psd`` was chosen on the development seeds of
    :mod:`agents.experiments.hand_variance` (static: seeds 1, 2, the paper's 11 angles x 5
    repeats x 10 s; moving: seeds 101, 102, 10 users sweeping about the forearm at 90 deg/s), the
    other fields set by the reasoning given with each.

    Attributes:
        rate_hz: frame rate, Hz (Kinect v2: 30).
        measurement_std: std of the raw Euler angles, rad (one value or one per ``[yaw, pitch,
            roll]``). Default 2 deg: Yao 2023's raw static variances (Tables 1-3) span 0.5 to
            14 deg^2 (0.7 to 3.7 deg), typically about 4 deg^2.
        accel_psd: spectral density of the angular acceleration at rest, rad^2/s^3 (one or per
            axis). Default 1: on the development seeds, the value of the grid 0.03, 0.1, 0.3, 1,
            3, 10 whose Kalman output has the smallest RMSE against the truth relative to raw's,
            averaged over the three axes, the still and the moving trials (0.926; 0.935 at 0.3,
            0.926 at 3; ``python -m agents.experiments.hand_variance --only yao2023``). Smaller
            values smooth a still hand more (higher variance reduction) and fall behind a moving
            one.
        max_accel_psd: cap of the adapted density, rad^2/s^3 (one or per axis, >= accel_psd).
            Default 10.
        adapt_time: time constant of the innovation average that drives the adaptation, s.
            Default 0.1 s (3 frames).
        init_rate_std: std of the rate at initialisation, rad/s. Default 90 deg/s, a brisk wrist
            rotation.
        max_coast_frames: frames a stream without a valid measurement keeps predicting before it
            is declared stale (its output then holds and the next valid measurement
            re-initialises it). Default 5 (167 ms at 30 Hz).
    """

    rate_hz: float = KINECT_RATE_HZ
    measurement_std: float | tuple[float, float, float] = float(np.deg2rad(2.0))
    accel_psd: float | tuple[float, float, float] = 1.0
    max_accel_psd: float | tuple[float, float, float] = 10.0
    adapt_time: float = 0.1
    init_rate_std: float | tuple[float, float, float] = float(np.deg2rad(90.0))
    max_coast_frames: int = 5

    def __post_init__(self) -> None:
        inf = math.inf
        check_in_range(self, "rate_hz", 0.0, inf, "Hz", lo_open=True)
        per_axis = (
            ("measurement_std", "rad"),
            ("accel_psd", "rad^2/s^3"),
            ("max_accel_psd", "rad^2/s^3"),
            ("init_rate_std", "rad/s"),
        )
        for name, unit in per_axis:  # a number, or one per axis
            if isinstance(getattr(self, name), numbers.Real):
                check_in_range(self, name, 0.0, inf, unit, lo_open=True)
            else:
                check_numbers(self, name, 0.0, inf, unit, length=3, lo_open=True)
        lo, hi = _per_axis(self.accel_psd), _per_axis(self.max_accel_psd)
        check_condition(
            self,
            "max_accel_psd",
            bool(np.all(hi >= lo)),
            f">= accel_psd={value_repr(self.accel_psd)} on every axis",
        )
        check_in_range(self, "adapt_time", 0.0, inf, "s", lo_open=True)
        check_in_range(self, "max_coast_frames", 0, inf, "frames", whole=True)


def kalman_constants(
    p: KalmanParams,
) -> tuple[
    float, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float
]:
    """The filter's constants: frame period dt (s); per axis the measurement variance, the
    acceleration PSD at rest and its cap, the initial rate variance; the gain per frame of the
    innovation low-pass, ``1 - exp(-dt / adapt_time)``."""
    dt = 1.0 / p.rate_hz
    return (
        dt,
        _per_axis(p.measurement_std) ** 2,
        _per_axis(p.accel_psd),
        _per_axis(p.max_accel_psd),
        _per_axis(p.init_rate_std) ** 2,
        1.0 - np.exp(-dt / p.adapt_time),
    )


@dataclass(frozen=True)
class HandParams:
    """Parameters of the hand pipeline.

    Attributes:
        holt: joint smoothing, :class:`HoltParams` (Kinect SDK defaults).
        kalman: Euler Kalman filter, :class:`KalmanParams`.
        median_window: frames in the median over consecutive Kalman outputs, >= 1. Default 3:
            Yao 2023 does not state it. On a steady rotation a causal median of n frames lags
            (n - 1) / 2 frames: 33 ms for 3, 67 ms for 5 at 30 Hz. Behind our Kalman filter the
            median removes a few points more variance at rest but adds that lag in motion (its
            share and its price: ``vrloco experiment hand-variance``), so we keep the smallest
            window that is still a median; 1 disables it.
        singularity_threshold: eq (2) is used where ``|wy - zx|`` exceeds this (paper: 0.499).
        wrist_joint: joint whose orientation ``hand_quat`` is (default 10, WristRight).
        center_joints: joints whose mean locates a body for the nearest-body rule (default 0
            SpineBase, 1 SpineMid, 20 SpineShoulder).
        min_wrist_state: the wrist quaternion is used only if the wrist joint's tracking state is
            at least this (1: inferred accepted, the default, since the Kinect still reports an
            orientation; 2: tracked only). Below it the frame is an orientation dropout.
    """

    holt: HoltParams = field(default_factory=HoltParams)
    kalman: KalmanParams = field(default_factory=KalmanParams)
    median_window: int = 3
    singularity_threshold: float = PAPER_SINGULARITY_THRESHOLD
    wrist_joint: int = _WRIST_RIGHT
    center_joints: tuple[int, ...] = (_SPINE_BASE, _SPINE_MID, _SPINE_SHOULDER)
    min_wrist_state: int = INFERRED

    def __post_init__(self) -> None:
        check_instance(self, "holt", HoltParams)
        check_instance(self, "kalman", KalmanParams)
        check_in_range(self, "median_window", 1, math.inf, "frames", whole=True)
        check_in_range(self, "singularity_threshold", 0.0, 0.5, lo_open=True)
        check_in_range(
            self,
            "min_wrist_state",
            INFERRED,
            TRACKED,
            whole=True,
            allowed="1 (inferred) or 2 (tracked)",
        )
        check_in_range(self, "wrist_joint", 0, math.inf, "(a joint index)", whole=True)
        check_numbers(self, "center_joints", 0, math.inf, "(joint indices)", whole=True)


def kernel_params(p: HandParams) -> tuple[NDArray, NDArray]:
    """The kernels' parameter records (:mod:`estimators.hand._kernel`): ``prm`` (1,) with the
    fields of :class:`~estimators.hand.joint_smoothing.HoltParams` and ``PARAM_FIELDS``, ``axes``
    (3,) with ``AXIS_FIELDS``."""
    dt, r, q, q_max, p11_init, lam = kalman_constants(p.kalman)
    values = {
        "singularity_threshold": p.singularity_threshold,
        "wrist_joint": p.wrist_joint,
        "min_wrist_state": p.min_wrist_state,
        "max_coast_frames": p.kalman.max_coast_frames,
        "dt": dt,
        "dt2_2": dt**2 / 2.0,
        "dt3_3": dt**3 / 3.0,
        "nis_gain": lam,
    }
    prm = param_record(p.holt, **{name: values[name] for name in PARAM_FIELDS})
    axes = np.zeros(3, record_dtype({name: () for name in AXIS_FIELDS}))
    for name, value in zip(AXIS_FIELDS, (r, q, q_max, p11_init), strict=True):
        axes[name] = value
    return shared_layout(prm), shared_layout(axes)
