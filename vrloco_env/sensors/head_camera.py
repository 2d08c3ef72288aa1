"""Head camera model for seed 004's visual helmet pose: wall landmarks seen by a pinhole camera.

A camera on the helmet looks at landmarks with known 3-D positions on the room's inner walls
(:attr:`vrloco_env.world.layout.Layout.landmarks`). For B users and N frames at once,
:class:`HeadCamera` projects every landmark, decides which ones are geometrically visible, which of
those a feature detector extracts, which extracted features a matcher assigns to the right landmark,
and adds pixel noise. The output (:class:`CameraFrames`) is what a PnP solver (OpenCV
``solvePnPRansac``) takes: 2-D pixels with the landmark index the matcher assigned, outliers
included.

Frames and conventions
----------------------
*World*: ENU, z up (:mod:`estimators.rotations`). *Head body frame*: x forward, y left, z up;
``quat`` rotates body -> world. *Camera frame*: OpenCV's, x right, y down, z forward (optical
axis). Without a mount tilt the camera axes are camera z = body x, camera x = -body y, camera
y = -body z (:data:`BODY_FROM_CAMERA`). The mount (:attr:`CameraSpec.mount_offset_m`, body frame, m;
:attr:`CameraSpec.mount_tilt_deg`, positive tilts the optical axis down, a rotation about body +y)
places the camera on the helmet; :func:`camera_pose` gives the camera's world pose, and
:func:`head_pose_from_camera` turns a camera pose (e.g. from PnP) back into a head pose.

Pinhole model, no lens distortion (the images are taken as rectified; decision, seed 004 gives
only fx, fy, cx, cy): ``u = fx X / Z + cx``, ``v = fy Y / Z + cy`` for a camera-frame point
``(X, Y, Z)``, pixel centres at integer coordinates (OpenCV), so the image spans
``[-0.5, width - 0.5] x [-0.5, height - 0.5]`` px. The defaults (640 x 480 px, fx = fy = 460 px,
principal point at the image centre) give a 69.6 deg x 55.1 deg field of view, a typical helmet
tracking camera. :attr:`CameraSpec.camera_matrix` is OpenCV's K; ``fx, fy, cx, cy, width,
height`` are plain fields, so ``estimators.visual_pose.CameraIntrinsics(spec.fx, spec.fy,
spec.cx, spec.cy, spec.width, spec.height)`` describes the same camera.

Per landmark and frame (all decisions, seed 004 states only the outcome rates)
-------------------------------------------------------------------------------
1. *Visible* (geometry): in front of the camera with depth ``Z >= min_range_m``, distance from the
   camera ``<= max_range_m``, projection inside the image, not flagged ``blocked`` by the caller
   (e.g. an obstacle in the line of sight, which this model does not ray-cast), and — where wall
   normals are given — seen from the room side of its wall at less than ``max_view_angle_deg``
   from the wall normal (a marker seen edge-on is not detectable; 80 deg by default). Without
   normals the last test is skipped: a head inside the room sees every wall face from its front.
2. *Occluded*: the ``occlusion`` condition puts an occluder in the image — a vertical band of
   ``occluder_fraction`` of the image width (a person, a door frame, a hand in front of the lens)
   whose centre drifts as a random walk of ``occluder_drift_px_per_sqrt_s`` px/sqrt(s), folded
   back at the image borders so that the band always lies fully inside the image. Visible
   landmarks under it are not extracted.
3. *Blur*: the image of a landmark moves, during the exposure, with the rotational optical flow
   ``u' = fx (x y wx - (1 + x^2) wy + y wz)``, ``v' = fy ((1 + y^2) wx - x y wy - x wz)``
   (``x, y`` normalised image coordinates, ``w`` the angular rate in the camera frame); the blur
   length is ``L = |(u', v')| * exposure_s`` px. This is ``|w_perp| * exposure * f`` at the image
   centre, and adds the roll-induced streak off centre. Translation is neglected (at 1.5 m/s and
   2 m it is 0.75 rad/s-equivalent at most, usually far less than head rotation). The frame time
   is the middle of the exposure, so the streak's centroid is the true projection (no bias).
4. *Extracted* (detection): with probability
   ``extraction_prob * exp(-max(L - blur_free_px, 0) / blur_scale_px)`` for a visible,
   unoccluded landmark: a detector tolerates ``blur_free_px`` of smear, then loses corners
   exponentially (engineering choice). Over a room's landmarks, turning about the vertical, the
   motion_blur preset then extracts ~71 % at 1 rad/s and ~24 % at 3 rad/s, the ideal one ~83 %
   at 3 rad/s (95 % when still).
5. *Pixel noise*: independent Gaussian per axis with std
   ``sqrt(pixel_noise_px^2 + (blur_noise_per_px * L)^2)``: the corner localisation error plus the
   centroid uncertainty of a streak (a uniform streak of length L has std L / sqrt(12), the
   default factor). A noisy pixel may fall up to a few px outside the image; it is kept.
6. *Matched*: an extracted feature is given its own landmark index with probability ``match_prob``;
   otherwise (a wrong match) the index of one of its ``match_neighbors`` nearest other landmarks
   (3-D distance; on the wall grid these are the markers next to it, the ones whose descriptors a
   real matcher confuses), chosen uniformly. The pixel stays where the true landmark projects.
   Where a landmark has no other valid landmark, the match cannot go wrong.

Conditions (:data:`CONDITIONS`, :func:`camera_spec`), calibrated to seed 004's rates for a still
head (motion lowers extraction further through blur):

===========  ========== ======== ======= =========== ==================================
condition    extraction matching  noise   exposure    other
===========  ========== ======== ======= =========== ==================================
ideal        0.95       0.90     0.5 px  2 ms
low_light    0.70       0.85     1.5 px  4 ms        dim, noisy corners, longer exposure
occlusion    0.95       0.60     0.5 px  2 ms        band over 30 % of the width
motion_blur  0.95       0.90     0.5 px  8.3 ms      full frame-time exposure
===========  ========== ======== ======= =========== ==================================

Seed 004 reports extraction 95 % ideal / ~70 % low light and matching 90 % / ~60 % with
occlusion. Matching in low light is not reported: 0.85 (engineering choice, dim descriptors are
a little less distinctive). Under occlusion, :func:`extraction_rate` (extracted / visible) is about
``0.95 * (1 - 0.3)``, about 0.67, since the occluder hides visible landmarks; among the unoccluded
ones it stays 0.95. :func:`matching_rate` equals ``match_prob`` in expectation, whatever the
geometry. 0.5 px is the usual sub-pixel corner accuracy; 1.5 px in low light (gain noise). The
exposure of the motion_blur preset is the whole 1/120 s frame time, the longest a 120 Hz camera
allows (a fixed long exposure, or an auto-exposure opening up indoors); low light lengthens the
exposure to 4 ms, so it blurs more than ideal when the head turns.

The extraction and matching probabilities are therefore the model's inputs, set to the paper's
rates, not results. The pixel noise is not the paper's: with it and the ~17 landmarks a frame of
the default room extracts, PnP is about 3x more accurate than seed 004's +-0.05 m / +-1 deg.
Seed 004's experiment (:mod:`agents.experiments.vio`) scales every preset's noise by a factor
calibrated to the paper's visual-only error; the presets here (and the env's camera) keep the
sub-pixel corner accuracy.

Randomness
----------
Every number comes from the :class:`~vrloco_env.batch_rng.BatchRng` passed in. :meth:`HeadCamera.
reset` draws one normal per reset user (the occluder's start); :meth:`HeadCamera.capture` draws a
fixed block of ``1 + 3 * max_landmarks`` normals per frame and user (occluder step, then per
landmark slot: one uniform for detection and matching — given a detection ``u < p``, ``u / p`` is
again uniform and decides the match —, pixel noise u, pixel noise v), whatever K the landmark array
has. So a batch of B users equals B single runs bit for bit — also when a single run passes only
its own landmarks and the batch pads them (padding at the end) — and a capture split into chunks
equals one capture. The draws are about a third of the cost (a capture of 4 frames for 64 users
and 96 landmarks takes ~4 ms on one core, numpy throughout); the default 128 slots hold the
default rooms' 96-102 landmarks, a larger room needs a larger ``max_landmarks``. Uniforms are the
normal CDF of the draws, as in ``BatchRng.uniform``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtr

from estimators.batching import stream_rows
from estimators.rotations import (
    ensure_quaternion,
    matrix_to_quat,
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
    quat_rotate,
    quat_rotate_inverse,
)
from vrloco_env.batch_rng import BatchRng

if TYPE_CHECKING:
    from vrloco_env.world import Layout

__all__ = [
    "BODY_FROM_CAMERA",
    "CONDITIONS",
    "MAX_RATE_HZ",
    "CameraFrames",
    "CameraSpec",
    "HeadCamera",
    "camera_pose",
    "camera_spec",
    "extraction_rate",
    "head_pose_from_camera",
    "layout_landmarks",
    "matching_rate",
    "pad_landmarks",
    "project",
]

#: Highest frame rate the model accepts, Hz (high-speed tracking cameras; seed 004 uses 120).
MAX_RATE_HZ = 240.0
#: Rotation camera (OpenCV: x right, y down, z forward) -> head body (x forward, y left, z up),
#: without mount tilt: its columns are the camera axes in body coordinates.
BODY_FROM_CAMERA = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
_Q_BODY_FROM_CAMERA = matrix_to_quat(BODY_FROM_CAMERA)
_BELOW_ONE = 1.0 - 2.0**-53  # the largest double below 1 (as BatchRng.uniform)
#: Normal draws per frame and user before the landmark slots (the occluder's step).
_FRAME_DRAWS = 1
#: Normal draws per landmark slot and frame: detection-and-match, pixel noise u, pixel noise v.
_SLOT_DRAWS = 3


# --------------------------------------------------------------------------------------------------
# Specification


def _check(cond: bool, msg: str) -> None:
    if not cond:
        raise ValueError(msg)


def _real(value: object, name: str) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    _check(not math.isnan(v), f"{name} must not be NaN")
    return v


def _integer(value: object, name: str, lo: int, hi: int) -> None:
    _check(
        isinstance(value, int | np.integer) and not isinstance(value, bool) and lo <= value <= hi,
        f"{name} must be an integer in [{lo}, {hi}], got {value!r}",
    )


@dataclass(frozen=True)
class CameraSpec:
    """Parameters of the simulated head camera (validated on construction; units in the names).

    Use :func:`camera_spec` for a condition preset with overrides. Every value the paper does not
    give is an engineering choice explained in the module docstring.

    Attributes:
        name: label of the condition ("ideal", "low_light", "occlusion", "motion_blur" or free).
        fx: focal length along u, px, > 0.
        fy: focal length along v, px, > 0.
        cx: principal point u, px, in [0, width].
        cy: principal point v, px, in [0, height].
        width: image width, px, integer in [1, 10000].
        height: image height, px, integer in [1, 10000].
        rate_hz: frame rate, Hz, in (0, 240] (seed 004: 120).
        exposure_s: exposure time, s, in [0, 1 / rate_hz].
        min_range_m: nearest depth (along the optical axis) a landmark is seen at, m, > 0.
        max_range_m: farthest distance a landmark is detectable at, m, > min_range_m (a 10 cm
            marker is ~5 px wide at 10 m with f = 460 px).
        max_view_angle_deg: largest angle between a wall's normal and the line of sight to its
            landmark, deg, in (0, 90]; used only where normals are given.
        mount_offset_m: camera position in the head body frame, m (3 finite numbers).
        mount_tilt_deg: downward tilt of the optical axis, deg, in (-90, 90).
        pixel_noise_px: std of the corner localisation noise per axis, px, >= 0.
        extraction_prob: probability that a visible, unoccluded, unblurred landmark is detected,
            in [0, 1].
        match_prob: probability that an extracted feature is matched to its own landmark, in
            [0, 1]; otherwise it gets a neighbour's index.
        match_neighbors: how many nearest landmarks a wrong match picks from, integer in [1, 64].
        occluder_fraction: width of the occluding vertical band as a fraction of the image width,
            in [0, 1); 0 disables it.
        occluder_drift_px_per_sqrt_s: random-walk intensity of the band's centre, px/sqrt(s), >= 0.
        blur_free_px: blur length a detector tolerates without loss, px, >= 0.
        blur_scale_px: decay length of the detection probability beyond ``blur_free_px``, px,
            > 0 (``inf`` turns the blur's effect on detection off).
        blur_noise_per_px: pixel-noise std per px of blur length, >= 0 (1/sqrt(12) for a uniform
            streak).
        max_landmarks: landmark slots drawn for per frame, integer in [1, 4096]; a capture may pass
            at most this many landmarks. Fixed so that the random streams do not depend on how many
            landmarks a room (or a batch's padding) has; 128 holds the default rooms (96 in the
            8 m x 8 m room, ~102 in the Avoid corridor).
    """

    name: str = "ideal"
    fx: float = 460.0
    fy: float = 460.0
    cx: float = 319.5
    cy: float = 239.5
    width: int = 640
    height: int = 480
    rate_hz: float = 120.0
    exposure_s: float = 0.002
    min_range_m: float = 0.1
    max_range_m: float = 10.0
    max_view_angle_deg: float = 80.0
    mount_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mount_tilt_deg: float = 0.0
    pixel_noise_px: float = 0.5
    extraction_prob: float = 0.95
    match_prob: float = 0.90
    match_neighbors: int = 4
    occluder_fraction: float = 0.0
    occluder_drift_px_per_sqrt_s: float = 60.0
    blur_free_px: float = 2.0
    blur_scale_px: float = 8.0
    blur_noise_per_px: float = 1.0 / math.sqrt(12.0)
    max_landmarks: int = 128

    def __post_init__(self) -> None:
        _check(isinstance(self.name, str), f"name must be a string, got {self.name!r}")
        _integer(self.width, "width", 1, 10000)
        _integer(self.height, "height", 1, 10000)
        for name in ("fx", "fy"):
            v = _real(getattr(self, name), name)
            _check(0.0 < v < math.inf, f"{name} must be a finite focal length > 0 px, got {v}")
        cx, cy = _real(self.cx, "cx"), _real(self.cy, "cy")
        _check(0.0 <= cx <= self.width, f"cx must lie in [0, width={self.width}] px, got {cx}")
        _check(0.0 <= cy <= self.height, f"cy must lie in [0, height={self.height}] px, got {cy}")
        rate = _real(self.rate_hz, "rate_hz")
        _check(
            0.0 < rate <= MAX_RATE_HZ, f"rate_hz must lie in (0, {MAX_RATE_HZ:g}] Hz, got {rate}"
        )
        exp_s = _real(self.exposure_s, "exposure_s")
        _check(
            0.0 <= exp_s <= 1.0 / rate,
            f"exposure_s must lie in [0, 1/rate_hz = {1.0 / rate:.6g}] s, got {exp_s}",
        )
        near = _real(self.min_range_m, "min_range_m")
        far = _real(self.max_range_m, "max_range_m")
        _check(0.0 < near < math.inf, f"min_range_m must be a finite distance > 0 m, got {near}")
        _check(
            near < far < math.inf,
            f"max_range_m must be finite and > min_range_m = {near} m, got {far}",
        )
        va = _real(self.max_view_angle_deg, "max_view_angle_deg")
        _check(0.0 < va <= 90.0, f"max_view_angle_deg must lie in (0, 90] deg, got {va}")
        off = np.asarray(self.mount_offset_m, dtype=np.float64)
        _check(
            off.shape == (3,) and bool(np.all(np.isfinite(off))),
            f"mount_offset_m must be three finite numbers (m), got {self.mount_offset_m!r}",
        )
        tilt = _real(self.mount_tilt_deg, "mount_tilt_deg")
        _check(-90.0 < tilt < 90.0, f"mount_tilt_deg must lie in (-90, 90) deg, got {tilt}")
        for name in ("pixel_noise_px", "occluder_drift_px_per_sqrt_s", "blur_free_px"):
            v = _real(getattr(self, name), name)
            _check(0.0 <= v < math.inf, f"{name} must be finite and >= 0, got {v}")
        bn = _real(self.blur_noise_per_px, "blur_noise_per_px")
        _check(0.0 <= bn < math.inf, f"blur_noise_per_px must be finite and >= 0, got {bn}")
        bs = _real(self.blur_scale_px, "blur_scale_px")
        _check(bs > 0.0, f"blur_scale_px must be > 0 px (inf allowed), got {bs}")
        for name in ("extraction_prob", "match_prob"):
            v = _real(getattr(self, name), name)
            _check(0.0 <= v <= 1.0, f"{name} must lie in [0, 1], got {v}")
        occ = _real(self.occluder_fraction, "occluder_fraction")
        _check(0.0 <= occ < 1.0, f"occluder_fraction must lie in [0, 1), got {occ}")
        _integer(self.match_neighbors, "match_neighbors", 1, 64)
        _integer(self.max_landmarks, "max_landmarks", 1, 4096)

    @property
    def camera_matrix(self) -> NDArray[np.float64]:
        """OpenCV's intrinsic matrix K, (3, 3), px."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def fov_deg(self) -> tuple[float, float]:
        """Horizontal and vertical field of view, deg (edges of the image at -0.5 and size-0.5)."""
        h = math.atan((self.cx + 0.5) / self.fx) + math.atan((self.width - 0.5 - self.cx) / self.fx)
        v = math.atan((self.cy + 0.5) / self.fy) + math.atan(
            (self.height - 0.5 - self.cy) / self.fy
        )
        return math.degrees(h), math.degrees(v)

    @property
    def body_from_camera(self) -> NDArray[np.float64]:
        """Rotation camera -> head body frame including the mount tilt, (3, 3)."""
        return _mount_matrix(self)

    def noiseless(self) -> CameraSpec:
        """The same camera that sees perfectly: no noise, no detection or match failure, no
        occluder, blur without effect (geometry, mount and ranges kept)."""
        return dataclasses.replace(
            self,
            name=f"{self.name}-noiseless",
            pixel_noise_px=0.0,
            extraction_prob=1.0,
            match_prob=1.0,
            occluder_fraction=0.0,
            blur_scale_px=math.inf,
            blur_noise_per_px=0.0,
        )

    def with_(self, **changes: object) -> CameraSpec:
        """A copy with some fields changed (validated); unknown fields raise ValueError."""
        names = {f.name for f in dataclasses.fields(self)}
        bad = sorted(set(changes) - names)
        if bad:
            raise ValueError(f"CameraSpec has no field(s) {bad}; valid fields: {sorted(names)}")
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]


