"""Seed 004's experiments in simulation: inertial, visual and fused helmet pose against the truth.

Everything runs through the real chain at seed 004's rates (IMU 1000 Hz, camera 120 Hz, frames
triggered by the IMU clock, :func:`vrloco_env.head_tracking.frame_triggers`)::

    UserMotion (1 kHz true head pose) -> HeadImu (ig500n unit) x axis errors -> Strapdown / filter
                                      -> HeadCamera (true intrinsics, true landmarks, late by the
                                         time offset) -> OpenCV PnP (nominal intrinsics, surveyed
                                         map; EPnP RANSAC)

Trajectories (one user each, ``duration`` s, default 120 s, at 1 kHz)
--------------------------------------------------------------------
* ``static``: standing still in place (the paper's static test).
* ``rotation``: in place, 2 s still, then a constant body yaw rate of 10 deg/s (the paper's
  turntable: "uniform rotation").
* ``walk``: overground (``MotionParams(overground=True)``) around the 8 m x 8 m "approach" room
  (:func:`vrloco_env.tasks.make_layout`, local frame, walls at +-4 m, 96 wall landmarks): 1 s
  standing at (0, -2.5) facing +x, then cadence 1.6 steps/s (0.65 m strides, 1.04 m/s) turning
  at ``1.04 / 2.5`` rad/s, a circle of radius ~2.5 m about the room centre, with a head
  serpentine (0.15 rad at 0.3 Hz) and nod (0.08 rad at 0.5 Hz) on top. Every visual and fused row
  uses this one walk and its one IMU record; only the camera differs.

The experiment's tracked space is the room's walls: the obstacles of the "approach" layout do not
hide landmarks in the camera model (``HeadCamera.capture`` takes no ``blocked`` mask here).

Model mismatch (:class:`Mismatch`, drawn once per run by :func:`make_setup`)
---------------------------------------------------------------------------
The simulator's truth and what the estimators are told differ; the estimators get only nominal
values. Defaults (1-sigma of the per-run draw) and their evidence:

* IMU axis errors: the unit's output is ``(I + E) reading``, ``E`` = a scale-factor error per
  axis (0.3 %) on the diagonal and misalignment / non-orthogonality (0.1 deg) off it, for the
  gyro and the accelerometer each. The seed calibrates its IMU on a turntable (bias and
  scale factor); what is left is of the order of factory-calibrated MEMS IMUs' datasheets (Analog
  Devices ADIS16475: +-0.1 deg axis-to-axis misalignment; the 0.3 % scale-factor residual is our
  estimate). Applied to the IMU model's output, so the bias and noise pass through ``I + E`` too
  (a 0.3 % change of a 4 mg bias, negligible).
* IMU noise: the unit's white-noise densities and bias instabilities are the ig500n datasheet's
  (:mod:`vrloco_env.sensors.imu`) times a log-normal factor (sigma 0.2, our estimate of unit-to-unit
  scatter around a datasheet's "typical" value); the filter is given the datasheet values.
* Camera-IMU time offset: 5 ms, constant: each frame is exposed 5 ms after the IMU sample that
  stamps it (the filter applies it at the stamp). The seed synchronises its acquisition; 5 ms is
  a small residual beside the several to tens of ms that online temporal calibration papers
  estimate for unsynchronised pairs (Qin & Shen, IROS 2018).
* Landmark map: the PnP uses the surveyed map, each landmark off its true place by 5 mm per axis
  (our estimate of a tape-and-level survey of wall markers).
* Intrinsics: the PnP uses the nominal fx, fy, cx, cy; the camera's true ones differ by 0.2 % in
  focal length and 1 px in the principal point (the order of the uncertainties of a Zhang
  calibration, the seed's method, at 640 x 480).

``Mismatch.none()`` turns all of it off (the estimators are then told the truth, apart from the
filter's start).

IMU only (``imu_only``)
-----------------------
:class:`estimators.head_pose.strapdown.Strapdown` from the *true* initial pose (position, attitude,
zero velocity; standing still), not from a coarse alignment: the paper's turntable test starts from
a known attitude, and an alignment would add its own tilt error (``b_a / g``, 0.2 deg for 4 mg) to
what is measured here, the drift. "Calibration" as in the paper's turntable calibration: the
unit's biases right after :meth:`HeadImu.reset` (for the ig500n preset the initial state of its
Gauss-Markov biases, 4 mg and 0.1 deg/s 1-sigma times the drawn scatter) are subtracted from
every sample; the in-run bias instability (tau = 100 s), white noise, quantisation and the axis
errors remain. Reported: the largest and the final attitude error (deg, angle of
``q_true^-1 q_est``) and position error (m, 3-D) over the run, and both at each quarter of it.

The paper's static position bound (+-0.2 m over 120 s) is physically inconsistent with its own
accelerometer accuracy (+-0.005 m/s^2): a constant residual bias ``b`` alone integrates to
``0.5 b t^2 = 0.5 * 0.005 * 120^2 = 36 m``, and +-0.2 m would need ``b <= 2 * 0.2 / 120^2 =
2.8e-5 m/s^2`` (3 ug), far below any MEMS accelerometer. A tilt error ``theta`` leaks gravity as
well (``g theta``: 1 deg is 0.17 m/s^2, 1.2 km in 120 s). Our position row is therefore far above
the paper's; we report it as computed. The attitude rows follow the unit's in-run gyro bias
instability (0.1 deg/s 1-sigma Gauss-Markov, tau = 100 s): after the calibration its change over
120 s integrates to an expected 8.8 deg per axis (15 deg 3-D RMS), against the paper's +-2 deg,
which would need a bias about 4x more stable than the datasheet's. The uniform rotation adds the
gyro's scale-factor and misalignment errors (0.3 % of 1200 deg is 3.6 deg of yaw), each row one
draw.

Visual only (``visual_only``)
-----------------------------
Every frame of the walk through :func:`estimators.head_pose.pnp.solve_poses` (OpenCV
``solvePnPRansac`` with EPnP + LM refinement, at least 6 landmarks, RANSAC threshold
:func:`pnp_params`: 2.5 sigma of the camera's nominal pixel noise, at least 3 px). The errors are
against the truth at each frame's *stamp*, so they include the time offset, the map and the
intrinsics errors. Per condition of :data:`vrloco_env.sensors.camera.CONDITIONS` and
``complex``: ``pos_m`` / ``att_deg`` are the RMSE over the frames that have a pose (position
error 3-D, m; attitude error angle, deg), with the 95th percentile and the largest;
``pos_clean_m`` / ``att_clean_deg`` the RMSE without the gross errors (poses off by more than
0.25 m or 5 deg: a wrong PnP solution that passed RANSAC, e.g. a flipped pose), whose share is
``gross_fraction``; ``availability`` is the fraction of frames with a pose. ``extraction`` =
extracted / visible and ``matching`` = correct matches / extracted over all frames: these rates
are the camera model's *inputs* (the presets' ``extraction_prob`` and ``match_prob`` are set to
the paper's 95 % / ~70 % and 90 % / ~60 %); the measured rates only check the model (under
occlusion extraction also counts the landmarks hidden by the occluder, about ``0.95 * 0.7``).

Camera calibration. The presets' pixel noise (0.5 px ideal, 1.5 px low light) with ~17
landmarks extracted per frame gives a visual-only error of about 0.015 m / 0.25 deg without
mismatch, well below the paper's +-0.05 m / +-1 deg. The experiment scales every preset's pixel
noise by :data:`PIXEL_NOISE_SCALE`, which :func:`calibrate_camera` sets so that the ideal
camera's ``pos_clean_m`` / ``att_clean_deg`` match the paper's +-0.05 m / +-1 deg (read as that
RMSE; the geometric mean of the two ratios is 1) on the development seeds
:data:`CALIBRATION_SEEDS` (30 s walks, with their mismatch draws). Landmark count and
extraction rate stay as they are (the rate is the paper's). Runs with other seeds (the default
0) are held-out; the other conditions' visual rows are not calibrated at all (their noise
keeps its ratio to ideal) and are compared with the paper's low-light / occlusion bounds as
they come out.

``complex`` = low light and occlusion together: the low-light detector, noise and exposure, the
occlusion preset's occluder (30 % of the width, same drift), and both matching losses taken as
independent (0.85 low light x 0.60 occlusion = 0.51). The paper reports one "low light /
occlusion" row; the harder combination is the stricter test of its fused claim.

Fused (``fused``)
-----------------
:class:`estimators.head_pose.visual_inertial.VisualInertialFilter` on the same IMU record and the
same visual poses, started at the first frame with a PnP pose (:func:`fuse`: that pose, zero
velocity, zero bias estimates), so errors are counted from that sample (``start_s``). IMU noise
in the filter from the ig500n *datasheet* (:func:`filter_config`), not the unit's drawn values:
white-noise densities as specified, the Gauss-Markov bias instability as the random walk
``sigma sqrt(2 / tau)`` with the same short-term growth, initial bias sigmas equal to the bias
instability. The filter knows nothing of the axis errors, the time offset, the map or
intrinsics errors. Main result: the adaptive (Sage-Husa R) filter with R0 = the paper's ideal
visual accuracy read as 2 sigma (0.025 m, 0.5 deg per axis:
:class:`~estimators.head_pose.visual_inertial. VioConfig` defaults); ``fixed`` rows: the same R0
kept fixed. ``pos_m`` / ``att_deg`` are the RMSE over every IMU sample from the start (1 kHz), with
the 95th percentile, the largest error, the largest RMS over 10 s windows (``window_max``) and the
RMS of the first and of the last 30 s (a quarter of the run when it is shorter than 120 s). Nothing
of the filter is tuned on these runs.

Adaptive vs fixed R (``adaptive``)
----------------------------------
The walk with the visual noise changing mid-run: the ideal camera for the first half (the very
frames and poses of the ``ideal`` rows), then from the first frame after ``duration / 2`` a noisy
camera, ``camera_spec("low_light")`` with :data:`NOISY_FACTOR` (12) times the calibrated ideal
pixel noise (a camera whose gain is pushed up in the dark), solved with its own RANSAC threshold
(:func:`pnp_params`). Both filters start from R tuned for the ideal camera: the per-axis RMS of
the ideal camera's pose errors over the first half (the RMSE without gross errors / sqrt(3),
clamped to the filter's floor). ``fixed`` keeps it; ``sage_husa`` re-estimates it from the
innovations. Reported: RMSE over the second half and over the whole run for both.

``targets_met``: fused ideal RMSE < 0.05 m and < 1 deg and complex < 0.1 m and < 3 deg, each with
its largest 10 s window RMS below the same bound (``bounded``); the adaptive filter's
second-half RMSE (position and attitude) below fixed R's; the fused ideal RMSE below the ideal
camera's own (without its gross errors).

Cost: the per-frame OpenCV calls dominate (about 79,000 frames in the full 120 s experiment);
degraded frames with few correct matches run all 200 RANSAC iterations. Frames are captured in
order (the camera's random stream is sequential) and their PnP is spread over ``workers``
threads in blocks of 600 frames; the result does not depend on the number of workers.

Run: ``vrloco experiment vio --json out/vio.json [--duration S] [--seed N] [--out DIR]
[--workers N]``. Non-finite numbers (an empty statistic) are written to the JSON as null.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from estimators import rotations as rot
from estimators.head_pose.pnp import (
    REASON_BEHIND_CAMERA,
    REASON_OK,
    REASON_RANSAC_FAILED,
    REASON_TOO_FEW_INLIERS,
    REASON_TOO_FEW_LANDMARKS,
    solve_poses,
)
from estimators.head_pose.strapdown import Strapdown
from estimators.head_pose.visual_inertial import VioConfig, VisualInertialFilter
from estimators.validation import check_in_range
from vrloco_env.batch_rng import BatchRng
from vrloco_env.head_tracking import PnpParams, camera_intrinsics, frame_triggers, pnp_mount
from vrloco_env.sensors.camera import (
    CameraSpec,
    HeadCamera,
    camera_spec,
    layout_landmarks,
)
from vrloco_env.sensors.imu import HeadImu, ImuSpec, get_imu_spec
from vrloco_env.tasks import make_layout
from vrloco_env.user import Intent, MotionParams, MotionRecord, UserMotion
from vrloco_env.world import RoomConfig

__all__ = [
    "CALIBRATION_SEEDS",
    "CAMERA_RATE_HZ",
    "IMU_RATE_HZ",
    "PAPER",
    "PIXEL_NOISE_SCALE",
    "Mismatch",
    "Setup",
    "Trajectory",
    "VisualRun",
    "calibrate_camera",
    "capture_visual",
    "condition_spec",
    "error_series",
    "filter_config",
    "format_table",
    "fuse",
    "imu_only",
    "make_setup",
    "pnp_params",
    "run_vio",
    "simulate",
    "visual_stats",
]

IMU_RATE_HZ = 1000.0
CAMERA_RATE_HZ = 120.0
IMU_PRESET = "ig500n"
#: Seed 004's reported numbers ("+-" bounds). Its extraction and matching success rates are not
#: results here: they are the camera model's inputs (``camera_inputs``).
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
#: Fused targets (RMSE) of seed 004: ideal and complex conditions.
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
#: out) lands on seed 004's +-0.05 m / +-1 deg in the geometric mean of the two ratios.
PIXEL_NOISE_SCALE = 2.68
_STILL_START_S = {"rotation": 2.0, "walk": 1.0}
_STRIDE_M = MotionParams().stride_m  # 0.65 m per step overground
_PNP_BLOCK = 600  # frames per PnP job (5 s at 120 Hz)
_CAPTURE_BLOCK = 1200  # frames per capture call (bounds the (N, K) arrays)


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
    """The fusion filter's parameters: the ig500n *datasheet* values (module docstring).

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


