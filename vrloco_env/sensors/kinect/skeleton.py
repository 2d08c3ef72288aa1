"""A standing skeleton in the Kinect v2's 25 joints (:func:`standing_skeleton`): the posture the
tests and the bystanders use, from anthropometric proportions."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.rotations import (
    matrix_to_quat,
    quat_from_ypr,
    quat_multiply,
    quat_rotate,
)
from vrloco_env.user import NUM_JOINTS, Joint

__all__ = ["standing_skeleton"]

J = Joint

# Standing posture, arms hanging, in the body frame (x forward, y left, z up, origin on the floor
# under the pelvis), in units of standing height H. Heights of joints follow the segment proportions
# of Drillis & Contini as given by Winter, "Biomechanics and Motor Control of Human Movement"
# (4th ed. 2009, Fig 4.1): hip 0.530 H, shoulder 0.818 H, elbow 0.630 H, wrist 0.485 H, knee
# 0.285 H, ankle 0.039 H; the Kinect joint placement (SpineBase at hip height, shoulders inside the
# acromion, hip joints ~0.05 H off the midline) follows the kinect_laban recording.
_TEMPLATE = np.array(
    [
        [0.000, 0.000, 0.530],  # SPINE_BASE
        [0.000, 0.000, 0.680],  # SPINE_MID
        [0.010, 0.000, 0.840],  # NECK
        [0.020, 0.000, 0.910],  # HEAD
        [0.000, 0.115, 0.805],  # SHOULDER_LEFT
        [0.000, 0.140, 0.630],  # ELBOW_LEFT
        [0.020, 0.145, 0.485],  # WRIST_LEFT
        [0.025, 0.145, 0.445],  # HAND_LEFT
        [0.000, -0.115, 0.805],  # SHOULDER_RIGHT
        [0.000, -0.140, 0.630],  # ELBOW_RIGHT
        [0.020, -0.145, 0.485],  # WRIST_RIGHT
        [0.025, -0.145, 0.445],  # HAND_RIGHT
        [0.000, 0.050, 0.530],  # HIP_LEFT
        [0.005, 0.055, 0.285],  # KNEE_LEFT
        [0.000, 0.055, 0.039],  # ANKLE_LEFT
        [0.060, 0.060, 0.020],  # FOOT_LEFT
        [0.000, -0.050, 0.530],  # HIP_RIGHT
        [0.005, -0.055, 0.285],  # KNEE_RIGHT
        [0.000, -0.055, 0.039],  # ANKLE_RIGHT
        [0.060, -0.060, 0.020],  # FOOT_RIGHT
        [0.000, 0.000, 0.800],  # SPINE_SHOULDER
        [0.030, 0.145, 0.395],  # HAND_TIP_LEFT
        [0.055, 0.135, 0.450],  # THUMB_LEFT
        [0.030, -0.145, 0.395],  # HAND_TIP_RIGHT
        [0.055, -0.135, 0.450],  # THUMB_RIGHT
    ]
)

# Right-arm poses, body frame, H units: elbow, wrist and the hand's orientation (hand frame ->
# body frame, [w, x, y, z]).
#   down:    arm hanging; forearm down, palm toward the thigh, thumb forward, back of hand outward.
#   forward: upper arm down, forearm held forward and level, palm down (vrloco_env.user.motion's
#            pose).
#   raised:  upper arm out and down, forearm vertical, palm facing forward, thumb to the left (the
#            kinect_laban "wave hand" posture).
_ARM_POSES = {
    "down": (
        _TEMPLATE[J.ELBOW_RIGHT],
        _TEMPLATE[J.WRIST_RIGHT],
        matrix_to_quat(np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])),
    ),
    "forward": (
        np.array([0.045, -0.125, 0.630]),
        np.array([0.197, -0.125, 0.630]),
        np.array([1.0, 0.0, 0.0, 0.0]),
    ),
    "raised": (
        np.array([0.0, -0.260, 0.720]),
        np.array([0.0, -0.260, 0.866]),
        matrix_to_quat(np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])),
    ),
}

# Hand-frame offsets of HAND, HAND_TIP and THUMB from the wrist, H units (hand length 0.108 H,
# Winter 2009; the thumb sits toward +y, the thumb side).
_HAND_OFFSETS = np.array([[0.040, 0.0, 0.0], [0.090, 0.0, 0.0], [0.045, 0.030, -0.010]])
_HAND_JOINTS = [J.HAND_RIGHT, J.HAND_TIP_RIGHT, J.THUMB_RIGHT]


def standing_skeleton(
    position_m: ArrayLike,
    yaw_rad: ArrayLike,
    height_m: ArrayLike = 1.70,
    right_arm: str = "down",
    hand_ypr_rad: ArrayLike = (0.0, 0.0, 0.0),
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A standing Kinect v2 skeleton and its right-hand orientation, in the world.

    Args:
        position_m: floor point under the pelvis, (..., 3) m (the feet stand at its z).
        yaw_rad: direction the person faces, (...) rad, CCW from east.
        height_m: standing height, (...) m, in (0.5, 2.5).
        right_arm: ``"down"`` (hanging), ``"forward"`` (forearm held forward, palm down: the pose
            of :mod:`vrloco_env.user.motion`) or ``"raised"`` (forearm vertical, palm forward).
        hand_ypr_rad: hand rotation relative to the arm pose, (..., 3) intrinsic ZYX
            [yaw, pitch, roll] rad in the hand frame; roll is the turn about the forearm. For
            ``"forward"`` this is motion.py's ``hand_ypr``. It moves the hand, hand-tip and thumb
            joints with the orientation.

    Returns:
        ``(joints, hand_quat)``: joints (..., 25, 3) m and the right hand's orientation
        (hand frame -> world) (..., 4).
    """
    pos = np.asarray(position_m, dtype=np.float64)
    if pos.ndim == 0 or pos.shape[-1] != 3 or not np.all(np.isfinite(pos)):
        raise ValueError(f"position_m must have shape (..., 3) and be finite, got {pos.shape}")
    yaw = np.asarray(yaw_rad, dtype=np.float64)
    height = np.asarray(height_m, dtype=np.float64)
    hand = np.asarray(hand_ypr_rad, dtype=np.float64)
    if hand.ndim == 0 or hand.shape[-1] != 3:
        raise ValueError(f"hand_ypr_rad must have shape (..., 3), got {hand.shape}")
    if not (np.all(np.isfinite(yaw)) and np.all(np.isfinite(hand))):
        raise ValueError("yaw_rad and hand_ypr_rad must be finite")
    if not np.all((height > 0.5) & (height < 2.5)):
        raise ValueError(f"height_m must lie in (0.5, 2.5) m, got {height}")
    if right_arm not in _ARM_POSES:
        raise ValueError(f"right_arm must be one of {sorted(_ARM_POSES)}, got {right_arm!r}")
    shape = np.broadcast_shapes(pos.shape[:-1], yaw.shape, height.shape, hand.shape[:-1])
    elbow, wrist, hand_pose = _ARM_POSES[right_arm]
    template = _TEMPLATE.copy()
    template[J.ELBOW_RIGHT] = elbow
    template[J.WRIST_RIGHT] = wrist
    zero = np.zeros(shape)
    q_yaw = quat_from_ypr(np.stack([zero + yaw, zero, zero], axis=-1))  # body -> world
    q_hand_body = quat_multiply(hand_pose, quat_from_ypr(np.broadcast_to(hand, (*shape, 3))))
    h = (zero + height)[..., None, None]
    body = np.broadcast_to(template, (*shape, NUM_JOINTS, 3)) * h
    offsets = quat_rotate(q_hand_body[..., None, :], _HAND_OFFSETS * h)
    body[..., _HAND_JOINTS, :] = body[..., [J.WRIST_RIGHT], :] + offsets
    joints = (
        quat_rotate(q_yaw[..., None, :], body) + np.broadcast_to(pos, (*shape, 3))[..., None, :]
    )
    return joints, quat_multiply(q_yaw, q_hand_body)