#: The four imaging conditions of seed 004, calibrated to its rates (module docstring table).
CONDITIONS: dict[str, CameraSpec] = {
    "ideal": CameraSpec(name="ideal"),
    "low_light": CameraSpec(
        name="low_light",
        extraction_prob=0.70,
        match_prob=0.85,
        pixel_noise_px=1.5,
        exposure_s=0.004,
    ),
    "occlusion": CameraSpec(name="occlusion", match_prob=0.60, occluder_fraction=0.30),
    "motion_blur": CameraSpec(name="motion_blur", exposure_s=1.0 / 120.0),
}


def camera_spec(condition: str = "ideal", **overrides: object) -> CameraSpec:
    """The preset of an imaging condition, with some fields changed.

    Args:
        condition: one of :data:`CONDITIONS` ("ideal", "low_light", "occlusion", "motion_blur").
        **overrides: any :class:`CameraSpec` field (units as there), e.g. ``rate_hz=60.0``.

    Returns:
        The validated spec; its ``name`` stays the condition's unless overridden.

    Raises:
        ValueError: an unknown condition or field, or an override out of its range.
    """
    if not isinstance(condition, str) or condition not in CONDITIONS:
        raise ValueError(f"condition must be one of {sorted(CONDITIONS)}, got {condition!r}")
    return CONDITIONS[condition].with_(**overrides)


