"""The helmet-tracking paper's experiment settings: the rates, the IMU preset, the paper's numbers
and the targets (:data:`PAPER`, :data:`TARGETS`), the trajectories' and cameras' constants, and the
nominal camera (:func:`condition_spec`), PnP (:func:`pnp_params`) and fusion filter
(:func:`filter_config`) of each run (:mod:`agents.experiments.vio`).
"""

from __future__ import annotations

import math

from estimators.head_pose.visual_inertial import VioConfig
from vrloco_env.head_tracking import PnpParams
from vrloco_env.sensors.camera import CameraSpec, camera_spec
from vrloco_env.sensors.imu import get_imu_spec

__all__ = [
    "CALIBRATION_DURATION_S",
    "CALIBRATION_SEEDS",
    "CAMERA_RATE_HZ",
    "GROSS_ATT_DEG",
    "GROSS_POS_M",
    "IMU_PRESET",
    "IMU_RATE_HZ",
    "NOISY_FACTOR",
    "PAPER",
    "PIXEL_NOISE_SCALE",
    "RANSAC_SIGMAS",
    "ROTATION_RATE_DEG_S",
    "TARGETS",
    "VISUAL_CONDITIONS",
    "WALK_CADENCE",
    "WALK_RADIUS_M",
    "WINDOW_S",
    "condition_spec",
    "filter_config",
    "pnp_params",
]

IMU_RATE_HZ = 1000.0
CAMERA_RATE_HZ = 120.0
IMU_PRESET = "ig500n"
#: The helmet-tracking paper's reported numbers ("+-" bounds). Its extraction and matching success
#: rates are not results here: they are the camera model's inputs (``camera_inputs``).
PAPER = {
    "imu_only": {
        "static": {"att_deg": 2.0, "pos_m": 0.2},
        "rotation": {"att_deg": 5.0, "rate_deg_s": 10.0},
        "duration_s": 120.0,
        "accel_accuracy_m_s2": 0.005,
    },
    "visual_only": {
        "ideal": {"pos_m": 0.05, "att_deg": 1.0},
        "low_light": {"pos_m": 0.1, "att_deg": 3.0},
        "occlusion": {"pos_m": 0.1, "att_deg": 3.0},
    },
    "camera_inputs": {
        "ideal": {"extraction": 0.95, "matching": 0.90},
        "low_light": {"extraction": 0.70},
        "occlusion": {"matching": 0.60},
    },
    "imu_rate_hz": IMU_RATE_HZ,
    "camera_rate_hz": CAMERA_RATE_HZ,
}
#: Fused targets (RMSE) of the helmet-tracking paper: ideal and complex conditions.
TARGETS = {"ideal": {"pos_m": 0.05, "att_deg": 1.0}, "complex": {"pos_m": 0.1, "att_deg": 3.0}}
VISUAL_CONDITIONS = ("ideal", "low_light", "occlusion", "motion_blur", "complex")
ROTATION_RATE_DEG_S = 10.0
WALK_RADIUS_M = 2.5
WALK_CADENCE = 1.6
WINDOW_S = 10.0
#: A visual pose this far from the truth is a gross error (a wrong PnP solution, e.g. a mirrored
#: pose from a wrong-match consensus), counted in ``gross_fraction``; m and deg.
GROSS_POS_M = 0.25
GROSS_ATT_DEG = 5.0
#: The noisy camera of the adaptive experiment's second half: its pixel noise as a multiple of
#: the (calibrated) ideal camera's.
NOISY_FACTOR = 12.0
#: RANSAC inlier threshold of every camera: this many of its nominal pixel-noise sigmas, at least
#: :class:`~vrloco_env.head_tracking.PnpParams`' default 3 px, at most 50 px.
RANSAC_SIGMAS = 2.5
#: Development seeds of the camera calibration (:func:`calibrate_camera`): the walk, the camera
#: streams and the mismatch draws of these seeds tune ``PIXEL_NOISE_SCALE``; reported runs use
#: other seeds (default 0), whose numbers are held-out.
CALIBRATION_SEEDS = (1000, 1001, 1002)
CALIBRATION_DURATION_S = 30.0
#: The experiment's pixel noise as a multiple of the camera presets' (ideal 0.5 px, low light
#: 1.5 px): the value :func:`calibrate_camera` returns on :data:`CALIBRATION_SEEDS` with the
#: default :class:`Mismatch` (``.venv/bin/python -c "from agents.experiments.vio import
#: calibrate_camera as c; print(c())"``): the ideal camera's visual-only RMSE (gross errors left
#: out) lands on the helmet-tracking paper's +-0.05 m / +-1 deg in the geometric mean of the two
#: ratios.
PIXEL_NOISE_SCALE = 2.68


def condition_spec(condition: str, pixel_noise_scale: float = PIXEL_NOISE_SCALE) -> CameraSpec:
    """The nominal camera of a visual condition, its pixel noise scaled by ``pixel_noise_scale``.

    Args:
        condition: a :data:`~vrloco_env.sensors.camera.CONDITIONS` preset, or ``"complex"``:
            low light and occlusion at once (the low-light detector, noise and exposure, the
            occlusion preset's occluder, both matching losses taken as independent).
        pixel_noise_scale: factor on the preset's ``pixel_noise_px``, in (0, 100].
    """
    if not (isinstance(pixel_noise_scale, int | float) and 0.0 < pixel_noise_scale <= 100.0):
        raise ValueError(f"pixel_noise_scale must be in (0, 100], got {pixel_noise_scale!r}")
    if condition == "complex":
        occ, low = camera_spec("occlusion"), camera_spec("low_light")
        spec = low.with_(
            name="complex",
            occluder_fraction=occ.occluder_fraction,
            occluder_drift_px_per_sqrt_s=occ.occluder_drift_px_per_sqrt_s,
            match_prob=low.match_prob * occ.match_prob,
        )
    else:
        spec = camera_spec(condition)
    return spec.with_(pixel_noise_px=spec.pixel_noise_px * float(pixel_noise_scale))


def pnp_params(spec: CameraSpec) -> PnpParams:
    """The PnP settings for a nominal camera: the RANSAC threshold from its pixel noise
    (:data:`RANSAC_SIGMAS`), so that a noisier camera keeps its good matches as inliers."""
    px = min(max(PnpParams().reprojection_px, RANSAC_SIGMAS * spec.pixel_noise_px), 50.0)
    return PnpParams(reprojection_px=px)


def filter_config(
    adaptive: str = "sage_husa",
    position_sigma: float = 0.025,
    attitude_sigma_deg: float = 0.5,
) -> VioConfig:
    """The fusion filter's parameters: the ig500n *datasheet* values (package docstring).

    Args:
        adaptive: ``"fixed"`` or ``"sage_husa"``.
        position_sigma: R0 position std per axis, m.
        attitude_sigma_deg: R0 attitude std per axis, deg.
    """
    s = get_imu_spec(IMU_PRESET)
    floor_pos, floor_att = VioConfig().r_floor
    return VioConfig(
        accel_noise_density=s.accel.noise_density,
        gyro_noise_density=s.gyro.noise_density,
        accel_bias_walk=s.accel.bias_stability * math.sqrt(2.0 / s.accel.bias_tau),
        gyro_bias_walk=s.gyro.bias_stability * math.sqrt(2.0 / s.gyro.bias_tau),
        init_accel_bias_sigma=s.accel.bias_stability,
        init_gyro_bias_sigma=s.gyro.bias_stability,
        position_sigma=max(float(position_sigma), floor_pos),
        attitude_sigma=max(math.radians(attitude_sigma_deg), floor_att),
        adaptive=adaptive,
    )