# ------------------------------------------------------------------------------------------------
# Model mismatch
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Mismatch:
    """How far the simulated sensors and room are from what the estimators are told (1-sigma of
    the per-run draws unless stated; module docstring for the evidence behind each default).

    Attributes:
        gyro_scale: scale-factor error per gyro axis, dimensionless, in [0, 0.05].
        gyro_misalignment_deg: each off-diagonal entry of the gyro's axis error matrix (axis
            misalignment and non-orthogonality), deg, in [0, 2].
        accel_scale: scale-factor error per accelerometer axis, in [0, 0.05].
        accel_misalignment_deg: the accelerometer's off-diagonal entries, deg, in [0, 2].
        noise_scatter: log-normal sigma of the unit's white-noise densities and bias
            instabilities around the datasheet values the filter is given, in [0, 1].
        time_offset_s: how much later than its IMU trigger stamp a frame is exposed (constant,
            not drawn), s, in [0, 0.05].
        landmark_sigma_m: survey error of each landmark of the map the PnP uses, per axis, m,
            in [0, 0.1].
        focal_sigma: relative error of fx and fy (each drawn) in the intrinsics the PnP uses,
            in [0, 0.05].
        principal_sigma_px: error of cx and cy in the intrinsics the PnP uses, px, in [0, 20].
    """

    gyro_scale: float = 0.003
    gyro_misalignment_deg: float = 0.1
    accel_scale: float = 0.003
    accel_misalignment_deg: float = 0.1
    noise_scatter: float = 0.2
    time_offset_s: float = 0.005
    landmark_sigma_m: float = 0.005
    focal_sigma: float = 0.002
    principal_sigma_px: float = 1.0

    def __post_init__(self) -> None:
        for name, hi, unit in (
            ("gyro_scale", 0.05, ""), ("gyro_misalignment_deg", 2.0, "deg"),
            ("accel_scale", 0.05, ""), ("accel_misalignment_deg", 2.0, "deg"),
            ("noise_scatter", 1.0, ""), ("time_offset_s", 0.05, "s"),
            ("landmark_sigma_m", 0.1, "m"), ("focal_sigma", 0.05, ""),
            ("principal_sigma_px", 20.0, "px"),
        ):  # fmt: skip
            check_in_range(self, name, 0.0, hi, unit)

    @classmethod
    def none(cls) -> Mismatch:
        """No mismatch: the estimators are told the simulator's truth (for comparison)."""
        return cls(**{f.name: 0.0 for f in dataclasses.fields(cls)})


