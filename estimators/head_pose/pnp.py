"""Head pose from a head camera that sees landmarks with known 3D positions (the helmet-tracking
paper, visual part).

Source: the helmet-tracking paper section 2.2: pinhole camera (``fx, fy, cx, cy``, calibrated with
Zhang's method), feature matching with outlier removal by RANSAC, pose by PnP (DLT or EPnP). We use
OpenCV: ``cv2.solvePnPRansac(..., flags=cv2.SOLVEPNP_EPNP)`` (EPnP hypotheses on minimal
subsets, inliers by reprojection error), then a Levenberg-Marquardt refinement on the inliers
(``cv2.solvePnPRefineLM``). No distortion model: the images are taken as undistorted (the seed
calibrates and undistorts before matching).

Frames and conventions
----------------------
* Head body frame (:mod:`estimators.rotations`): x forward, y left, z up; the pose is the world
  position of the head origin (m, ENU) and the quaternion body -> world ``[w, x, y, z]``.
* OpenCV camera frame: x right, y down, z forward (optical axis). :data:`CAMERA_FROM_BODY` maps
  a vector from a camera-aligned body frame to it: ``camera z = body x``,
  ``camera x = -body y``, ``camera y = -body z``.
* OpenCV's ``rvec, tvec`` map world points into the camera: ``x_cam = R_cw X_world + t_cw``.
  :func:`camera_pose_to_body` turns ``(R_cw, t_cw)`` into the head pose and
  :func:`body_pose_to_camera` back.
* Mount: the camera may sit on the head rotated and offset. ``mount_quat`` rotates the camera's
  own body-aligned frame (x along the optical axis, y left, z up in the image) into the head
  frame; ``mount_offset`` is the optical centre in the head frame (m, the lever arm). Identity and
  zero by default: the camera centre is the head origin and looks along the head's x axis.

RANSAC in OpenCV draws its subsets from a fixed-seed generator, so :func:`solve_pose` is
deterministic for given inputs (no generator argument is needed).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.rotations import ensure_quaternion, matrix_to_quat, quat_to_matrix
from estimators.validation import check_in_range, check_value

__all__ = [
    "CAMERA_FROM_BODY",
    "CAMERA_FROM_BODY_QUAT",
    "REASON_BEHIND_CAMERA",
    "REASON_OK",
    "REASON_RANSAC_FAILED",
    "REASON_TOO_FEW_INLIERS",
    "REASON_TOO_FEW_LANDMARKS",
    "CameraIntrinsics",
    "NotEnoughLandmarks",
    "VisualPose",
    "VisualPoseBatch",
    "body_pose_to_camera",
    "camera_pose_to_body",
    "project_points",
    "solve_pose",
    "solve_poses",
]

#: Rotation matrix from a camera-aligned body frame (x forward, y left, z up) to the OpenCV camera
#: frame (x right, y down, z forward): ``v_cam = CAMERA_FROM_BODY @ v_body``.
CAMERA_FROM_BODY = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
CAMERA_FROM_BODY.flags.writeable = False
#: The same rotation as a quaternion ``[w, x, y, z]`` (``= [0.5, -0.5, 0.5, -0.5]``).
CAMERA_FROM_BODY_QUAT = matrix_to_quat(CAMERA_FROM_BODY)
CAMERA_FROM_BODY_QUAT.flags.writeable = False

#: Reason codes of :class:`VisualPoseBatch` (and ``NotEnoughLandmarks.reason``).
REASON_OK = 0
REASON_TOO_FEW_LANDMARKS = 1  # fewer than min_landmarks correspondences were given
REASON_RANSAC_FAILED = 2  # OpenCV found no consensus (or raised on degenerate geometry)
REASON_TOO_FEW_INLIERS = 3  # a consensus, but with fewer than min_landmarks inliers
REASON_BEHIND_CAMERA = 4  # the solution puts inliers behind the camera (a mirrored solution)

# LM refinement: OpenCV's default criteria (20 iterations, step below FLT_EPSILON) leave up to
# 3e-5 px (1e-6 m) on exact data, and an EPS criterion of 1e-10 stops nearly as early. A pure
# iteration count of 100 reaches 1e-13 px; OpenCV's LM still ends once a step stops reducing the
# error, so on noisy 40-point frames it costs the same (measured: 85 us per call either way).
_LM_CRITERIA = (cv2.TERM_CRITERIA_COUNT, 100, 0.0)


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics of an undistorted camera.

    Attributes:
        fx, fy: focal lengths, pixels (> 0).
        cx, cy: principal point, pixels (inside the image).
        width, height: image size, pixels (positive integers).
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def __post_init__(self) -> None:
        check_in_range(self, "width", 1, math.inf, "px", integer=True)
        check_in_range(self, "height", 1, math.inf, "px", integer=True)
        check_in_range(self, "fx", 0.0, math.inf, "px", lo_open=True)
        check_in_range(self, "fy", 0.0, math.inf, "px", lo_open=True)
        check_in_range(self, "cx", 0.0, self.width, allowed=f"in [0, width={self.width}] px")
        check_in_range(self, "cy", 0.0, self.height, allowed=f"in [0, height={self.height}] px")

    @property
    def matrix(self) -> NDArray[np.float64]:
        """The 3x3 camera matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