# --------------------------------------------------------------------------------------------------
# Geometry


def _mount_matrix(spec: CameraSpec) -> NDArray[np.float64]:
    th = math.radians(spec.mount_tilt_deg)
    c, s = math.cos(th), math.sin(th)
    tilt = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # about body +y: nose down
    return tilt @ BODY_FROM_CAMERA


def _mount_quat(spec: CameraSpec) -> NDArray[np.float64]:
    """Quaternion camera -> body (mount tilt included), (4,)."""
    tilt = quat_from_rotvec(np.array([0.0, math.radians(spec.mount_tilt_deg), 0.0]))
    return quat_multiply(tilt, _Q_BODY_FROM_CAMERA)


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


# --------------------------------------------------------------------------------------------------
# Landmarks from rooms


def layout_landmarks(layout: Layout) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A room's landmarks in the world and the inward normals of their walls.

    Args:
        layout: a :class:`vrloco_env.world.layout.Layout`; its landmarks lie on the inner wall faces
            (local frame), shifted here by ``layout.origin`` (use ``layout.with_origin((0, 0))``
            for the local frame).

    Returns:
        ``(points, normals)``: (K, 3) m and (K, 3) unit vectors pointing into the room. A landmark
        is assigned the wall face (of the interior ``bounds``) it is closest to.
    """
    lm = np.asarray(layout.landmarks, dtype=np.float64)
    xmin, xmax, ymin, ymax = layout.bounds
    gaps = np.stack([lm[:, 0] - xmin, xmax - lm[:, 0], lm[:, 1] - ymin, ymax - lm[:, 1]], axis=1)
    inward = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
    normals = inward[np.argmin(np.abs(gaps), axis=1)]
    ox, oy = layout.origin
    return lm + np.array([ox, oy, 0.0]), normals


def pad_landmarks(
    points: Sequence[ArrayLike],
    normals: Sequence[ArrayLike] | None = None,
    width: int | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.bool_]]:
    """Stack per-user landmark sets of different sizes into padded arrays for a batch.

    Args:
        points: B arrays (K_i, 3) m.
        normals: B arrays (K_i, 3), or None.
        width: K of the result, >= every K_i (default: the largest K_i).

    Returns:
        ``(landmarks (B, K, 3), normals (B, K, 3) or None, mask (B, K))``; padded rows are zeros
        with mask False (at the end of each row, so a batch reproduces single runs).
    """
    pts = [np.asarray(p, dtype=np.float64) for p in points]
    _check(len(pts) > 0, "points must hold at least one (K_i, 3) array")
    for i, p in enumerate(pts):
        _check(p.ndim == 2 and p.shape[1] == 3, f"points[{i}] must be (K_i, 3) m, got {p.shape}")
    k = max(p.shape[0] for p in pts) if width is None else int(width)
    _check(
        k >= max(p.shape[0] for p in pts),
        f"width must be >= the largest K_i = {max(p.shape[0] for p in pts)}, got {width}",
    )
    b = len(pts)
    out = np.zeros((b, k, 3))
    mask = np.zeros((b, k), dtype=bool)
    nrm = None
    if normals is not None:
        _check(len(normals) == b, f"normals must hold B={b} arrays, got {len(normals)}")
        nrm = np.zeros((b, k, 3))
    for i, p in enumerate(pts):  # once per room change, not on the hot path
        out[i, : p.shape[0]] = p
        mask[i, : p.shape[0]] = True
        if nrm is not None:
            n = np.asarray(normals[i], dtype=np.float64)  # type: ignore[index]
            _check(n.shape == p.shape, f"normals[{i}] must have shape {p.shape}, got {n.shape}")
            nrm[i, : p.shape[0]] = n
    return out, nrm, mask


# --------------------------------------------------------------------------------------------------
# Frames


class CameraFrames(NamedTuple):
    """What the head camera delivers for B users, N frames and K landmarks.

    Missing values are NaN in ``pixels`` / ``pixels_true`` and -1 in ``matched_id``, always with an
    explicit boolean mask beside them.

    Attributes:
        t: (B, N) frame times (mid-exposure), s, as passed to :meth:`HeadCamera.capture`.
        pixels: (B, N, K, 2) measured feature positions (u, v), px; NaN where not extracted.
        pixels_true: (B, N, K, 2) noiseless projections, px; NaN where not visible.
        visible: (B, N, K) bool, geometric visibility (module docstring, step 1).
        occluded: (B, N, K) bool, visible but under the occluder band.
        extracted: (B, N, K) bool, the detector found the feature (implies visible, not occluded).
        matched_id: (B, N, K) int64, landmark index (row of the landmark array) the matcher gave
            the feature: k when right, another row when wrong, -1 when not extracted.
        blur_px: (B, N, K) blur length of each landmark's image, px (0 where not visible).
        occluder: (B, N, 2) the occluder band's [u_min, u_max], px; NaN without an occluder.
        n_visible: (B, N) int64 visible landmarks per frame.
        n_extracted: (B, N) int64 extracted features per frame.
        n_correct: (B, N) int64 extracted features matched to their own landmark.
    """

    t: NDArray[np.float64]
    pixels: NDArray[np.float64]
    pixels_true: NDArray[np.float64]
    visible: NDArray[np.bool_]
    occluded: NDArray[np.bool_]
    extracted: NDArray[np.bool_]
    matched_id: NDArray[np.int64]
    blur_px: NDArray[np.float64]
    occluder: NDArray[np.float64]
    n_visible: NDArray[np.int64]
    n_extracted: NDArray[np.int64]
    n_correct: NDArray[np.int64]

    @property
    def correct(self) -> NDArray[np.bool_]:
        """(B, N, K) bool: extracted and matched to its own landmark."""
        k = np.arange(self.matched_id.shape[-1])
        return self.extracted & (self.matched_id == k)

    @staticmethod
    def concatenate(chunks: Sequence[CameraFrames]) -> CameraFrames:
        """Join captures along the frame axis (axis 1)."""
        _check(len(chunks) > 0, "chunks must hold at least one CameraFrames")
        return CameraFrames(
            *(
                np.concatenate([c[i] for c in chunks], axis=1)
                for i in range(len(CameraFrames._fields))
            )
        )


def extraction_rate(frames: CameraFrames) -> float:
    """Extracted / visible landmark observations over all users and frames of ``frames``.

    Raises:
        ValueError: no landmark was visible (the rate is undefined).
    """
    n = int(np.count_nonzero(frames.visible))
    _check(n > 0, "frames.visible holds no visible landmark: extraction_rate is undefined")
    return int(np.count_nonzero(frames.extracted)) / n


def matching_rate(frames: CameraFrames) -> float:
    """Correct matches / extracted features over all users and frames of ``frames``.

    Raises:
        ValueError: no feature was extracted (the rate is undefined).
    """
    n = int(np.count_nonzero(frames.extracted))
    _check(n > 0, "frames.extracted holds no extracted feature: matching_rate is undefined")
    return int(np.count_nonzero(frames.correct)) / n


# --------------------------------------------------------------------------------------------------
# The camera


def _fold(x: NDArray[np.float64], lo: float, hi: float) -> NDArray[np.float64]:
    """Reflect ``x`` into [lo, hi] (a random walk between two mirrors)."""
    s = np.mod((x - lo) / (hi - lo), 2.0)
    return lo + (hi - lo) * (1.0 - np.abs(1.0 - s))


class HeadCamera:
    """The head camera of B users: landmark observations with detection and matching errors.

    Args:
        spec: the camera, a :class:`CameraSpec` or a condition name of :data:`CONDITIONS`.
        rng: one random stream per user.

    The constructor resets every user. Per-user state: the occluder's (unfolded) band centre and a
    frame counter.
    """

    def __init__(self, spec: CameraSpec | str, rng: BatchRng) -> None:
        if isinstance(spec, str):
            spec = camera_spec(spec)
        if not isinstance(spec, CameraSpec):
            raise ValueError(f"spec must be a CameraSpec or a condition name, got {spec!r}")
        if not isinstance(rng, BatchRng):
            raise ValueError(
                f"rng must be a vrloco_env.batch_rng.BatchRng, got {type(rng).__name__}"
            )
        self.spec = spec
        self.rng = rng
        self.dt = 1.0 / spec.rate_hz
        self._mount_q = _mount_quat(spec)
        self._mount_off = np.asarray(spec.mount_offset_m, dtype=np.float64)
        band = spec.occluder_fraction * spec.width
        self._band_half = 0.5 * band
        # Band centre range: the band lies inside the image [-0.5, width - 0.5].
        self._occ_lo = -0.5 + 0.5 * band
        self._occ_hi = spec.width - 0.5 - 0.5 * band
        self._draws = _FRAME_DRAWS + _SLOT_DRAWS * spec.max_landmarks
        self._nb_key: tuple[NDArray, NDArray] | None = None
        self.reset()

    @property
    def batch_size(self) -> int:
        """B, the number of users."""
        return self.rng.batch_size

    def reset(self, users: ArrayLike | None = None) -> None:
        """Start a new session for some or all users (the occluder's start position).

        Each reset user draws one normal from its own stream; the other users' state and streams
        are untouched, so after ``rng.reseed(i, g)`` and ``reset(users=[i])`` user i continues as
        a fresh single-user camera on ``BatchRng([g])``.

        Args:
            users: indices or a (B,) boolean mask; None resets all.

        Raises:
            ValueError: an index outside [0, B), a repeated index or a mask of the wrong shape.
        """
        b = self.batch_size
        rows = stream_rows(users, b)
        if not hasattr(self, "_occ_raw"):
            self._occ_raw = np.zeros(b)
            #: Frames captured per user since its reset.
            self.frames_taken = np.zeros(b, dtype=np.int64)
        z = self.rng.normal((1,), rows=rows)[:, 0]
        u = np.minimum(ndtr(z), _BELOW_ONE)
        self._occ_raw[rows] = self._occ_lo + (self._occ_hi - self._occ_lo) * u
        self.frames_taken[rows] = 0

    # ------------------------------------------------------------------------------ validation

    def _validate(self, t, pos, quat, omega, landmarks, mask, normals, blocked):
        b = self.batch_size
        p = np.asarray(pos, dtype=np.float64)
        _check(
            p.ndim == 3 and p.shape[0] == b and p.shape[2] == 3,
            f"pos must have shape (B={b}, N, 3) m, got {p.shape}",
        )
        n = p.shape[1]
        _check(n >= 1, "pos must hold at least one frame (N >= 1)")
        _check(bool(np.isfinite(p).all()), "pos contains NaN or infinite positions")
        q = np.asarray(quat, dtype=np.float64)
        _check(q.shape == (b, n, 4), f"quat must have shape (B={b}, N={n}, 4), got {q.shape}")
        q = ensure_quaternion(q, "quat")
        w = np.asarray(omega, dtype=np.float64)
        _check(
            w.shape == (b, n, 3), f"omega must have shape (B={b}, N={n}, 3) rad/s, got {w.shape}"
        )
        _check(bool(np.isfinite(w).all()), "omega contains NaN or infinite rates")
        tt = np.asarray(t, dtype=np.float64)
        if tt.shape == (n,):
            tt = np.broadcast_to(tt, (b, n))
        _check(
            tt.shape == (b, n), f"t must have shape (N={n},) or (B={b}, N={n}) s, got {tt.shape}"
        )
        _check(bool(np.isfinite(tt).all()), "t contains NaN or infinite times")
        lm = np.asarray(landmarks, dtype=np.float64)
        if lm.ndim == 2:
            lm = np.broadcast_to(lm, (b, *lm.shape))
        _check(
            lm.ndim == 3 and lm.shape[0] == b and lm.shape[2] == 3,
            f"landmarks must have shape (K, 3) or (B={b}, K, 3) m, got {np.shape(landmarks)}",
        )
        k = lm.shape[1]
        cap = self.spec.max_landmarks
        _check(
            1 <= k <= cap,
            f"landmarks must hold 1 <= K <= max_landmarks = {cap} rows, got K = {k} "
            "(raise CameraSpec.max_landmarks for larger rooms)",
        )
        if mask is None:
            m = np.ones((b, k), dtype=bool)
        else:
            m = np.asarray(mask)
            if m.shape == (k,):
                m = np.broadcast_to(m, (b, k))
            _check(
                m.shape == (b, k) and m.dtype == bool,
                f"mask must be a bool array of shape (K={k},) or (B={b}, K={k}), "
                f"got {m.dtype} {np.shape(mask)}",
            )
        _check(
            bool(np.isfinite(lm[m]).all()),
            "landmarks contains NaN or infinite coordinates in rows the mask marks valid",
        )
        lm = np.where(m[..., None], lm, 0.0)
        nrm = None
        if normals is not None:
            nrm = np.asarray(normals, dtype=np.float64)
            if nrm.shape == (k, 3):
                nrm = np.broadcast_to(nrm, (b, k, 3))
            _check(
                nrm.shape == (b, k, 3),
                f"normals must have shape (K={k}, 3) or (B={b}, K={k}, 3), got {np.shape(normals)}",
            )
            nrm = np.where(m[..., None], nrm, 0.0)
            norm = np.sqrt(nrm[..., 0] ** 2 + nrm[..., 1] ** 2 + nrm[..., 2] ** 2)
            _check(
                bool(np.all(np.isfinite(norm)) and np.all(norm[m] > 1e-9)),
                "normals must be finite and non-zero in rows the mask marks valid",
            )
            nrm = nrm / np.where(norm > 0.0, norm, 1.0)[..., None]
        blk = None
        if blocked is not None:
            blk = np.asarray(blocked)
            _check(
                blk.shape == (b, n, k) and blk.dtype == bool,
                f"blocked must be a bool array of shape (B={b}, N={n}, K={k}), "
                f"got {blk.dtype} {blk.shape}",
            )
        return tt.copy(), p, q, w, np.ascontiguousarray(lm), np.ascontiguousarray(m), nrm, blk

    def _neighbors(
        self, lm: NDArray[np.float64], mask: NDArray[np.bool_]
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """The ``match_neighbors`` nearest valid other landmarks of each landmark, (B, K, M), and
        how many of them exist per user, (B,). Cached while the landmarks do not change."""
        key = self._nb_key
        if key is not None and key[0].shape == lm.shape:
            same = np.all(key[0] == lm, axis=(1, 2)) & np.all(key[1] == mask, axis=1)
            if same.all():
                return self._nb, self._nb_count
            rows = np.flatnonzero(~same)
            nb, cnt = self._nb.copy(), self._nb_count.copy()
        else:
            b, k = mask.shape
            rows = np.arange(b)
            nb = np.zeros((b, k, self.spec.match_neighbors), dtype=np.int64)
            cnt = np.zeros(b, dtype=np.int64)
        p, mk = lm[rows], mask[rows]
        d = p[:, :, None, :] - p[:, None, :, :]
        d2 = d[..., 0] ** 2 + d[..., 1] ** 2 + d[..., 2] ** 2  # elementwise: batch == single
        k = mask.shape[1]
        bad = ~(mk[:, :, None] & mk[:, None, :]) | np.eye(k, dtype=bool)
        d2[bad] = np.inf
        m = min(self.spec.match_neighbors, k)
        order = np.argsort(d2, axis=2, kind="stable")[:, :, :m]
        nb[rows] = 0
        nb[rows, :, :m] = order
        cnt[rows] = np.minimum(self.spec.match_neighbors, np.maximum(mk.sum(axis=1) - 1, 0))
        self._nb, self._nb_count = nb, cnt
        self._nb_key = (lm.copy(), mask.copy())
        return nb, cnt

    # --------------------------------------------------------------------------------- capture

    def capture(
        self,
        t: ArrayLike,
        pos: ArrayLike,
        quat: ArrayLike,
        omega: ArrayLike,
        landmarks: ArrayLike,
        mask: ArrayLike | None = None,
        normals: ArrayLike | None = None,
        blocked: ArrayLike | None = None,
    ) -> CameraFrames:
        """Observe the landmarks in N successive frames of each of the B users.

        The model steps the occluder by ``1 / rate_hz`` per frame; ``t`` is passed through (the
        caller samples the head at the camera's rate, mid-exposure).

        Args:
            t: frame times, (N,) or (B, N) s, finite.
            pos: true head positions in the world, (B, N, 3) m.
            quat: true head orientations body -> world, (B, N, 4) [w, x, y, z], finite, non-zero.
            omega: true head angular rates in the body frame, (B, N, 3) rad/s (for motion blur).
            landmarks: landmark positions in the world, (K, 3) or (B, K, 3) m, K <=
                ``spec.max_landmarks``; rows the mask marks invalid may hold anything.
            mask: (K,) or (B, K) bool, True for real landmarks (False: padding); None: all real.
            normals: inward unit normals of each landmark's wall, (K, 3) or (B, K, 3); None skips
                the viewing-angle test.
            blocked: (B, N, K) bool, True where something in the scene (an obstacle) hides a
                landmark's line of sight; None: nothing does.

        Returns:
            :class:`CameraFrames`; K equals the landmarks' K.

        Raises:
            ValueError: a wrong shape or dtype, a non-finite value, a zero quaternion or more
                landmarks than ``spec.max_landmarks``. Nothing is drawn when it raises.
        """
        s = self.spec
        t, p, q, w, lm, mk, nrm, blk = self._validate(
            t, pos, quat, omega, landmarks, mask, normals, blocked
        )
        b, n = p.shape[:2]
        k = lm.shape[1]
        cap = s.max_landmarks
        nb, nb_count = self._neighbors(lm, mk)

        z = self.rng.normal((n, self._draws))  # (B, N, 1 + 4 C): fixed per frame and user
        self.frames_taken += n

        # Geometry: camera pose, camera-frame points, projections.
        cam_q = quat_multiply(q, self._mount_q)  # (B, N, 4) camera -> world
        cam_p = p + quat_rotate(q, self._mount_off)
        d = lm[:, None, :, :] - cam_p[:, :, None, :]  # (B, N, K, 3)
        xyz = quat_rotate_inverse(cam_q[:, :, None, :], d)
        zc = xyz[..., 2]
        front = zc >= s.min_range_m
        zsafe = np.where(front, zc, 1.0)
        x, y = xyz[..., 0] / zsafe, xyz[..., 1] / zsafe
        u = s.fx * x + s.cx
        v = s.fy * y + s.cy
        dist = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2 + d[..., 2] ** 2)
        visible = (
            front
            & mk[:, None, :]
            & (dist <= s.max_range_m)
            & (u >= -0.5)
            & (u <= s.width - 0.5)
            & (v >= -0.5)
            & (v <= s.height - 0.5)
        )
        if nrm is not None:  # seen from the room side, at most max_view_angle from the normal
            cos_view = -(
                nrm[:, None, :, 0] * d[..., 0]
                + nrm[:, None, :, 1] * d[..., 1]
                + nrm[:, None, :, 2] * d[..., 2]
            )
            limit = math.cos(math.radians(s.max_view_angle_deg)) * dist
            visible &= cos_view > limit
        if blk is not None:
            visible &= ~blk

        # Occluder band: a folded random walk of its centre, one step per frame.
        if s.occluder_fraction > 0.0:
            steps = s.occluder_drift_px_per_sqrt_s * math.sqrt(self.dt) * z[:, :, 0]
            walk = np.cumsum(np.concatenate([self._occ_raw[:, None], steps], axis=1), axis=1)
            self._occ_raw = walk[:, -1].copy()
            centre = _fold(walk[:, 1:], self._occ_lo, self._occ_hi)  # (B, N)
            band = np.stack([centre - self._band_half, centre + self._band_half], axis=-1)
            occluded = visible & (u >= band[:, :, None, 0]) & (u <= band[:, :, None, 1])
        else:
            band = np.full((b, n, 2), np.nan)
            occluded = np.zeros((b, n, k), dtype=bool)

        # Motion blur: rotational optical flow times the exposure.
        wc = quat_rotate_inverse(self._mount_q, w)  # (B, N, 3) camera-frame rate
        wx, wy, wz = (wc[:, :, None, i] for i in range(3))
        du = s.fx * (x * y * wx - (1.0 + x * x) * wy + y * wz)
        dv = s.fy * ((1.0 + y * y) * wx - x * y * wy - x * wz)
        blur = np.where(visible, np.sqrt(du * du + dv * dv) * s.exposure_s, 0.0)

        # Detection, then matching from the same uniform: given u < p_det (extracted), u / p_det
        # is again uniform on (0, 1) and independent of the detection outcome, so one number per
        # slot decides both (3 draws per slot instead of 4: the draws dominate the cost).
        c0 = _FRAME_DRAWS
        u_slot = np.minimum(ndtr(z[:, :, c0 : c0 + k]), _BELOW_ONE)
        p_det = s.extraction_prob * np.exp(
            -np.maximum(blur - s.blur_free_px, 0.0) / s.blur_scale_px
        )
        extracted = visible & ~occluded & (u_slot < p_det)

        # Pixel noise.
        sigma = np.sqrt(s.pixel_noise_px**2 + (s.blur_noise_per_px * blur) ** 2)
        nu = z[:, :, c0 + cap : c0 + cap + k]
        nv = z[:, :, c0 + 2 * cap : c0 + 2 * cap + k]
        pixels = np.where(
            extracted[..., None], np.stack([u + sigma * nu, v + sigma * nv], axis=-1), np.nan
        )
        pixels_true = np.where(visible[..., None], np.stack([u, v], axis=-1), np.nan)

        # Matching: own index with match_prob, else one of the nearest landmarks.
        u_match = np.minimum(u_slot / np.where(extracted, p_det, 1.0), _BELOW_ONE)
        own = np.broadcast_to(np.arange(k), (b, n, k))
        cnt = nb_count[:, None, None]
        wrong = (u_match >= s.match_prob) & (cnt > 0)
        if s.match_prob < 1.0:
            u_pick = (u_match - s.match_prob) / (1.0 - s.match_prob)  # uniform given a wrong match
        else:
            u_pick = np.zeros_like(u_match)
        j = np.minimum(np.floor(np.clip(u_pick, 0.0, _BELOW_ONE) * cnt), np.maximum(cnt - 1, 0))
        j = j.astype(np.int64)
        other = np.take_along_axis(
            np.broadcast_to(nb[:, None], (b, n, k, nb.shape[2])), j[..., None], axis=3
        )[..., 0]
        matched = np.where(wrong, other, own)
        matched_id = np.where(extracted, matched, -1).astype(np.int64)

        correct = extracted & (matched_id == own)
        return CameraFrames(
            t=t,
            pixels=pixels,
            pixels_true=pixels_true,
            visible=visible,
            occluded=occluded,
            extracted=extracted,
            matched_id=matched_id,
            blur_px=blur,
            occluder=band,
            n_visible=visible.sum(axis=2, dtype=np.int64),
            n_extracted=extracted.sum(axis=2, dtype=np.int64),
            n_correct=correct.sum(axis=2, dtype=np.int64),
        )