@dataclass(frozen=True)
class Setup:
    """One run's draw of the mismatch: the truth the simulator uses beside the nominal values.

    Attributes:
        mismatch: what was drawn from.
        gyro_matrix, accel_matrix: (3, 3) ``I + error``: the unit outputs ``matrix @ reading``.
        imu_spec: the unit's true error model (the datasheet's with the drawn noise scatter).
        offset_samples: the time offset in IMU samples (rounded).
        landmarks: (K, 3) true landmark positions (the room's), m; normals: (K, 3) inward.
        map_landmarks: (K, 3) the surveyed map the PnP uses, m.
        intrinsics_error: (dfx, dfy, dcx, dcy): true minus nominal, px.
    """

    mismatch: Mismatch
    gyro_matrix: NDArray[np.float64]
    accel_matrix: NDArray[np.float64]
    imu_spec: ImuSpec
    offset_samples: int
    landmarks: NDArray[np.float64]
    normals: NDArray[np.float64]
    map_landmarks: NDArray[np.float64]
    intrinsics_error: tuple[float, float, float, float]

    def true_camera(self, nominal: CameraSpec) -> CameraSpec:
        """The camera that takes the images: ``nominal`` with the drawn intrinsics error."""
        dfx, dfy, dcx, dcy = self.intrinsics_error
        return nominal.with_(fx=nominal.fx + dfx, fy=nominal.fy + dfy, cx=nominal.cx + dcx,
                             cy=nominal.cy + dcy)  # fmt: skip

    def summary(self) -> dict:
        """The drawn values, for the result's JSON (scale factors, misalignments in deg)."""
        out = {"mismatch": dataclasses.asdict(self.mismatch),
               "offset_samples": self.offset_samples,
               "map_error_rms_m": float(np.sqrt(np.mean(
                   np.sum((self.map_landmarks - self.landmarks) ** 2, axis=1)))),
               "intrinsics_error_px": list(self.intrinsics_error)}  # fmt: skip
        nominal = get_imu_spec(IMU_PRESET)
        for name, m in (("gyro", self.gyro_matrix), ("accel", self.accel_matrix)):
            off = m - np.diag(np.diag(m))
            out[f"{name}_scale"] = (np.diag(m) - 1.0).tolist()
            out[f"{name}_misalignment_deg"] = np.rad2deg(off[off != 0.0]).tolist()
            true_s, nom_s = getattr(self.imu_spec, name), getattr(nominal, name)
            out[f"{name}_noise_factor"] = true_s.noise_density / nom_s.noise_density
            out[f"{name}_bias_factor"] = true_s.bias_stability / nom_s.bias_stability
        return out


def _error_matrix(rng: np.random.Generator, scale: float, misalign_deg: float) -> NDArray:
    m = np.eye(3) + np.diag(rng.normal(0.0, 1.0, 3) * scale)
    off = rng.normal(0.0, 1.0, (3, 3)) * math.radians(misalign_deg)
    return m + off - np.diag(np.diag(off))


def make_setup(seed: int, mismatch: Mismatch | None = None) -> Setup:
    """Draw one run's mismatch (its own random stream of ``seed``) in the experiment's room.

    Args:
        seed: the run's seed.
        mismatch: what to draw; None: the defaults (:class:`Mismatch`).
    """
    mm = Mismatch() if mismatch is None else mismatch
    if not isinstance(mm, Mismatch):
        raise ValueError(f"mismatch must be a Mismatch or None, got {type(mm).__name__}")
    rng = np.random.default_rng([seed, 7])
    gyro = _error_matrix(rng, mm.gyro_scale, mm.gyro_misalignment_deg)
    accel = _error_matrix(rng, mm.accel_scale, mm.accel_misalignment_deg)
    f = np.exp(rng.normal(0.0, 1.0, 4) * mm.noise_scatter)
    nominal = get_imu_spec(IMU_PRESET)
    spec = dataclasses.replace(
        nominal,
        accel=dataclasses.replace(nominal.accel, noise_density=nominal.accel.noise_density * f[0],
                                  bias_stability=nominal.accel.bias_stability * f[2]),
        gyro=dataclasses.replace(nominal.gyro, noise_density=nominal.gyro.noise_density * f[1],
                                 bias_stability=nominal.gyro.bias_stability * f[3]),
    )  # fmt: skip
    layout = make_layout("approach", RoomConfig(), np.random.default_rng(seed)).with_origin((0, 0))
    lm, nrm = layout_landmarks(layout)
    survey = rng.normal(0.0, 1.0, lm.shape) * mm.landmark_sigma_m
    cam = camera_spec("ideal")
    dfx, dfy = rng.normal(0.0, 1.0, 2) * mm.focal_sigma * np.array([cam.fx, cam.fy])
    dcx, dcy = rng.normal(0.0, 1.0, 2) * mm.principal_sigma_px
    return Setup(
        mismatch=mm, gyro_matrix=gyro, accel_matrix=accel, imu_spec=spec,
        offset_samples=round(mm.time_offset_s * IMU_RATE_HZ), landmarks=lm, normals=nrm,
        map_landmarks=lm + survey, intrinsics_error=(float(dfx), float(dfy), float(dcx),
                                                     float(dcy)),
    )  # fmt: skip


# ------------------------------------------------------------------------------------------------
# Trajectories and the IMU
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Trajectory:
    """One user's true head motion and IMU record at 1 kHz (N samples).

    Attributes:
        kind: "static", "rotation" or "walk".
        t: (N,) sample times, s. pos: (N, 3) IMU position, m. quat: (N, 4) body -> world.
        omega: (N, 3) body rate, rad/s. gyr, acc: (N, 3) IMU samples (rad/s, m/s^2), the
            setup's axis error matrices applied.
        gyro_bias, accel_bias: (3,) the turntable calibration: the unit's biases right after its
            reset, as they appear in the samples (through the axis error matrices).
    """

    kind: str
    t: NDArray[np.float64]
    pos: NDArray[np.float64]
    quat: NDArray[np.float64]
    omega: NDArray[np.float64]
    gyr: NDArray[np.float64]
    acc: NDArray[np.float64]
    gyro_bias: NDArray[np.float64]
    accel_bias: NDArray[np.float64]