class NotEnoughLandmarks(ValueError):
    """Too few landmarks, or too few RANSAC inliers, for a pose.

    Attributes:
        seen: correspondences given.
        inliers: inliers found (0 if RANSAC did not run or failed).
        minimum: the required count.
        reason: one of the ``REASON_*`` codes.
    """

    def __init__(self, message: str, seen: int, inliers: int, minimum: int, reason: int) -> None:
        super().__init__(message)
        self.seen = seen
        self.inliers = inliers
        self.minimum = minimum
        self.reason = reason


@dataclass(frozen=True, eq=False)
class VisualPose:
    """A head pose from one camera frame.

    Attributes:
        position: (3,) world position of the head origin, m.
        quat: (4,) head attitude, body -> world ``[w, x, y, z]`` (``w >= 0``).
        inliers: (M,) indices of the correspondences used for the final pose.
        reprojection_rms_px: RMS reprojection error over the inliers, pixels.
        ok: True (a failure raises :class:`NotEnoughLandmarks` instead).
        rotation_cw: (3, 3) OpenCV world -> camera rotation.
        translation_cw: (3,) OpenCV world -> camera translation, m.
    """

    position: NDArray[np.float64]
    quat: NDArray[np.float64]
    inliers: NDArray[np.intp]
    reprojection_rms_px: float
    ok: bool
    rotation_cw: NDArray[np.float64]
    translation_cw: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class VisualPoseBatch:
    """Poses of F frames (:func:`solve_poses`): failed frames are NaN rows, flagged.

    Attributes:
        position: (F, 3) world head position, m; NaN where ``ok`` is False.
        quat: (F, 4) body -> world; NaN where ``ok`` is False.
        ok: (F,) bool, a pose was found.
        reason: (F,) int8 ``REASON_*`` code (``REASON_OK`` where ``ok``).
        n_landmarks: (F,) correspondences given.
        n_inliers: (F,) inliers used (0 on failure before RANSAC).
        reprojection_rms_px: (F,) RMS reprojection error, pixels; NaN where not ``ok``.
    """

    position: NDArray[np.float64]
    quat: NDArray[np.float64]
    ok: NDArray[np.bool_]
    reason: NDArray[np.int8]
    n_landmarks: NDArray[np.int64]
    n_inliers: NDArray[np.int64]
    reprojection_rms_px: NDArray[np.float64]


# ------------------------------------------------------------------------------------------------
# Frame helpers.
# ------------------------------------------------------------------------------------------------


