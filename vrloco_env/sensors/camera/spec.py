"""The head camera's specification (:class:`CameraSpec`) and its lighting presets
(:data:`LIGHTING`, :func:`camera_spec`); the sources of the values are given per field."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.registry import Registry, renamed_attributes
from estimators.rotations import matrix_to_quat, quat_from_rotvec, quat_multiply
from estimators.validation import check_in_range, check_instance, check_numbers

__all__ = ["LIGHTING", "MAX_RATE_HZ", "CameraSpec", "camera_spec"]

#: Highest frame rate the model accepts, Hz (high-speed tracking cameras; the helmet-tracking paper
#: uses 120).
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
        rate_hz: frame rate, Hz, in (0, 240] (the helmet-tracking paper: 120).
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
        inf = math.inf
        check_instance(self, "name", str)
        check_in_range(self, "width", 1, 10000, "px", integer=True)
        check_in_range(self, "height", 1, 10000, "px", integer=True)
        check_in_range(self, "fx", 0.0, inf, "px", lo_open=True)
        check_in_range(self, "fy", 0.0, inf, "px", lo_open=True)
        check_in_range(self, "cx", 0.0, self.width, allowed=f"in [0, width={self.width}] px")
        check_in_range(self, "cy", 0.0, self.height, allowed=f"in [0, height={self.height}] px")
        check_in_range(self, "rate_hz", 0.0, MAX_RATE_HZ, "Hz", lo_open=True)
        check_in_range(
            self,
            "exposure_s",
            0.0,
            1.0 / self.rate_hz,
            allowed=f"in [0, 1/rate_hz={1.0 / self.rate_hz:.6g}] s",
        )
        check_in_range(self, "min_range_m", 0.0, inf, "m", lo_open=True)
        check_in_range(
            self,
            "max_range_m",
            self.min_range_m,
            inf,
            lo_open=True,
            allowed=f"in (min_range_m={float(self.min_range_m):g}, inf) m",
        )
        check_in_range(self, "max_view_angle_deg", 0.0, 90.0, "deg", lo_open=True)
        check_numbers(self, "mount_offset_m", -inf, inf, "m", length=3)
        check_in_range(self, "mount_tilt_deg", -90.0, 90.0, "deg", lo_open=True, hi_open=True)
        check_in_range(self, "pixel_noise_px", 0.0, inf, "px")
        check_in_range(self, "occluder_drift_px_per_sqrt_s", 0.0, inf, "px/sqrt(s)")
        check_in_range(self, "blur_free_px", 0.0, inf, "px")
        check_in_range(self, "blur_noise_per_px", 0.0, inf)
        check_in_range(self, "blur_scale_px", 0.0, inf, "px", lo_open=True, allow_inf=True)
        check_in_range(self, "extraction_prob", 0.0, 1.0)
        check_in_range(self, "match_prob", 0.0, 1.0)
        check_in_range(self, "occluder_fraction", 0.0, 1.0, hi_open=True)
        check_in_range(self, "match_neighbors", 1, 64, integer=True)
        check_in_range(self, "max_landmarks", 1, 4096, integer=True)

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


#: The four imaging conditions of the helmet-tracking paper, calibrated to its rates (the
#: :mod:`vrloco_env.sensors.camera` docstring's table).
LIGHTING: Registry[CameraSpec] = Registry("condition")
LIGHTING.register("ideal", CameraSpec(name="ideal"), "good light, nothing in the way")
LIGHTING.register(
    "low_light",
    CameraSpec(
        name="low_light",
        extraction_prob=0.70,
        match_prob=0.85,
        pixel_noise_px=1.5,
        exposure_s=0.004,
    ),
    "dim: fewer features extracted, noisier corners, a longer exposure",
)
LIGHTING.register(
    "occlusion",
    CameraSpec(name="occlusion", match_prob=0.60, occluder_fraction=0.30),
    "a band over 30 % of the image width hides landmarks",
)
LIGHTING.register(
    "motion_blur",
    CameraSpec(name="motion_blur", exposure_s=1.0 / 120.0),
    "full frame-time exposure",
)

#: ``CONDITIONS``, the old name of :data:`LIGHTING`, still imports (with a warning).
__getattr__ = renamed_attributes(globals(), {"CONDITIONS": "LIGHTING"})


def camera_spec(condition: str = "ideal", **overrides: object) -> CameraSpec:
    """The preset of an imaging condition, with some fields changed.

    Args:
        condition: one of :data:`LIGHTING` ("ideal", "low_light", "occlusion", "motion_blur").
        **overrides: any :class:`CameraSpec` field (units as there), e.g. ``rate_hz=60.0``.

    Returns:
        The validated spec; its ``name`` stays the condition's unless overridden.

    Raises:
        ValueError: an unknown condition or field, or an override out of its range.
    """
    return LIGHTING.get(condition).with_(**overrides)


def _mount_matrix(spec: CameraSpec) -> NDArray[np.float64]:
    th = math.radians(spec.mount_tilt_deg)
    c, s = math.cos(th), math.sin(th)
    tilt = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # about body +y: nose down
    return tilt @ BODY_FROM_CAMERA


def _mount_quat(spec: CameraSpec) -> NDArray[np.float64]:
    """Quaternion camera -> body (mount tilt included), (4,)."""
    tilt = quat_from_rotvec(np.array([0.0, math.radians(spec.mount_tilt_deg), 0.0]))
    return quat_multiply(tilt, _Q_BODY_FROM_CAMERA)