def _intent(kind: str, t0: float) -> Intent:
    still = t0 < _STILL_START_S.get(kind, 0.0) - 1e-9
    if kind == "static" or still:
        return Intent()
    if kind == "rotation":
        return Intent(turn_rate=np.array([math.radians(ROTATION_RATE_DEG_S)]))
    speed = _STRIDE_M * WALK_CADENCE
    return Intent(
        cadence=np.array([WALK_CADENCE]),
        turn_rate=np.array([speed / WALK_RADIUS_M]),
        gesture_amplitude=np.array([[0.15, 0.08, 0.0]]),
        gesture_frequency=np.array([[0.3, 0.5, 0.5]]),
    )


def simulate(kind: str, duration: float, seed: int, setup: Setup | None = None) -> Trajectory:
    """Simulate one trajectory (module docstring) and the IMU record of the setup's unit.

    Args:
        kind: "static", "rotation" or "walk".
        duration: s, in [0.1, 600], rounded to the 0.1 s control step.
        seed: random seed (the motion and the IMU draw from their own streams of it).
        setup: the unit's errors (:func:`make_setup`); None: the datasheet unit without axis
            errors (:meth:`Mismatch.none`).
    """
    kinds = ("static", "rotation", "walk")
    if kind not in kinds:
        raise ValueError(f"kind must be one of {kinds}, got {kind!r}")
    if not (0.1 <= float(duration) <= 600.0):
        raise ValueError(f"duration must be in [0.1, 600] s, got {duration!r}")
    if setup is None:
        setup = make_setup(seed, Mismatch.none())
    key = kinds.index(kind)
    params = MotionParams(imu_rate_hz=IMU_RATE_HZ, overground=(kind == "walk"))
    steps = round(duration * params.control_rate_hz)
    motion = UserMotion(params, BatchRng([np.random.default_rng([seed, key, 0])]))
    base = (0.0, -WALK_RADIUS_M) if kind == "walk" else (0.0, 0.0)
    motion.reset(yaw=0.0, base=base)
    imu = HeadImu(setup.imu_spec, BatchRng([np.random.default_rng([seed, key, 1])]), IMU_RATE_HZ)
    calib = imu.bias
    chunks, gyr, acc = [], [], []
    for k in range(steps):
        chunk = motion.advance(_intent(kind, k / params.control_rate_hz))
        s = imu.sample(chunk.quat, chunk.omega, chunk.acc, chunk.pos)
        chunks.append(chunk)
        gyr.append(s.gyr[0])
        acc.append(s.acc[0])
    rec = MotionRecord.concatenate(chunks)
    mg, ma = setup.gyro_matrix, setup.accel_matrix
    return Trajectory(
        kind=kind,
        t=rec.t,
        pos=rec.pos[0],
        quat=rec.quat[0],
        omega=rec.omega[0],
        gyr=np.concatenate(gyr) @ mg.T,
        acc=np.concatenate(acc) @ ma.T,
        gyro_bias=mg @ calib.gyr[0],
        accel_bias=ma @ calib.acc[0],
    )


def error_series(
    pos: NDArray, quat: NDArray, pos_true: NDArray, quat_true: NDArray
) -> tuple[NDArray, NDArray]:
    """Position error (m, 3-D norm) and attitude error (deg, angle of ``q_true^-1 q``)."""
    ep = np.linalg.norm(pos - pos_true, axis=-1)
    ea = np.rad2deg(rot.rotation_angle(rot.quat_multiply(rot.quat_conjugate(quat_true), quat)))
    return ep, ea


def _start_velocity(traj: Trajectory) -> NDArray:
    return (traj.pos[1] - traj.pos[0]) * IMU_RATE_HZ  # ~0: every trajectory starts standing


def imu_only(traj: Trajectory) -> dict:
    """Strapdown from the true initial pose with calibrated samples; drift statistics.

    Returns:
        ``pos_m`` / ``att_deg``: the largest errors over the run; ``pos_end_m`` / ``att_end_deg``
        the final ones; ``pos_at_m`` / ``att_at_deg`` at ``t_at_s`` (each quarter of the run).
    """
    nav = Strapdown(1, IMU_RATE_HZ)
    nav.reset(traj.pos[0], _start_velocity(traj), traj.quat[0], gyr=traj.gyr[0], acc=traj.acc[0])
    out = nav.propagate(traj.gyr[None, 1:], traj.acc[None, 1:], gyro_bias=traj.gyro_bias,
                        accel_bias=traj.accel_bias)  # fmt: skip
    p = np.concatenate([traj.pos[:1], out.p[0]])
    q = np.concatenate([traj.quat[:1], out.q[0]])
    ep, ea = error_series(p, q, traj.pos, traj.quat)
    n = traj.t.size
    at = [max(round(n * f) - 1, 0) for f in (0.25, 0.5, 0.75, 1.0)]
    return {
        "pos_m": float(ep.max()),
        "att_deg": float(ea.max()),
        "pos_end_m": float(ep[-1]),
        "att_end_deg": float(ea[-1]),
        "t_at_s": [float(traj.t[i]) for i in at],
        "pos_at_m": [float(ep[i]) for i in at],
        "att_at_deg": [float(ea[i]) for i in at],
        "calibration": {
            "gyro_bias_deg_s": np.rad2deg(traj.gyro_bias).tolist(),
            "accel_bias_m_s2": traj.accel_bias.tolist(),
        },
        "_series": (ep, ea),
    }


# ------------------------------------------------------------------------------------------------
# Camera and PnP
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class VisualRun:
    """The frames of one camera over (part of) a trajectory and their PnP poses (M frames).

    Attributes:
        sample: (M,) IMU sample index of each frame's trigger (its time stamp).
        position: (M, 3) m, NaN without a pose. quat: (M, 4). ok: (M,) bool.
        reason: (M,) int8 failure code (``estimators.head_pose.pnp.REASON_*``).
        n_visible, n_extracted, n_correct: (M,) landmark counts per frame.
    """

    sample: NDArray[np.intp]
    position: NDArray[np.float64]
    quat: NDArray[np.float64]
    ok: NDArray[np.bool_]
    reason: NDArray[np.int8]
    n_visible: NDArray[np.int64]
    n_extracted: NDArray[np.int64]
    n_correct: NDArray[np.int64]

    def select(self, keep: NDArray[np.bool_]) -> VisualRun:
        """The frames where ``keep`` (M,) is True."""
        return VisualRun(*(getattr(self, f)[keep] for f in VisualRun.__dataclass_fields__))

    @staticmethod
    def concatenate(runs: list[VisualRun]) -> VisualRun:
        """The frames of several runs, in the given order."""
        return VisualRun(*(np.concatenate([getattr(r, f) for r in runs])
                           for f in VisualRun.__dataclass_fields__))  # fmt: skip


def _solve_block(args: tuple) -> tuple:
    """PnP on a block of frames (runs in a worker thread): ``args`` = (the map's landmarks
    (K, 3), matched landmark ids and pixels of the extracted features of all frames,
    concatenated, features per frame, nominal spec, pnp)."""
    landmarks, ids, pixels, per_frame, spec, pnp = args
    cuts = np.cumsum(per_frame)[:-1]
    frames = list(zip(np.split(landmarks[ids], cuts), np.split(pixels, cuts), strict=True))
    mq, mo = pnp_mount(spec)
    res = solve_poses(frames, camera_intrinsics(spec), pnp.min_landmarks, pnp.reprojection_px,
                      mount_quat=mq, mount_offset=mo)  # fmt: skip
    return res.position, res.quat, res.ok, res.reason


@dataclass
class _Capture:
    """Frames of one camera, captured; their PnP still to do (``jobs`` for :func:`_solve_block`)."""

    sample: NDArray[np.intp]
    counts: NDArray[np.int64]  # (3, M) visible, extracted, correct
    jobs: list


