"""What the compiled motion kernels (:mod:`vrloco_env.user._motion_numba`) read besides each
user's state: the Fourier weights of the heel-strike pulse, the body geometry (:data:`_BODY`, for
:data:`~vrloco_env.user._motion_numba.skeleton_kernel`) and the parameter record of a
:class:`~vrloco_env.user.motion_params.MotionParams` (:func:`_kernel_params`, for
:data:`~vrloco_env.user._motion_numba.evaluate_kernel`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import rotations as rot
from estimators.kernels import param_record
from vrloco_env.user.motion_params import MotionParams
from vrloco_env.user.skeleton import Joint

_PULSE_KAPPA = 3.0  # von Mises concentration of the heel-strike acceleration pulse
_PULSE_HARMONICS = 24


def _pulse_coefficients() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Fourier weights of the unit-peak, zero-mean heel-strike pulse and of its double integral."""
    from scipy.special import iv

    k = np.arange(1, _PULSE_HARMONICS + 1, dtype=np.float64)
    w = iv(k, _PULSE_KAPPA)
    w = w / (2.0 * w.sum())  # peak of sum 2 w_k cos(...) at the heel strike is 1
    acc = 2.0 * w  # d2Z/dphi2 = sum acc_k cos(2 pi k (phi - 1/2))
    pos = -acc / (2.0 * np.pi * k) ** 2  # Z = sum pos_k cos(...)
    return acc, pos


_PULSE_ACC, _PULSE_POS = _pulse_coefficients()
_PULSE_K = np.arange(1, _PULSE_HARMONICS + 1, dtype=np.float64)
_PULSE_Z0 = float(np.sum(_PULSE_POS * np.cos(-np.pi * _PULSE_K)))  # Z at a step boundary


#: Joints fixed in the torso frame, as offsets (m) from the neck pivot (x forward, y left, z up);
#: adult proportions after Winter, Biomechanics and Motor Control of Human Movement (2009).
_TORSO_OFFSETS = {
    Joint.NECK: (0.0, 0.0, 0.0),
    Joint.SPINE_SHOULDER: (0.0, 0.0, -0.08),
    Joint.SPINE_MID: (0.0, 0.0, -0.32),
    Joint.SPINE_BASE: (0.0, 0.0, -0.55),
    Joint.SHOULDER_LEFT: (0.0, 0.19, -0.12),
    Joint.SHOULDER_RIGHT: (0.0, -0.19, -0.12),
    Joint.ELBOW_LEFT: (0.0, 0.21, -0.40),
    Joint.ELBOW_RIGHT: (0.08, -0.21, -0.36),
    # The left arm hangs.
    Joint.WRIST_LEFT: (0.02, 0.21, -0.65),
    Joint.HAND_LEFT: (0.02, 0.21, -0.73),
    Joint.HAND_TIP_LEFT: (0.02, 0.21, -0.82),
    Joint.THUMB_LEFT: (0.06, 0.21, -0.71),
}
_TORSO_JOINTS = np.array(list(_TORSO_OFFSETS), dtype=np.intp)
_TORSO_OFFSET_ARRAY = np.array(list(_TORSO_OFFSETS.values()))
_HEAD_OFFSET = np.array([0.02, 0.0, 0.10])  # head centre from the neck pivot, head frame
#: Legs (left, right) x (hip, knee, ankle, foot) at rest, and the change at full knee lift.
_LEG_JOINTS = np.array(
    [
        Joint.HIP_LEFT,
        Joint.KNEE_LEFT,
        Joint.ANKLE_LEFT,
        Joint.FOOT_LEFT,
        Joint.HIP_RIGHT,
        Joint.KNEE_RIGHT,
        Joint.ANKLE_RIGHT,
        Joint.FOOT_RIGHT,
    ],
    dtype=np.intp,
)
_LEG_REST = np.array(
    [[[0.0, y, -0.60], [0.0, y, -1.05], [0.0, y, -1.47], [0.12, y, -1.53]] for y in (0.09, -0.09)]
)
_LEG_LIFT = np.array([[0.0, 0.0, 0.0], [0.10, 0.0, 0.12], [0.05, 0.0, 0.12], [0.05, 0.0, 0.12]])
_FLOOR_CLEARANCE = 0.02  # m, lowest height of ankle and foot joints
_FOREARM = np.array([0.26, 0.0, 0.04])  # elbow -> wrist, torso frame
#: Hand, hand tip and thumb from the wrist in the hand frame (x to the fingertips, y thumb side).
_HAND_JOINTS = np.array([Joint.HAND_RIGHT, Joint.HAND_TIP_RIGHT, Joint.THUMB_RIGHT], dtype=np.intp)
_HAND_OFFSETS = np.array([[0.08, 0.0, 0.0], [0.17, 0.0, 0.0], [0.06, 0.05, 0.0]])


def _record(base: NDArray | None = None, **values: ArrayLike) -> NDArray:
    """A (1,) record for a kernel: the fields of ``base`` (a (1,) record such as
    :func:`estimators.kernels.param_record` builds), then ``values``, each a number or a
    fixed-shape array stored with its own dtype and shape."""
    items = {} if base is None else {name: base[name][0] for name in base.dtype.names}
    items.update((name, np.asarray(v)) for name, v in values.items())
    rec = np.zeros(1, [(name, v.dtype, v.shape) for name, v in items.items()])
    for name, v in items.items():
        rec[name][0] = v
    return rec


#: The body geometry :data:`vrloco_env.user._motion_numba.skeleton_kernel` reads: torso-frame
#: offsets (m) and the Kinect joints they place.
_BODY = _record(
    torso_offsets=_TORSO_OFFSET_ARRAY,
    torso_joints=_TORSO_JOINTS,
    head_offset=_HEAD_OFFSET,
    head_joint=int(Joint.HEAD),
    leg_rest=_LEG_REST,
    leg_lift=_LEG_LIFT,
    leg_joints=_LEG_JOINTS,
    floor_z=_FLOOR_CLEARANCE,
    forearm=_FOREARM,
    elbow_right=int(Joint.ELBOW_RIGHT),
    wrist_right=int(Joint.WRIST_RIGHT),
    hand_offsets=_HAND_OFFSETS,
    hand_joints=_HAND_JOINTS,
)

#: MotionParams fields :data:`vrloco_env.user._motion_numba.evaluate_kernel` does not read.
_UNREAD_PARAMS = (
    "imu_rate_hz",
    "kinect_rate_hz",
    "control_rate_hz",
    "max_turn_rate",
    "max_hand_rate",
    "sway_roll_deg",
    "style_spread",
    "overground",
    "stride_m",
    "speed_lag_s",
)


def _kernel_params(p: MotionParams) -> NDArray:
    """The (1,) parameter record of :data:`vrloco_env.user._motion_numba.evaluate_kernel`: the
    fields of ``p`` it reads under their names, the sway roll in rad, gravity (m/s^2) and the
    heel-strike pulse's position weights ``pulse_pos`` with their value at a step boundary."""
    scalars = param_record(
        p,
        exclude=_UNREAD_PARAMS,
        sway_roll=float(np.deg2rad(p.sway_roll_deg)),
        gravity=rot.GRAVITY,
        pulse_z0=_PULSE_Z0,
    )
    return _record(
        scalars,
        cadence_range_hz=np.asarray(p.cadence_range_hz, dtype=np.float64),
        peak_accel_g=np.asarray(p.peak_accel_g, dtype=np.float64),
        imu_offset_m=np.asarray(p.imu_offset_m, dtype=np.float64),
        pulse_pos=_PULSE_POS,
    )
