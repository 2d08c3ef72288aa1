"""What the Kinect v2 delivers (:class:`KinectFrames`, :class:`KinectTruth`) and the frames it is
in: camera space, the SDK's wrist joint frame (:data:`HAND_FROM_SDK_WRIST`) and the conversions."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.rotations import (
    matrix_to_quat,
    quat_conjugate,
    quat_from_ypr,
    quat_multiply,
    quat_rotate,
    quat_rotate_inverse,
)
from vrloco_env.sensors.kinect.spec import KinectSpec

__all__ = [
    "HAND_FROM_SDK_WRIST",
    "KinectFrames",
    "KinectTruth",
    "camera_quat",
    "camera_to_world",
    "hand_to_sdk_wrist",
    "quat_camera_to_world",
    "quat_world_to_camera",
    "sdk_wrist_to_hand",
    "world_to_camera",
]

#: Rotation from the SDK's wrist joint frame to our hand frame: SDK x (binormal) = hand z (back of
#: hand), SDK y (bone) = hand x (forearm), SDK z (normal) = hand y (thumb side). [w, x, y, z].
HAND_FROM_SDK_WRIST = matrix_to_quat(np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]))

# Camera axes in the sensor's own forward-left-up frame: camera x = left, y = up, z = forward.
_SENSOR_FROM_CAMERA = matrix_to_quat(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))


def camera_quat(spec: KinectSpec) -> NDArray[np.float64]:
    """Orientation of camera space in the world: the quaternion rotating camera -> world, (4,)."""
    mount = quat_from_ypr([spec.camera_yaw_rad, -math.radians(spec.camera_tilt_deg), 0.0])
    return quat_multiply(mount, _SENSOR_FROM_CAMERA)


def world_to_camera(spec: KinectSpec, points_world: ArrayLike) -> NDArray[np.float64]:
    """World points (..., 3) m -> Kinect camera-space points (..., 3) m."""
    p = np.asarray(points_world, dtype=np.float64)
    return quat_rotate_inverse(camera_quat(spec), p - np.asarray(spec.camera_position_m))


def camera_to_world(spec: KinectSpec, points_cam: ArrayLike) -> NDArray[np.float64]:
    """Kinect camera-space points (..., 3) m -> world points (..., 3) m."""
    p = np.asarray(points_cam, dtype=np.float64)
    return quat_rotate(camera_quat(spec), p) + np.asarray(spec.camera_position_m)


def quat_world_to_camera(spec: KinectSpec, q_world: ArrayLike) -> NDArray[np.float64]:
    """Orientation (frame -> world) (..., 4) -> the same frame's orientation in camera space."""
    return quat_multiply(quat_conjugate(camera_quat(spec)), np.asarray(q_world, dtype=np.float64))


def quat_camera_to_world(spec: KinectSpec, q_cam: ArrayLike) -> NDArray[np.float64]:
    """Orientation (frame -> camera) (..., 4) -> the same frame's orientation in the world."""
    return quat_multiply(camera_quat(spec), np.asarray(q_cam, dtype=np.float64))


def hand_to_sdk_wrist(q_hand: ArrayLike) -> NDArray[np.float64]:
    """Hand-frame orientation (..., 4) -> the SDK's wrist joint frame (bone on +y), same space."""
    return quat_multiply(np.asarray(q_hand, dtype=np.float64), HAND_FROM_SDK_WRIST)


def sdk_wrist_to_hand(q_sdk: ArrayLike) -> NDArray[np.float64]:
    """SDK wrist joint orientation (bone on +y) (..., 4) -> our hand frame (forearm on +x)."""
    return quat_multiply(np.asarray(q_sdk, dtype=np.float64), quat_conjugate(HAND_FROM_SDK_WRIST))


@dataclass
class KinectTruth:
    """Ground truth for the target user, in camera space, at delivery time (not delayed).

    Attributes:
        slot: (B, M) int64 body slot of the target user (fixed for a session).
        joints: (B, M, 25, 3) true joint positions, m (whether in view or not).
        hand_quat: (B, M, 4) true right-wrist orientation, SDK wrist frame -> camera space.
    """

    slot: NDArray[np.int64]
    joints: NDArray[np.float64]
    hand_quat: NDArray[np.float64]


@dataclass
class KinectFrames:
    """What the Kinect v2 delivers, batched: B users, M frames, K = 6 body slots.

    Attributes:
        t: (B, M) delivery time of each frame, s (the ``t`` passed to :meth:`KinectV2.capture`).
        body_id: (B, M, K) int64 tracking id, 0 where the slot holds no tracked body.
        body_tracked: (B, M, K) bool.
        joints: (B, M, K, 25, 3) camera-space joint positions, m; NaN where not tracked.
        joint_state: (B, M, K, 25) int8, NOT_TRACKED / INFERRED / TRACKED
            (vrloco_env.user.skeleton).
        hand_quat: (B, M, K, 4) noisy right-wrist orientation [w, x, y, z], SDK wrist frame
            (bone on +y) -> camera space (see the module docstring); NaN where the body or its
            wrist is not tracked.
        truth: ground truth of the target user.
    """

    t: NDArray[np.float64]
    body_id: NDArray[np.int64]
    body_tracked: NDArray[np.bool_]
    joints: NDArray[np.float64]
    joint_state: NDArray[np.int8]
    hand_quat: NDArray[np.float64]
    truth: KinectTruth = field(repr=False)

    @staticmethod
    def concatenate(chunks: Sequence[KinectFrames]) -> KinectFrames:
        """Join captures along the frame axis (axis 1)."""
        if not chunks:
            raise ValueError("chunks must hold at least one KinectFrames")

        def cat(get):
            return np.concatenate([get(c) for c in chunks], axis=1)

        truth = KinectTruth(
            **{f.name: cat(lambda c, n=f.name: getattr(c.truth, n)) for f in fields(KinectTruth)}
        )
        return KinectFrames(
            **{
                f.name: cat(lambda c, n=f.name: getattr(c, n))
                for f in fields(KinectFrames)
                if f.name != "truth"
            },
            truth=truth,
        )