def _mount(mount_quat: ArrayLike | None, mount_offset: ArrayLike | None) -> tuple[NDArray, NDArray]:
    if mount_quat is None:
        m = np.eye(3)
    else:
        m = quat_to_matrix(ensure_quaternion(mount_quat, "mount_quat"))
        if m.shape != (3, 3):
            raise ValueError(f"mount_quat must have shape (4,), got {np.shape(mount_quat)}")
    if mount_offset is None:
        o = np.zeros(3)
    else:
        o = np.asarray(mount_offset, dtype=np.float64)
        if o.shape != (3,) or not np.all(np.isfinite(o)):
            raise ValueError(f"mount_offset must be a finite (3,) vector (m), got {o!r}")
    return m, o


def camera_pose_to_body(
    rotation_cw: ArrayLike,
    translation_cw: ArrayLike,
    mount_quat: ArrayLike | None = None,
    mount_offset: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Head pose from an OpenCV camera pose ``x_cam = R_cw X_world + t_cw``.

    ``R(q_head) = R_cw^T C M^T`` and ``p_head = c - R(q_head) o``, with ``C`` =
    :data:`CAMERA_FROM_BODY`, ``M`` the mount rotation, ``o`` the mount offset and
    ``c = -R_cw^T t_cw`` the camera centre.

    Args:
        rotation_cw: (..., 3, 3) world -> camera rotation (``cv2.Rodrigues(rvec)[0]``).
        translation_cw: (..., 3) world -> camera translation, m (``tvec``).
        mount_quat: (4,) camera-aligned body frame -> head frame; None: identity.
        mount_offset: (3,) camera centre in the head frame, m; None: zero.

    Returns:
        ``(position (..., 3), quat (..., 4))`` of the head in the world (body -> world).
    """
    r = np.asarray(rotation_cw, dtype=np.float64)
    t = np.asarray(translation_cw, dtype=np.float64)
    if r.shape[-2:] != (3, 3) or t.shape != r.shape[:-1]:
        raise ValueError(
            f"rotation_cw must be (..., 3, 3) and translation_cw (..., 3), got {r.shape}, {t.shape}"
        )
    m, o = _mount(mount_quat, mount_offset)
    rt = np.swapaxes(r, -1, -2)
    centre = -np.einsum("...ij,...j->...i", rt, t)
    head = rt @ CAMERA_FROM_BODY @ m.T
    position = centre - head @ o
    return position, matrix_to_quat(head)


def body_pose_to_camera(
    position: ArrayLike,
    quat: ArrayLike,
    mount_quat: ArrayLike | None = None,
    mount_offset: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """OpenCV camera pose ``(R_cw, t_cw)`` of a head pose (inverse of :func:`camera_pose_to_body`).

    Args:
        position: (..., 3) head position in the world, m.
        quat: (..., 4) head attitude body -> world.
        mount_quat, mount_offset: camera mount (see the module docstring).

    Returns:
        ``(rotation_cw (..., 3, 3), translation_cw (..., 3))``.
    """
    p = np.asarray(position, dtype=np.float64)
    q = ensure_quaternion(quat, "quat")
    if p.shape[-1:] != (3,) or p.shape[:-1] != q.shape[:-1]:
        raise ValueError(f"position must be (..., 3) matching quat (..., 4), got {p.shape}")
    m, o = _mount(mount_quat, mount_offset)
    head = quat_to_matrix(q)
    centre = p + head @ o
    r_cw = CAMERA_FROM_BODY @ m.T @ np.swapaxes(head, -1, -2)
    return r_cw, -np.einsum("...ij,...j->...i", r_cw, centre)


def project_points(
    landmarks_world: ArrayLike,
    position: ArrayLike,
    quat: ArrayLike,
    intrinsics: CameraIntrinsics,
    mount_quat: ArrayLike | None = None,
    mount_offset: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Ideal pinhole projection of world points seen from a head pose.

    Args:
        landmarks_world: (K, 3) or (..., K, 3) world points, m.
        position: (..., 3) head position, m.
        quat: (..., 4) head attitude body -> world.
        intrinsics: the camera.
        mount_quat, mount_offset: camera mount.

    Returns:
        ``(pixels (..., K, 2), depth (..., K))``: pixel coordinates (u right, v down) and the
        depth along the optical axis, m. Points with ``depth <= 0`` are behind the camera (their
        pixels are meaningless; callers mask them), and pixels outside
        ``[0, width) x [0, height)`` are off the image.
    """
    x = np.asarray(landmarks_world, dtype=np.float64)
    if x.shape[-1:] != (3,):
        raise ValueError(f"landmarks_world must be (..., K, 3), got {x.shape}")
    r, t = body_pose_to_camera(position, quat, mount_quat, mount_offset)
    xc = np.einsum("...ij,...kj->...ki", r, x) + t[..., None, :]
    depth = xc[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = intrinsics.fx * xc[..., 0] / depth + intrinsics.cx
        v = intrinsics.fy * xc[..., 1] / depth + intrinsics.cy
    return np.stack([u, v], axis=-1), depth


# ------------------------------------------------------------------------------------------------
# PnP.
# ------------------------------------------------------------------------------------------------


def _check_correspondences(
    landmarks_world: ArrayLike, pixels: ArrayLike
) -> tuple[NDArray, NDArray]:
    x = np.asarray(landmarks_world, dtype=np.float64)
    u = np.asarray(pixels, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"landmarks_world must have shape (K, 3), got {x.shape}")
    if u.shape != (x.shape[0], 2):
        raise ValueError(f"pixels must have shape ({x.shape[0]}, 2) like landmarks, got {u.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(u))):
        raise ValueError("landmarks_world and pixels must be finite (drop undetected landmarks)")
    return x, u


def _residuals(x: NDArray, u: NDArray, k: NDArray, rvec: NDArray, tvec: NDArray) -> NDArray:
    proj, _ = cv2.projectPoints(x, rvec, tvec, k, None)
    return np.linalg.norm(proj.reshape(-1, 2) - u, axis=1)


def _ransac(x: NDArray, u: NDArray, k: NDArray, threshold: float, flags: int) -> tuple:
    """``cv2.solvePnPRansac`` with the minimal solver ``flags`` (OpenCV fits its RANSAC samples
    with EPnP, or with P3P/AP3P when asked); ``(False, None, None, None)`` where OpenCV raises on
    degenerate input."""
    try:
        return cv2.solvePnPRansac(
            x,
            u,
            k,
            None,
            iterationsCount=200,
            reprojectionError=threshold,
            confidence=0.999,
            flags=flags,
        )
    except cv2.error:
        return False, None, None, None


def solve_pose(
    landmarks_world: ArrayLike,
    pixels: ArrayLike,
    intrinsics: CameraIntrinsics,
    min_landmarks: int = 6,
    reprojection_px: float = 3.0,
    refine: bool = True,
    mount_quat: ArrayLike | None = None,
    mount_offset: ArrayLike | None = None,
) -> VisualPose:
    """Head pose from K landmark correspondences: EPnP inside RANSAC, then LM on the inliers.

    Steps: ``cv2.solvePnPRansac`` (EPnP, ``reprojection_px`` inlier threshold, 200 iterations,
    confidence 0.999). When that consensus holds fewer than half the points, RANSAC runs again
    with AP3P samples and the larger consensus wins; when all the landmarks lie in one plane it
    runs AP3P alone. A head camera near a wall often sees one wall only, and OpenCV's EPnP
    returns a wrong pose on coplanar points, even exact ones (decision; the test shows it),
    while its 4-point AP3P samples are fine on a plane. With
    ``refine``, ``cv2.solvePnPRefineLM`` on the inliers, then the inliers
    are re-selected with the refined pose (same threshold) and, if the set changed, refined once
    more. A solution that puts the inliers behind the camera is refused.

    ``min_landmarks`` defaults to 6, not EPnP's 4: OpenCV's RANSAC draws 5-point EPnP subsets,
    so with 5 or fewer points every subset fits exactly and a wrong match cannot be detected;
    the sixth point is the first that can disagree.

    Args:
        landmarks_world: (K, 3) world positions of the matched landmarks, m.
        pixels: (K, 2) their pixel coordinates (u right, v down), undistorted.
        intrinsics: the camera.
        min_landmarks: the least correspondences and inliers accepted (>= 4).
        reprojection_px: RANSAC inlier threshold, pixels (> 0).
        refine: run the LM refinement.
        mount_quat, mount_offset: camera mount on the head (module docstring).

    Returns:
        The :class:`VisualPose` of the head.

    Raises:
        NotEnoughLandmarks: fewer than ``min_landmarks`` correspondences or inliers, no RANSAC
            consensus, or a solution behind the camera; the message gives the counts.
        ValueError: malformed input (shapes, non-finite values, bad parameters).
    """
    x, u = _check_correspondences(landmarks_world, pixels)
    check_value(
        "min_landmarks",
        min_landmarks,
        4,
        math.inf,
        integer=True,
        allowed="an integer >= 4 (EPnP needs 4)",
    )
    n_min = int(min_landmarks)
    check_value("reprojection_px", reprojection_px, 0.0, math.inf, "px", lo_open=True)
    _mount(mount_quat, mount_offset)  # validate before any work
    n = x.shape[0]
    if n < n_min:
        raise NotEnoughLandmarks(
            f"saw {n} landmarks, need at least {n_min} for a pose",
            n,
            0,
            n_min,
            REASON_TOO_FEW_LANDMARKS,
        )
    k = intrinsics.matrix
    centred = x - x.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[2] <= 1e-9 * max(sv[0], 1e-12):  # one plane (one wall): EPnP samples are all wrong
        found, rvec, tvec, inl = False, None, None, None
    else:
        found, rvec, tvec, inl = _ransac(x, u, k, float(reprojection_px), cv2.SOLVEPNP_EPNP)
    if not found or inl is None or inl.size < max(n_min, n // 2):
        # EPnP's 5-point samples from one wall are coplanar, where OpenCV's EPnP returns a wrong
        # pose even on exact data (tests/test_estimators/head_pose/test_pnp.py): try AP3P's 4-point
        # samples.
        retry = _ransac(x, u, k, float(reprojection_px), cv2.SOLVEPNP_AP3P)
        if retry[0] and retry[3] is not None and (inl is None or retry[3].size > inl.size):
            found, rvec, tvec, inl = retry
    if not found or inl is None:
        raise NotEnoughLandmarks(
            f"RANSAC found no consensus among {n} landmarks (need {n_min} inliers)",
            n,
            0,
            n_min,
            REASON_RANSAC_FAILED,
        )
    inliers = np.sort(inl.ravel().astype(np.intp))
    if inliers.size < n_min:
        raise NotEnoughLandmarks(
            f"only {inliers.size} of {n} landmarks are RANSAC inliers, need at least {n_min}",
            n,
            inliers.size,
            n_min,
            REASON_TOO_FEW_INLIERS,
        )
    rvec = rvec.astype(np.float64)
    tvec = tvec.astype(np.float64)
    if refine:
        for _ in range(2):
            rvec, tvec = cv2.solvePnPRefineLM(
                x[inliers], u[inliers], k, None, rvec, tvec, criteria=_LM_CRITERIA
            )
            again = np.flatnonzero(_residuals(x, u, k, rvec, tvec) < reprojection_px)
            if again.size < n_min:
                raise NotEnoughLandmarks(
                    f"only {again.size} of {n} landmarks are inliers after refinement, "
                    f"need at least {n_min}",
                    n,
                    again.size,
                    n_min,
                    REASON_TOO_FEW_INLIERS,
                )
            if np.array_equal(again, inliers):
                break
            inliers = again
    r_cw = cv2.Rodrigues(rvec)[0]
    t_cw = tvec.ravel()
    depth = x[inliers] @ r_cw[2] + t_cw[2]
    if np.count_nonzero(depth > 0) < n_min:
        raise NotEnoughLandmarks(
            f"the pose puts {np.count_nonzero(depth <= 0)} of {inliers.size} inliers behind the "
            f"camera ({n} landmarks seen, need {n_min} in front)",
            n,
            inliers.size,
            n_min,
            REASON_BEHIND_CAMERA,
        )
    res = _residuals(x[inliers], u[inliers], k, rvec, tvec)
    position, quat = camera_pose_to_body(r_cw, t_cw, mount_quat, mount_offset)
    return VisualPose(
        position=position,
        quat=quat,
        inliers=inliers,
        reprojection_rms_px=float(np.sqrt(np.mean(res**2))),
        ok=True,
        rotation_cw=r_cw,
        translation_cw=t_cw,
    )


def solve_poses(
    frames: Sequence[tuple[ArrayLike, ...]],
    intrinsics: CameraIntrinsics,
    min_landmarks: int = 6,
    reprojection_px: float = 3.0,
    refine: bool = True,
    mount_quat: ArrayLike | None = None,
    mount_offset: ArrayLike | None = None,
) -> VisualPoseBatch:
    """:func:`solve_pose` over F frames, with failures flagged instead of raised.

    OpenCV solves one frame per call, so this loops over frames in Python. A frame whose pose
    fails (too few landmarks or inliers, no consensus, behind the camera) gets a NaN row, ``ok``
    False and its reason code; nothing is raised for those, so a sensor stream with dropouts can
    be solved in one call. Malformed input (wrong shapes, non-finite landmark positions) still
    raises ValueError: that is a bug, not a dropout.

    Args:
        frames: F tuples ``(landmarks_world (K, 3), pixels (K, 2))`` or
            ``(landmarks_world, pixels, detected (K,) bool)``; K may differ per frame. With a
            ``detected`` mask, only those rows are used (pixels of the others may be NaN).
        intrinsics, min_landmarks, reprojection_px, refine, mount_quat, mount_offset: as in
            :func:`solve_pose`.

    Returns:
        A :class:`VisualPoseBatch` of F rows.
    """
    f = len(frames)
    out = VisualPoseBatch(
        position=np.full((f, 3), np.nan),
        quat=np.full((f, 4), np.nan),
        ok=np.zeros(f, dtype=bool),
        reason=np.zeros(f, dtype=np.int8),
        n_landmarks=np.zeros(f, dtype=np.int64),
        n_inliers=np.zeros(f, dtype=np.int64),
        reprojection_rms_px=np.full(f, np.nan),
    )
    for i, frame in enumerate(frames):
        if len(frame) not in (2, 3):
            raise ValueError(
                f"frames[{i}] must be (landmarks_world, pixels) or (landmarks_world, pixels, "
                f"detected), got {len(frame)} items"
            )
        x = np.asarray(frame[0], dtype=np.float64)
        u = np.asarray(frame[1], dtype=np.float64)
        if len(frame) == 3:
            det = np.asarray(frame[2])
            if det.dtype != bool or det.shape != x.shape[:1]:
                raise ValueError(
                    f"frames[{i}] detected must be a ({x.shape[0]},) bool mask, got "
                    f"{det.dtype} {det.shape}"
                )
            x, u = x[det], u[det]
        out.n_landmarks[i] = x.shape[0] if x.ndim == 2 else 0
        try:
            pose = solve_pose(
                x, u, intrinsics, min_landmarks, reprojection_px, refine, mount_quat, mount_offset
            )
        except NotEnoughLandmarks as exc:
            out.reason[i] = exc.reason
            out.n_inliers[i] = exc.inliers
            continue
        out.position[i] = pose.position
        out.quat[i] = pose.quat
        out.ok[i] = True
        out.n_inliers[i] = pose.inliers.size
        out.reprojection_rms_px[i] = pose.reprojection_rms_px
    return out