def _capture(
    traj: Trajectory,
    spec: CameraSpec,
    rng: BatchRng,
    setup: Setup,
    pnp: PnpParams,
    first_sample: int,
) -> _Capture:
    """Frames triggered at or after ``first_sample`` by the nominal camera ``spec``: imaged by the
    setup's true camera at the trigger plus the time offset, solved against the setup's map."""
    idx = frame_triggers(0, traj.t.size, IMU_RATE_HZ, spec.rate_hz)
    idx = idx[(idx >= first_sample) & (idx + setup.offset_samples < traj.t.size)]
    cam = HeadCamera(setup.true_camera(spec), rng)
    m = idx.size
    counts = np.zeros((3, m), np.int64)
    jobs = []
    for a in range(0, m, _CAPTURE_BLOCK):
        j = idx[a : a + _CAPTURE_BLOCK] + setup.offset_samples  # the instant actually imaged
        fr = cam.capture(traj.t[j], traj.pos[None, j], traj.quat[None, j], traj.omega[None, j],
                         setup.landmarks, normals=setup.normals)  # fmt: skip
        counts[:, a : a + j.size] = fr.n_visible[0], fr.n_extracted[0], fr.n_correct[0]
        for b in range(0, j.size, _PNP_BLOCK):
            ext = fr.extracted[0, b : b + _PNP_BLOCK]
            jobs.append(
                (
                    setup.map_landmarks,
                    fr.matched_id[0, b : b + _PNP_BLOCK][ext],
                    fr.pixels[0, b : b + _PNP_BLOCK][ext],
                    ext.sum(axis=1),
                    spec,
                    pnp,
                )
            )
    return _Capture(idx, counts, jobs)


def _assemble(cap: _Capture, results: list) -> VisualRun:
    if results:
        pos, quat, ok, reason = (np.concatenate(x) for x in zip(*results, strict=True))
    else:
        pos, quat = np.zeros((0, 3)), np.zeros((0, 4))
        ok, reason = np.zeros(0, bool), np.zeros(0, np.int8)
    return VisualRun(cap.sample, pos, quat, ok, reason, *cap.counts)


def capture_visual(
    traj: Trajectory,
    spec: CameraSpec,
    rng: BatchRng,
    setup: Setup,
    pnp: PnpParams = PnpParams(),  # noqa: B008  (frozen)
    first_sample: int = 0,
    workers: int = 1,
) -> VisualRun:
    """Capture the frames triggered at or after ``first_sample`` and solve their poses.

    Args:
        traj: the trajectory (its true pose is what the camera sees).
        spec: the nominal camera (the PnP's intrinsics); the images come from
            ``setup.true_camera(spec)``. rng: its random stream (one user).
        setup: the run's truth and nominal values (:func:`make_setup`).
        pnp: PnP settings.
        first_sample: IMU sample from which frames are taken (the clock starts at sample 0).
        workers: threads for the PnP (the poses do not depend on it).
    """
    if not (isinstance(workers, int) and workers >= 1):
        raise ValueError(f"workers must be an int >= 1, got {workers!r}")
    cap = _capture(traj, spec, rng, setup, pnp, first_sample)
    return _assemble(cap, _solve_all({"run": cap}, workers)["run"])


def visual_stats(run: VisualRun, traj: Trajectory) -> dict:
    """Errors of the visual poses against the truth at their time stamps (module docstring)."""
    ep, ea = error_series(run.position[run.ok], run.quat[run.ok], traj.pos[run.sample[run.ok]],
                          traj.quat[run.sample[run.ok]])  # fmt: skip
    names = {REASON_OK: "ok", REASON_TOO_FEW_LANDMARKS: "too_few_landmarks",
             REASON_RANSAC_FAILED: "ransac_failed", REASON_TOO_FEW_INLIERS: "too_few_inliers",
             REASON_BEHIND_CAMERA: "behind_camera"}  # fmt: skip
    out = {
        "frames": int(run.ok.size),
        "availability": float(run.ok.mean()) if run.ok.size else 0.0,
        "extraction": float(run.n_extracted.sum() / max(run.n_visible.sum(), 1)),
        "matching": float(run.n_correct.sum() / max(run.n_extracted.sum(), 1)),
        "visible_per_frame": float(run.n_visible.mean()) if run.ok.size else 0.0,
        "extracted_per_frame": float(run.n_extracted.mean()) if run.ok.size else 0.0,
        "outcomes": {n: int(np.count_nonzero(run.reason == code)) for code, n in names.items()},
    }
    out.update(_error_stats(ep, ea, samples=False))
    gross = (ep > GROSS_POS_M) | (ea > GROSS_ATT_DEG)
    out.update({
        "pos_median_m": float(np.median(ep)) if ep.size else float("nan"),
        "att_median_deg": float(np.median(ea)) if ea.size else float("nan"),
        "gross_fraction": float(gross.mean()) if ep.size else 0.0,
        "pos_clean_m": _rms(ep[~gross]),
        "att_clean_deg": _rms(ea[~gross]),
    })  # fmt: skip
    return out


# ------------------------------------------------------------------------------------------------
# Camera calibration
# ------------------------------------------------------------------------------------------------


def _calibration_error(scale: float, runs: list) -> tuple[float, float, float]:
    """Clean visual-only RMSE (m, deg) of the ideal camera at ``scale`` over the development
    runs (pooled frames) and the log of the geometric mean of their ratios to the paper's."""
    ep, ea = [], []
    for traj, setup, seed in runs:
        spec = condition_spec("ideal", scale)
        run = capture_visual(traj, spec, _camera_rng(seed, 0), setup, pnp_params(spec),
                             workers=2)  # fmt: skip
        e_p, e_a = error_series(run.position[run.ok], run.quat[run.ok],
                                traj.pos[run.sample[run.ok]], traj.quat[run.sample[run.ok]])
        good = (e_p <= GROSS_POS_M) & (e_a <= GROSS_ATT_DEG)
        ep.append(e_p[good])
        ea.append(e_a[good])
    pos, att = _rms(np.concatenate(ep)), _rms(np.concatenate(ea))
    paper = PAPER["visual_only"]["ideal"]
    return pos, att, 0.5 * (math.log(pos / paper["pos_m"]) + math.log(att / paper["att_deg"]))


def calibrate_camera(
    seeds: tuple[int, ...] = CALIBRATION_SEEDS,
    duration: float = CALIBRATION_DURATION_S,
    mismatch: Mismatch | None = None,
    iterations: int = 6,
) -> dict:
    """The pixel-noise scale at which the ideal camera's visual-only error matches seed 004's.

    The target is the paper's own visual-only accuracy (+-0.05 m, +-1 deg, ideal conditions),
    read as the RMSE without gross errors (the ``pos_clean_m`` / ``att_clean_deg`` of
    :func:`visual_stats`), on the walks of the development ``seeds`` with their mismatch draws.
    One parameter cannot hit two numbers: it zeroes the mean of ``log(pos / 0.05 m)`` and
    ``log(att / 1 deg)`` (secant steps on ``log(scale)``, from 1 and 4).

    Returns:
        ``{"pixel_noise_scale", "pixel_noise_px" (ideal camera), "pos_m", "att_deg", "seeds",
        "duration_s", "steps"}``: the last step's scale and its development-set errors.
    """
    runs = []
    for seed in seeds:
        setup = make_setup(seed, mismatch)
        runs.append((simulate("walk", duration, seed, setup), setup, seed))
    xs = [0.0, math.log(4.0)]
    fs = [_calibration_error(math.exp(x), runs) for x in xs]
    for _ in range(iterations):
        (x0, x1), (f0, f1) = xs[-2:], (fs[-2][2], fs[-1][2])
        if abs(f1) < 0.005 or f1 == f0:
            break
        x2 = min(max(x1 - f1 * (x1 - x0) / (f1 - f0), math.log(0.1)), math.log(100.0))
        xs.append(x2)
        fs.append(_calibration_error(math.exp(x2), runs))
    scale = math.exp(xs[-1])
    pos, att, _ = fs[-1]
    return {
        "pixel_noise_scale": scale,
        "pixel_noise_px": camera_spec("ideal").pixel_noise_px * scale,
        "pos_m": pos,
        "att_deg": att,
        "seeds": list(seeds),
        "duration_s": duration,
        "steps": [{"scale": math.exp(x), "pos_m": f[0], "att_deg": f[1]} for x, f in zip(xs, fs,
                                                                                      strict=True)],
    }  # fmt: skip


