"""Visual-inertial head tracking (the helmet-tracking paper) for B users: head camera -> PnP ->
Kalman fusion.

This module composes the pieces, it holds no estimator logic::

    true head pose at the IMU rate -> HeadCamera frames at the camera trigger samples
        -> estimators.head_pose.pnp.solve_poses (OpenCV solvePnPRansac, EPnP), one frame per call
        -> estimators.head_pose.visual_inertial.VisualInertialFilter (strapdown prediction at every
        IMU
           sample, visual pose update after each frame's trigger sample)

Camera timing. The camera is triggered by the IMU clock, as on a hardware-synchronised helmet:
frame k is exposed at the IMU sample ``ceil(k * imu_rate / camera_rate)`` (counting samples from
1), so a 120 Hz camera beside a 1 kHz IMU takes frames 8 or 9 samples apart, 120 per second on
average, and the filter applies each frame right after its sample with no interpolation.

Start. :meth:`VisualInertialTracker.reset` starts a user's filter at a given pose, standing
still: the start marker of the tracked space, where a headset defines its origin. The filter's
initial sigmas (:class:`~estimators.head_pose.visual_inertial.VioConfig`) say how well that is
known.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import rotations as rot
from estimators.batching import stream_rows
from estimators.head_pose.pnp import CameraIntrinsics, solve_poses
from estimators.head_pose.visual_inertial import VioConfig, VisualInertialFilter
from estimators.validation import check_in_range
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.camera import CameraFrames, CameraSpec, HeadCamera

__all__ = [
    "PnpParams",
    "TrackedChunk",
    "VisualInertialTracker",
    "VisualPoses",
    "camera_intrinsics",
    "frame_triggers",
    "pnp_mount",
    "solve_frames",
]


@dataclass(frozen=True)
class PnpParams:
    """How frames are turned into poses (:func:`estimators.head_pose.pnp.solve_pose`).

    Attributes:
        min_landmarks: fewest correspondences and inliers for a pose (>= 4; 6 lets RANSAC
            detect a wrong match, see ``solve_pose``).
        reprojection_px: RANSAC inlier threshold (px).
    """

    min_landmarks: int = 6
    reprojection_px: float = 3.0

    def __post_init__(self) -> None:
        check_in_range(self, "min_landmarks", 4, math.inf, integer=True)
        check_in_range(self, "reprojection_px", 0.0, 50.0, "px", lo_open=True)


@dataclass(frozen=True)
class VisualPoses:
    """Poses from M frames of B users (NaN rows where ``ok`` is False, with a reason code).

    Attributes:
        position: (B, M, 3) head positions, m. quat: (B, M, 4) body -> world.
        ok: (B, M) bool. reason: (B, M) int8 ``estimators.head_pose.pnp.REASON_*``.
        n_inliers: (B, M) inliers of each pose.
    """

    position: NDArray[np.float64]
    quat: NDArray[np.float64]
    ok: NDArray[np.bool_]
    reason: NDArray[np.int8]
    n_inliers: NDArray[np.int64]


@dataclass(frozen=True)
class TrackedChunk:
    """One chunk of N IMU samples through the tracker.

    Attributes:
        position: (B, N, 3) estimated head positions after each sample (and its frame), m.
        quat: (B, N, 4) estimated attitudes, body -> world.
        frame_sample: (M,) index in the chunk of each camera frame's trigger sample.
        frames: the camera frames (M of them).
        poses: their PnP poses.
        status: (B, M) the filter's verdict on each frame (``STATUS_*`` of
            :mod:`estimators.head_pose.visual_inertial`).
    """

    position: NDArray[np.float64]
    quat: NDArray[np.float64]
    frame_sample: NDArray[np.intp]
    frames: CameraFrames | None
    poses: VisualPoses
    status: NDArray[np.int8]


def camera_intrinsics(spec: CameraSpec) -> CameraIntrinsics:
    """The estimator-side description of a :class:`CameraSpec`."""
    return CameraIntrinsics(spec.fx, spec.fy, spec.cx, spec.cy, spec.width, spec.height)


def pnp_mount(spec: CameraSpec) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(mount_quat, mount_offset)`` for :func:`estimators.head_pose.pnp.solve_pose` from the
    camera's mount (a downward tilt is a positive pitch about the head's y axis)."""
    q = rot.quat_from_ypr([0.0, math.radians(spec.mount_tilt_deg), 0.0])
    return q, np.asarray(spec.mount_offset_m, dtype=np.float64)


def frame_triggers(first_sample: int, n: int, imu_rate_hz: float, camera_rate_hz: float):
    """Indices (M,) within a chunk of ``n`` samples, whose first sample is number
    ``first_sample + 1`` since the clock started, of the samples that trigger a frame."""
    s = first_sample + np.arange(n + 1)  # samples first_sample .. first_sample + n
    k = np.floor(s * (camera_rate_hz / imu_rate_hz) + 1e-9)
    return np.flatnonzero(np.diff(k) > 0).astype(np.intp)


