"""Where the head camera is and what it sees: its pose on the head (:func:`camera_pose`,
:func:`head_pose_from_camera`) and the pinhole projection (:func:`project`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.rotations import (
    ensure_quaternion,
    quat_conjugate,
    quat_multiply,
    quat_rotate,
    quat_rotate_inverse,
)
from vrloco_env.sensors.camera.spec import BODY_FROM_CAMERA, CameraSpec, _mount_quat

__all__ = ["BODY_FROM_CAMERA", "camera_pose", "head_pose_from_camera", "project"]


def camera_pose(
    spec: CameraSpec, pos: ArrayLike, quat: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """World pose of the camera for head poses.

    Args:
        spec: the camera (its mount is used).
        pos: head positions in the world, (..., 3) m.
        quat: head orientations body -> world, (..., 4) [w, x, y, z].

    Returns:
        ``(cam_pos, cam_quat)``: camera centre in the world (..., 3) m and the quaternion rotating
        camera-frame (OpenCV) vectors into the world, (..., 4).
    """
    q = ensure_quaternion(quat, "quat")
    p = np.asarray(pos, dtype=np.float64)
    cam_pos = p + quat_rotate(q, np.asarray(spec.mount_offset_m, dtype=np.float64))
    return cam_pos, quat_multiply(q, _mount_quat(spec))


def head_pose_from_camera(
    spec: CameraSpec, cam_pos: ArrayLike, cam_quat: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Head pose from a camera pose (the inverse of :func:`camera_pose`), e.g. after PnP.

    Args:
        spec: the camera (its mount is used).
        cam_pos: camera centres in the world, (..., 3) m.
        cam_quat: camera (OpenCV frame) -> world quaternions, (..., 4).

    Returns:
        ``(pos, quat)``: head positions (..., 3) m and body -> world quaternions (..., 4).
    """
    qc = ensure_quaternion(cam_quat, "cam_quat")
    q = quat_multiply(qc, quat_conjugate(_mount_quat(spec)))
    pos = np.asarray(cam_pos, dtype=np.float64) - quat_rotate(
        q, np.asarray(spec.mount_offset_m, dtype=np.float64)
    )
    return pos, q


def project(
    spec: CameraSpec, pos: ArrayLike, quat: ArrayLike, points: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Noiseless pinhole projection of world points for head poses (no visibility test).

    Args:
        spec: the camera.
        pos: head positions, (..., 3) m.
        quat: head orientations body -> world, (..., 4).
        points: world points, broadcastable against ``pos[..., None, :]``: (..., K, 3) m.

    Returns:
        ``(uv, xyz)``: pixels (..., K, 2) px (``inf``/NaN-free only where ``Z > 0``; behind the
        camera the division is still done) and camera-frame points (..., K, 3) m.
    """
    cam_pos, cam_q = camera_pose(spec, pos, quat)
    d = np.asarray(points, dtype=np.float64) - cam_pos[..., None, :]
    xyz = quat_rotate_inverse(cam_q[..., None, :], d)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = spec.fx * (xyz[..., 0] / xyz[..., 2]) + spec.cx
        v = spec.fy * (xyz[..., 1] / xyz[..., 2]) + spec.cy
    return np.stack([u, v], axis=-1), xyz