# ------------------------------------------------------------------------------------------------
# Fusion
# ------------------------------------------------------------------------------------------------


def fuse(traj: Trajectory, run: VisualRun, config: VioConfig) -> tuple[NDArray, NDArray, dict]:
    """The visual-inertial filter over the trajectory, started at the first visual pose.

    The filter is reset at the first frame with a pose: that pose, zero velocity (the user
    stands at the start), zero bias estimates (their uncertainty is the config's initial bias
    sigmas), and the IMU sample of that instant; it then runs over the remaining samples.

    Returns:
        ``(pos (N, 3), quat (N, 4), counters)``: the estimate after every IMU sample (NaN before
        the start sample), and the filter's frame counters with ``start`` (the first estimated
        sample).
    """
    n = traj.t.size
    first = np.flatnonzero(run.ok)
    pos = np.full((n, 3), np.nan)
    quat = np.full((n, 4), np.nan)
    if first.size == 0 or run.sample[first[0]] >= n - 1:
        return pos, quat, {"updates": 0, "rejected": 0, "forced": 0, "start": n}
    j0 = int(first[0])
    s0 = int(run.sample[j0])
    f = VisualInertialFilter(1, IMU_RATE_HZ, config)
    f.reset(run.position[j0], np.zeros(3), run.quat[j0], gyr=traj.gyr[s0], acc=traj.acc[s0])
    sel = run.sample > s0
    p, q, _ = f.process(
        traj.gyr[None, s0 + 1 :], traj.acc[None, s0 + 1 :],
        (run.sample[sel] - s0 - 1).astype(np.intp),
        run.position[None, sel], run.quat[None, sel], run.ok[None, sel],
    )  # fmt: skip
    pos[s0] = run.position[j0]
    quat[s0] = run.quat[j0]
    pos[s0 + 1 :] = p[0]
    quat[s0 + 1 :] = q[0]
    counters = {"updates": int(f.updates[0]), "rejected": int(f.rejected[0]),
                "forced": int(f.forced[0]), "start": s0}  # fmt: skip
    return pos, quat, counters