def solve_frames(
    frames: CameraFrames,
    landmarks: NDArray[np.float64],
    spec: CameraSpec,
    pnp: PnpParams = PnpParams(),
) -> VisualPoses:
    """PnP on every frame of every user: the extracted features with the landmark the matcher
    gave them (wrong matches included, for RANSAC to reject).

    Args:
        frames: B users x M frames from :meth:`HeadCamera.capture`.
        landmarks: (B, K, 3) the landmark array the frames index (m).
        spec: the camera.
        pnp: solver settings.
    """
    b, m = frames.extracted.shape[:2]
    intr = camera_intrinsics(spec)
    mq, mo = pnp_mount(spec)
    out = VisualPoses(
        position=np.full((b, m, 3), np.nan),
        quat=np.full((b, m, 4), np.nan),
        ok=np.zeros((b, m), bool),
        reason=np.zeros((b, m), np.int8),
        n_inliers=np.zeros((b, m), np.int64),
    )
    for i in range(b):  # OpenCV solves one frame per call
        per_frame = []
        for j in range(m):
            sel = frames.extracted[i, j]
            per_frame.append((landmarks[i, frames.matched_id[i, j, sel]], frames.pixels[i, j, sel]))
        res = solve_poses(
            per_frame, intr, pnp.min_landmarks, pnp.reprojection_px, mount_quat=mq, mount_offset=mo
        )
        out.position[i], out.quat[i], out.ok[i] = res.position, res.quat, res.ok
        out.reason[i], out.n_inliers[i] = res.reason, res.n_inliers
    return out


class VisualInertialTracker:
    """Head camera + PnP + visual-inertial filter for B users, one IMU chunk at a time.

    Args:
        batch_size: B.
        imu_rate_hz: IMU rate (Hz).
        camera: the head camera (its ``rate_hz`` <= the IMU rate).
        config: the filter's parameters.
        rng: the users' random streams (the camera's noise).
        pnp: PnP settings.
    """

    def __init__(
        self,
        batch_size: int,
        imu_rate_hz: float,
        camera: CameraSpec,
        config: VioConfig,
        rng: BatchRng,
        pnp: PnpParams = PnpParams(),
    ) -> None:
        if camera.rate_hz > imu_rate_hz:
            raise ValueError(
                f"the camera rate ({camera.rate_hz} Hz) must not exceed the IMU rate "
                f"({imu_rate_hz} Hz): frames are triggered by IMU samples"
            )
        self.batch_size = b = batch_size
        self.imu_rate_hz = float(imu_rate_hz)
        self.spec = camera
        self.pnp = pnp
        self.camera = HeadCamera(camera, rng)
        self.filter = VisualInertialFilter(b, imu_rate_hz, config)
        k = camera.max_landmarks
        self.landmarks = np.zeros((b, k, 3))
        self.normals = np.zeros((b, k, 3))
        self.normals[..., 0] = 1.0
        self.mask = np.zeros((b, k), bool)
        self.samples_seen = 0

    def set_landmarks(self, user: int, points: ArrayLike, normals: ArrayLike) -> None:
        """Give user ``user`` its room's landmarks (K, 3) m and their walls' inward normals."""
        p = np.asarray(points, dtype=np.float64)
        nrm = np.asarray(normals, dtype=np.float64)
        k = p.shape[0]
        if p.shape != (k, 3) or nrm.shape != (k, 3) or k > self.spec.max_landmarks:
            raise ValueError(
                f"points and normals must be (K, 3) with K <= CameraSpec.max_landmarks = "
                f"{self.spec.max_landmarks}, got {p.shape} and {nrm.shape}"
            )
        self.landmarks[user] = 0.0
        self.landmarks[user, :k] = p
        self.normals[user] = [1.0, 0.0, 0.0]
        self.normals[user, :k] = nrm
        self.mask[user] = False
        self.mask[user, :k] = True

    def reset(self, users: ArrayLike | None, position: ArrayLike, quat: ArrayLike) -> None:
        """Restart users (indices or a (B,) mask; None: all) standing still at the given pose
        (rows for the reset users: (U, 3) m and (U, 4) body -> world)."""
        b = self.batch_size
        rows = stream_rows(users, b)
        p = np.zeros((b, 3))
        q = np.tile([1.0, 0.0, 0.0, 0.0], (b, 1))
        p[rows] = np.broadcast_to(np.asarray(position, np.float64), (rows.size, 3))
        q[rows] = np.broadcast_to(np.asarray(quat, np.float64), (rows.size, 4))
        mask = np.zeros(b, bool)
        mask[rows] = True
        self.filter.reset(p, np.zeros((b, 3)), q, mask=mask)
        if rows.size == b:
            self.camera.reset()
        else:
            self.camera.reset(users=rows)

    def step(
        self,
        t: NDArray[np.float64],
        gyr: NDArray[np.float64],
        acc: NDArray[np.float64],
        pos: NDArray[np.float64],
        quat: NDArray[np.float64],
        omega: NDArray[np.float64],
    ) -> TrackedChunk:
        """Track N IMU samples: camera frames at the trigger samples, PnP, filter.

        Args:
            t: (N,) sample times, s. gyr, acc: (B, N, 3) IMU samples (rad/s, m/s^2).
            pos, quat, omega: (B, N, ...) the true head pose and body rate at the samples (what
                the camera sees), m, body -> world, rad/s.
        """
        n = gyr.shape[1]
        idx = frame_triggers(self.samples_seen, n, self.imu_rate_hz, self.spec.rate_hz)
        self.samples_seen += n
        b, m = self.batch_size, idx.size
        if m:
            frames = self.camera.capture(
                t[idx],
                pos[:, idx],
                quat[:, idx],
                omega[:, idx],
                self.landmarks,
                mask=self.mask,
                normals=self.normals,
            )
            poses = solve_frames(frames, self.landmarks, self.spec, self.pnp)
        else:
            frames = None
            poses = VisualPoses(
                np.zeros((b, 0, 3)),
                np.zeros((b, 0, 4)),
                np.zeros((b, 0), bool),
                np.zeros((b, 0), np.int8),
                np.zeros((b, 0), np.int64),
            )
        p, q, status = self.filter.process(gyr, acc, idx, poses.position, poses.quat, poses.ok)
        return TrackedChunk(p, q, idx, frames, poses, status)