def _rms(x: NDArray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def _error_stats(ep: NDArray, ea: NDArray, samples: bool = True) -> dict:
    """RMSE, 95th percentile and max of position (m) and attitude (deg) errors; with
    ``samples`` (1 kHz series over the whole run) also windowed and first/last RMS."""
    if ep.size == 0:
        nan = float("nan")
        return {"pos_m": nan, "att_deg": nan, "pos_p95_m": nan, "att_p95_deg": nan,
                "pos_max_m": nan, "att_max_deg": nan}  # fmt: skip
    out = {
        "pos_m": _rms(ep),
        "att_deg": _rms(ea),
        "pos_p95_m": float(np.percentile(ep, 95)),
        "att_p95_deg": float(np.percentile(ea, 95)),
        "pos_max_m": float(ep.max()),
        "att_max_deg": float(ea.max()),
    }
    if samples:
        n = ep.size
        w = round(WINDOW_S * IMU_RATE_HZ)
        nw = max(n // w, 1)
        wp = [_rms(ep[i * w : (i + 1) * w]) for i in range(nw)]
        wa = [_rms(ea[i * w : (i + 1) * w]) for i in range(nw)]
        edge = min(round(30.0 * IMU_RATE_HZ), n // 4)
        out.update({
            "pos_window_max_m": float(max(wp)),
            "att_window_max_deg": float(max(wa)),
            "edge_s": edge / IMU_RATE_HZ,
            "pos_first_m": _rms(ep[:edge]),
            "pos_last_m": _rms(ep[-edge:]),
            "att_first_deg": _rms(ea[:edge]),
            "att_last_deg": _rms(ea[-edge:]),
        })  # fmt: skip
    return out


# ------------------------------------------------------------------------------------------------
# The experiment
# ------------------------------------------------------------------------------------------------


def _camera_rng(seed: int, key: int) -> BatchRng:
    return BatchRng([np.random.default_rng([seed, 10 + key])])


#: Order in which the PnP jobs are handed to the workers: the slowest conditions (many frames
#: where RANSAC finds no consensus and runs all its iterations) first, for a balanced finish.
_SOLVE_ORDER = ("complex", "occlusion", "low_light", "noisy", "motion_blur", "ideal")


def _solve_all(caps: dict[str, _Capture], workers: int) -> dict[str, list]:
    """PnP of every captured frame, in ``workers`` threads (1: in this one).

    Threads, not processes: OpenCV releases the GIL inside ``solvePnPRansac``, where ~90 % of
    the time goes (2 threads: 1.8x on 2 cores), and threads need no pickling, no process start
    and no ``if __name__ == "__main__"`` guard in the caller's script. The RANSAC of each call
    is seeded by OpenCV itself, so the poses do not depend on ``workers``.
    """
    if workers == 1:
        return {c: [_solve_block(job) for job in cap.jobs] for c, cap in caps.items()}
    order = sorted(caps, key=lambda c: _SOLVE_ORDER.index(c) if c in _SOLVE_ORDER else -1)
    with ThreadPoolExecutor(workers) as pool:
        futures = {c: [pool.submit(_solve_block, job) for job in caps[c].jobs] for c in order}
        return {c: [f.result() for f in futures[c]] for c in caps}


def _fused_stats(traj: Trajectory, pos: NDArray, quat: NDArray, start: int,
                 lo: int = 0, hi: int | None = None, samples: bool = True) -> tuple:
    """Errors of a fused run over samples ``[max(lo, start), hi)``, and the full-length series
    (NaN before the start) for the figure."""
    n = traj.t.size
    hi = n if hi is None else hi
    ep, ea = np.full(n, np.nan), np.full(n, np.nan)
    if start < n:
        ep[start:], ea[start:] = error_series(pos[start:], quat[start:], traj.pos[start:],
                                              traj.quat[start:])  # fmt: skip
    k = max(lo, start)
    return _error_stats(ep[k:hi], ea[k:hi], samples=samples), (ep, ea)


def run_vio(
    json_path: Path | None = None,
    duration: float = 120.0,
    seed: int = 0,
    out_dir: Path | None = None,
    workers: int = 2,
    verbose: bool = True,
    mismatch: Mismatch | None = None,
    pixel_noise_scale: float = PIXEL_NOISE_SCALE,
) -> dict:
    """All of seed 004's experiments; print the table beside the paper's, optionally write JSON
    and (with ``out_dir``) a figure of the errors over time.

    Args:
        json_path: where to write the results (JSON); None: not written.
        duration: length of every run, s, in [4, 600] and a multiple of 0.1 s (paper: 120).
        seed: random seed (not one of :data:`CALIBRATION_SEEDS` for held-out numbers).
        out_dir: folder for ``vio_errors.png``; None: no figure.
        workers: threads for the PnP (1: all in the calling thread).
        verbose: print the table.
        mismatch: the model mismatch drawn for the run; None: :class:`Mismatch` defaults
            (``Mismatch.none()``: the estimators told the simulator's truth).
        pixel_noise_scale: the cameras' pixel noise over the presets' (default: calibrated).

    Returns:
        The result dictionary (module docstring; ``pos_m`` / ``att_deg`` of the visual and fused
        rows are RMSEs, of the IMU-only rows the largest errors).
    """
    duration = float(duration)
    if not (4.0 <= duration <= 600.0) or abs(duration * 10 - round(duration * 10)) > 1e-6:
        raise ValueError(f"duration must be in [4, 600] s and a multiple of 0.1 s, got {duration}")
    if not (isinstance(workers, int) and workers >= 1):
        raise ValueError(f"workers must be an int >= 1, got {workers!r}")
    workers = min(workers, os.cpu_count() or 1)
    setup = make_setup(seed, mismatch)
    specs = {c: condition_spec(c, pixel_noise_scale) for c in VISUAL_CONDITIONS}
    noisy_px = NOISY_FACTOR * specs["ideal"].pixel_noise_px
    noisy_spec = camera_spec("low_light", name="noisy", pixel_noise_px=noisy_px)
    noisy_pnp = pnp_params(noisy_spec)
    result: dict = {
        "config": {
            "duration_s": duration, "seed": seed, "imu": IMU_PRESET, "imu_rate_hz": IMU_RATE_HZ,
            "camera_rate_hz": CAMERA_RATE_HZ, "rotation_rate_deg_s": ROTATION_RATE_DEG_S,
            "walk": {"radius_m": WALK_RADIUS_M, "cadence_hz": WALK_CADENCE,
                     "speed_m_s": _STRIDE_M * WALK_CADENCE},
            "room": "approach, 8 m x 8 m, 96 wall landmarks", "window_s": WINDOW_S,
            "pixel_noise_scale": pixel_noise_scale,
            "pixel_noise_px": {c: sp.pixel_noise_px for c, sp in specs.items()},
            "ransac_px": {c: pnp_params(sp).reprojection_px for c, sp in specs.items()},
            "calibration_seeds": list(CALIBRATION_SEEDS),
            "held_out": seed not in CALIBRATION_SEEDS,
            "complex_camera": {"condition": "low_light", "occluder_fraction": 0.3,
                               "match_prob": specs["complex"].match_prob},
            "adaptive_noisy_camera": {"condition": "low_light", "pixel_noise_px": noisy_px,
                                      "reprojection_px": noisy_pnp.reprojection_px,
                                      "switch_s": duration / 2},
            "setup": setup.summary(),
            "errors": "visual/fused pos_m, att_deg: RMSE; imu_only: largest over the run",
        },
        "paper": PAPER,
    }  # fmt: skip
    # IMU only.
    series: dict = {}
    result["imu_only"] = {}
    for kind in ("static", "rotation"):
        r = imu_only(simulate(kind, duration, seed, setup))
        series[f"imu_{kind}"] = r.pop("_series")
        result["imu_only"][kind] = r
    b = PAPER["imu_only"]["accel_accuracy_m_s2"]
    result["imu_only"]["paper_position_check"] = {
        "accel_accuracy_m_s2": b, "duration_s": 120.0, "position_from_bias_m": 0.5 * b * 120.0**2,
        "bias_for_0p2_m_m_s2": 2 * 0.2 / 120.0**2,
    }  # fmt: skip

    # Visual and fused on the walk.
    traj = simulate("walk", duration, seed, setup)
    half = traj.t.size // 2
    caps = {
        c: _capture(traj, specs[c], _camera_rng(seed, i), setup, pnp_params(specs[c]), 0)
        for i, c in enumerate(VISUAL_CONDITIONS)
    }
    caps["noisy"] = _capture(traj, noisy_spec, _camera_rng(seed, 99), setup, noisy_pnp, half)
    solved = _solve_all(caps, workers)
    runs = {c: _assemble(caps[c], solved[c]) for c in VISUAL_CONDITIONS}
    noisy = _assemble(caps["noisy"], solved["noisy"])
    result["visual_only"] = {c: visual_stats(r, traj) for c, r in runs.items()}
    result["fused"], result["fused_fixed"] = {}, {}
    for c, r in runs.items():
        for name, adaptive in (("fused", "sage_husa"), ("fused_fixed", "fixed")):
            p, q, counters = fuse(traj, r, filter_config(adaptive))
            stats, ser = _fused_stats(traj, p, q, counters["start"])
            result[name][c] = {**stats, **counters, "start_s": counters["start"] / IMU_RATE_HZ}
            if c in ("ideal", "complex"):
                series[f"{name}_{c}"] = ser

    # Adaptive vs fixed R: ideal frames before the switch, the noisy camera after it.
    ideal = runs["ideal"]
    first = ideal.sample < half
    mixed = VisualRun.concatenate([ideal.select(first), noisy])
    tuned = visual_stats(ideal.select(first), traj)
    sig_p, sig_a = tuned["pos_clean_m"] / math.sqrt(3), tuned["att_clean_deg"] / math.sqrt(3)
    result["adaptive"] = {
        "switch_s": float(traj.t[half]),
        "tuned_r": {"position_sigma_m": sig_p, "attitude_sigma_deg": sig_a},
        "visual_after_switch": visual_stats(noisy, traj),
    }
    for adaptive in ("fixed", "sage_husa"):
        p, q, counters = fuse(traj, mixed, filter_config(adaptive, sig_p, sig_a))
        after, ser = _fused_stats(traj, p, q, counters["start"], lo=half, samples=False)
        overall, _ = _fused_stats(traj, p, q, counters["start"], samples=False)
        before, _ = _fused_stats(traj, p, q, counters["start"], hi=half, samples=False)
        result["adaptive"][adaptive] = {
            "pos_m": after["pos_m"], "att_deg": after["att_deg"],
            "pos_p95_m": after["pos_p95_m"], "att_p95_deg": after["att_p95_deg"],
            "overall_pos_m": overall["pos_m"], "overall_att_deg": overall["att_deg"],
            "before_pos_m": before["pos_m"], "before_att_deg": before["att_deg"], **counters,
        }  # fmt: skip
        series[f"adaptive_{adaptive}"] = ser

    # Targets.
    met = {}
    for c, tgt in TARGETS.items():
        r = result["fused"][c]
        met[f"fused_{c}"] = bool(r["pos_m"] < tgt["pos_m"] and r["att_deg"] < tgt["att_deg"])
        met[f"fused_{c}_bounded"] = bool(r["pos_window_max_m"] < tgt["pos_m"]
                                         and r["att_window_max_deg"] < tgt["att_deg"])  # fmt: skip
    a = result["adaptive"]
    met["adaptive_beats_fixed"] = bool(
        a["sage_husa"]["pos_m"] < a["fixed"]["pos_m"]
        and a["sage_husa"]["att_deg"] < a["fixed"]["att_deg"]
    )
    met["fused_beats_visual_ideal"] = bool(
        result["fused"]["ideal"]["pos_m"] < result["visual_only"]["ideal"]["pos_clean_m"]
        and result["fused"]["ideal"]["att_deg"] < result["visual_only"]["ideal"]["att_clean_deg"]
    )
    result["targets"] = TARGETS
    result["targets_met"] = met

    if verbose:
        print(format_table(result))
    if json_path is not None:
        json_path = Path(json_path)
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(_finite(result), indent=2, allow_nan=False))
        if verbose:
            print(f"wrote {json_path}")
    if out_dir is not None:
        path = _figure(series, traj.t, Path(out_dir), result["adaptive"]["switch_s"])
        result["figure"] = str(path)
        if verbose:
            print(f"wrote {path}")
    return result


def _finite(x: object) -> object:
    """``x`` with NaN and infinities replaced by None (strict JSON)."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_finite(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _figure(series: dict, t: NDArray, out_dir: Path, switch_s: float) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(3, 2, figsize=(12, 9), sharex=True)
    for j, unit in enumerate(("position error (m)", "attitude error (deg)")):
        for key, label in (("imu_static", "static"), ("imu_rotation", "rotation 10 deg/s")):
            ax[0, j].plot(t, series[key][j], label=label)
        ax[0, j].set_title(f"IMU only: {unit}")
        for key, label in (("fused_ideal", "ideal, Sage-Husa"),
                           ("fused_fixed_ideal", "ideal, fixed R"),
                           ("fused_complex", "complex, Sage-Husa"),
                           ("fused_fixed_complex", "complex, fixed R")):  # fmt: skip
            ax[1, j].plot(t, series[key][j], lw=0.6, label=label)
        ax[1, j].set_title(f"fused, walk: {unit}")
        for key, label in (("adaptive_fixed", "fixed R"), ("adaptive_sage_husa", "Sage-Husa")):
            ax[2, j].plot(t, series[key][j], lw=0.6, label=label)
        ax[2, j].axvline(switch_s, color="k", ls="--", lw=0.8)
        ax[2, j].set_title(f"visual noise x12 after {switch_s:.0f} s: {unit}")
        ax[2, j].set_xlabel("time (s)")
        for a in ax[:, j]:
            a.legend(fontsize=7)
            a.grid(alpha=0.3)
    ax[0, 0].set_yscale("log")
    fig.tight_layout()
    path = out_dir / "vio_errors.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def format_table(result: dict) -> str:
    """The results beside seed 004's numbers, as plain text."""
    cfg, paper = result["config"], result["paper"]
    lines = [
        f"Seed 004 helmet pose: IMU {cfg['imu']} at {cfg['imu_rate_hz']:.0f} Hz, camera "
        f"{cfg['camera_rate_hz']:.0f} Hz, {cfg['duration_s']:.0f} s runs, seed {cfg['seed']}",
        "IMU only (strapdown, calibrated biases)   largest  |  at end       paper",
    ]
    io = result["imu_only"]
    pio = paper["imu_only"]
    for kind, label in (("static", "static"), ("rotation", "rotation 10 deg/s")):
        r = io[kind]
        pa = f"+-{pio[kind]['att_deg']:g}"
        pp = f"+-{pio[kind]['pos_m']:g} (*)" if "pos_m" in pio[kind] else "-"
        lines.append(f"  {label:<19} attitude (deg) {r['att_deg']:10.2f} | {r['att_end_deg']:8.2f}"
                     f"       {pa}")  # fmt: skip
        lines.append(f"  {'':<19} position (m)   {r['pos_m']:10.1f} | {r['pos_end_m']:8.1f}"
                     f"       {pp}")  # fmt: skip
    chk = io["paper_position_check"]
    lines.append(
        f"  (*) the paper's accelerometer accuracy {chk['accel_accuracy_m_s2']} m/s^2 alone gives "
        f"0.5 b t^2 = {chk['position_from_bias_m']:.0f} m in 120 s; +-0.2 m needs b <= "
        f"{chk['bias_for_0p2_m_m_s2']:.1e} m/s^2"
    )
    lines.append(
        f"Visual only (PnP per frame, walk; pixel noise x{cfg['pixel_noise_scale']:.2f} the "
        "presets, calibrated on the ideal row of seeds "
        f"{', '.join(map(str, cfg['calibration_seeds']))}"
        f"{'; this run is held-out' if cfg['held_out'] else '; IN-SAMPLE: a calibration seed'})"
    )
    lines.append(
        "  condition      RMSE pos (m) / att (deg)  no gross      p95          gross  avail  "
        "| paper: pos  att | extract match (model inputs)"
    )
    pv, pin = paper["visual_only"], paper["camera_inputs"]
    for c, r in result["visual_only"].items():
        p, pi = pv.get(c, {}), pin.get(c, {})

        def g(key: str, fmt: str, p: dict) -> str:
            return format(p[key], fmt) if key in p else "-"

        lines.append(
            f"  {c:<14} {r['pos_m']:12.3f} / {r['att_deg']:5.2f}   "
            f"{r['pos_clean_m']:5.3f}/{r['att_clean_deg']:4.2f}   "
            f"{r['pos_p95_m']:5.3f}/{r['att_p95_deg']:4.2f}   {100 * r['gross_fraction']:5.2f}%"
            f"  {r['availability']:5.2f}  |      {g('pos_m', '4.2f', p):>5} "
            f"{g('att_deg', '4.1f', p):>4}"
            f" | {r['extraction']:5.2f} {r['matching']:5.2f}  (set: "
            f"{g('extraction', '4.2f', pi)} / {g('matching', '4.2f', pi)})"
        )
    lines.append(
        f"  (no gross: RMSE without the poses off by > {GROSS_POS_M} m or > {GROSS_ATT_DEG:g} deg;"
        " the paper's +- bounds read as that RMSE. Extraction and matching rates are the camera"
        " model's inputs, set to the paper's; the measured rates check the model, they are not"
        " results)"
    )
    lines.append(
        "Fused (ESKF from the first PnP pose, datasheet noise)  RMSE pos (m) / att (deg)   p95"
        "          10 s max     first/last "
        f"{result['fused']['ideal']['edge_s']:.0f} s pos (m)   target"
    )
    for name, label in (("fused", "Sage-Husa"), ("fused_fixed", "fixed R")):
        for c, r in result[name].items():
            tgt = result["targets"].get(c)
            t = f"< {tgt['pos_m']:g} m, {tgt['att_deg']:g} deg" if tgt else ""
            lines.append(
                f"  {label:<9} {c:<12} {r['pos_m']:6.3f} / {r['att_deg']:5.2f}   "
                f"{r['pos_p95_m']:5.3f}/{r['att_p95_deg']:4.2f}   "
                f"{r['pos_window_max_m']:5.3f}/{r['att_window_max_deg']:4.2f}   "
                f"{r['pos_first_m']:5.3f} / {r['pos_last_m']:5.3f}     {t}"
            )
    a = result["adaptive"]
    tr = a["tuned_r"]
    noise = cfg["adaptive_noisy_camera"]["pixel_noise_px"]
    lines.append(
        f"Adaptive vs fixed R: ideal camera, then {noise:g} px noise after {a['switch_s']:.0f} s "
        f"(R tuned for ideal: {tr['position_sigma_m']:.4f} m, {tr['attitude_sigma_deg']:.3f} deg)"
    )
    lines.append("  filter     after switch: pos RMSE (m)  att RMSE (deg)   whole run: pos   att")
    for name in ("fixed", "sage_husa"):
        r = a[name]
        lines.append(f"  {name:<10} {r['pos_m']:27.4f} {r['att_deg']:15.3f} "
                     f"{r['overall_pos_m']:16.4f} {r['overall_att_deg']:6.3f}")  # fmt: skip
    met = result["targets_met"]
    lines.append("targets met: " + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in met.items()))
    return "\n".join(lines)
