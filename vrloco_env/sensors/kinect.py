"""Kinect v2 body-tracking model: joints, wrist orientation, tracking states and body ids.

The model turns the target user's true skeleton (world frame, from :mod:`vrloco_env.user.motion`)
into what the Kinect v2 SDK hands an application at 30 frames/s: up to six body slots, each with a
tracking id, 25 joints in camera space with a per-joint tracking state, and the right wrist's
orientation quaternion. It adds what makes the real sensor hard to use (seed 003, section 1):

* joint noise whose standard deviation grows with depth, part white and part temporally correlated
  (an AR(1) process), plus a per-session offset of every joint;
* jitter bursts: now and then one limb jitters strongly for a few frames;
* a noisy wrist orientation (white + AR(1) rotation noise: its level calibrated to seed 003
  Tables 1-3, its white share measured on a real Kinect v2 recording);
* tracking states: joints outside the field of view or depth range are not tracked (NaN); joints
  hidden behind a torso (the user's own or another body's), or in a short random episode, are
  *inferred* and noisier; a body with most of its joints out of view or hidden is lost, and gets a
  new id when it is acquired again;
* bystanders: other people standing and swaying farther away, now and then walking in or out of
  view, in random slots, so the target user must be chosen (nearest tracked body). Their noise has
  the same per-joint std, white fraction and time constants as the target's, but one noise vector
  per frame moves all their joints (and their wrist): a rigidly jittering skeleton, drawn at lower
  dimension for speed (an engineering decision: bystanders matter by where they stand and
  whom they hide, not by the shape of their jitter);
* optional latency of a whole number of frames.

Frames and conventions
----------------------
*World*: ENU, z up, the floor at z = 0 (see :mod:`estimators.rotations`).

*Camera space* follows the Kinect v2 SDK (``CameraSpacePoint``): origin at the depth sensor, +z out
of the sensor toward the scene, +y up, +x to the sensor's left (right-handed; a user facing the
sensor has her right hand at +x). :func:`world_to_camera` / :func:`camera_to_world` convert points;
:func:`quat_world_to_camera` / :func:`quat_camera_to_world` convert orientations.

*Hand frame* (what the motion model gives in the world): x along the forearm toward the
fingertips, y to the left of the palm (the thumb side of a right hand held palm-down), z out of the
back of the hand.

*Wrist frame* (what :attr:`KinectFrames.hand_quat` reports): the Kinect v2 SDK's joint frame for
WristRight. The SDK gives a joint's orientation as the absolute orientation, in camera space, of
the bone ending at the joint, with "bone direction Y, normal Z, binormal X" (Kinect v2 SDK
documentation, as answered on the MSDN Kinect v2 forum, 2014): +y along the forearm (elbow ->
wrist). We fix the two free axes as binormal x = back of the hand (hand z) and normal z = thumb side
(hand y), i.e. SDK (x, y, z) = hand (z, x, y) (:data:`HAND_FROM_SDK_WRIST`). The model reports
the hand's orientation in that convention (for a straight wrist the forearm and the hand's x axis
coincide; the poses of :func:`standing_skeleton` and motion.py keep the wrist straight).
``hand_quat`` is the Hamilton quaternion [w, x, y, z] rotating wrist-frame vectors into camera
space; :func:`hand_to_sdk_wrist` / :func:`sdk_wrist_to_hand` convert from / to the hand frame.

Seed 003's eq (1) on this quaternion — an engineering decision
----------------------------------------------------------------
Eq (1) names ``atan2(2(wx + yz), 1 - 2(x^2 + y^2))`` "yaw" (in :mod:`estimators.rotations`'s ZYX
naming that is the *roll*, ``quat_to_ypr(q)[..., 2]``, the rotation about the frame's own x axis),
``asin(2(wy - zx))`` "pitch" (our pitch, ``[..., 1]``) and ``atan2(2(wz + xy), 1 - 2(y^2 + z^2))``
"roll" (our *yaw* about z, ``[..., 0]``). With the SDK frame and the forearm pointing at the sensor
— the posture of :mod:`vrloco_env.user.motion` (right arm held forward, user facing the Kinect) and
of a user reaching toward it — these names are the hand's own, as for an aircraft whose nose is the
fingertips. Starting from the rest pose (palm down, pointing at the sensor) and rotating about one
hand axis:

    paper "roll"  = quat_to_ypr(q)[..., 0] =  90 deg - turn about the forearm (hand roll)
    paper "pitch" = quat_to_ypr(q)[..., 1] =           fingertips up/down    (hand pitch)
    paper "yaw"   = quat_to_ypr(q)[..., 2] = -90 deg + sweep left/right      (hand yaw)

(combined rotations couple, as for any Euler set). Eq (2)'s singularity is where the back of the
hand faces the sensor or away from it (e.g. fingertips straight up or down); the rest pose is
90 deg from it, and motion.py's hand limits (pitch within +-80 deg) stay clear of it for single-axis
rotations.

One would like the turn about the forearm to be the paper's "yaw", as the paper's text says
(its Tables 1-3 sweep "yaw" from -90 to 90 deg turning the hand about the bone). That cannot hold
together with the SDK's bone-on-+y convention: right-multiplying by a rotation about a frame axis
changes exactly the last ZYX angle only for the x axis, so "yaw" follows the forearm only if the
forearm is the x axis of the frame fed to eq (1) — and then eq (1) is singular (pitch = 90 deg)
whenever the forearm points at the sensor, which is motion.py's rest pose. We keep the SDK
convention, which is lock-free there, and read the paper's 11 "yaw angles" as turns about the
forearm: in this model they move eq (1)'s "roll". Whoever needs the other reading gets it with
``sdk_wrist_to_hand(q)`` (forearm on x; then eq (1)'s "yaw" is the turn, singular for a hand
pointing at the sensor but fine for a raised hand).

Randomness and speed
--------------------
Every number comes from the :class:`~vrloco_env.batch_rng.BatchRng` passed in:
:meth:`KinectV2.reset` draws the session (slots, ids, joint offsets, noise states, bystanders) and
:meth:`KinectV2.capture` draws a fixed block of normals per frame (125 with two bystanders; layout
and the devices that keep it small -- event thresholds, split uniforms, the white + AR(1) joint
noise as one ARMA(1, 1) process -- in :mod:`vrloco_env.sensors._kinect_numba`), so a batch of B
users reproduces B single runs bit for bit and a capture split into chunks equals one capture.
The frames are computed by one compiled kernel (``_kinect_numba.capture_frames``, explicit loops
over users, frames, bodies and joints; its uncompiled ``py_func`` is the reference the tests compare
it with): ``benchmarks/bench_sensors.py`` times a capture of 3 frames.
:meth:`KinectV2.reset` redraws all users, or only those given (``users=``), from their own
streams and leaving the others' state alone, so a vector env can start a new episode for one user
while the others carry on (every per-user state, the frame counter included, is a (B, ...) array).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtr, ndtri

from estimators.batching import stream_rows
from estimators.kernels import param_record, state_records
from estimators.rotations import (
    ensure_quaternion,
    matrix_to_quat,
    quat_conjugate,
    quat_from_ypr,
    quat_multiply,
    quat_rotate,
    quat_rotate_inverse,
    quat_to_matrix,
)
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors import _kinect_numba as _k
from vrloco_env.user import NOT_TRACKED, NUM_JOINTS, Joint

__all__ = [
    "HAND_FROM_SDK_WRIST",
    "LIMB_GROUPS",
    "MAX_BODIES",
    "TORSO_JOINTS",
    "KinectFrames",
    "KinectSpec",
    "KinectTruth",
    "KinectV2",
    "camera_quat",
    "camera_to_world",
    "hand_to_sdk_wrist",
    "quat_camera_to_world",
    "quat_world_to_camera",
    "sdk_wrist_to_hand",
    "standing_skeleton",
    "world_to_camera",
]

#: Bodies the Kinect v2 tracks at once (Microsoft Kinect for Windows v2 specification: six).
MAX_BODIES = _k.MAX_BODIES

J = Joint

#: Joints that make up the torso silhouette used for occlusion (they never hide behind their own
#: torso).
TORSO_JOINTS = (
    J.SPINE_BASE, J.SPINE_MID, J.NECK, J.SPINE_SHOULDER,
    J.SHOULDER_LEFT, J.SHOULDER_RIGHT, J.HIP_LEFT, J.HIP_RIGHT,
)  # fmt: skip

#: Limbs a jitter burst can hit (one at a time); index 0 is the right arm, which also carries the
#: reported wrist orientation.
LIMB_GROUPS = (
    (J.ELBOW_RIGHT, J.WRIST_RIGHT, J.HAND_RIGHT, J.HAND_TIP_RIGHT, J.THUMB_RIGHT),
    (J.ELBOW_LEFT, J.WRIST_LEFT, J.HAND_LEFT, J.HAND_TIP_LEFT, J.THUMB_LEFT),
    (J.KNEE_RIGHT, J.ANKLE_RIGHT, J.FOOT_RIGHT),
    (J.KNEE_LEFT, J.ANKLE_LEFT, J.FOOT_LEFT),
)

# Per-joint multiplier of the depth-dependent position noise. Extremities jitter more than the
# trunk: in the kinect_laban recording (../shared/data, Kinect v2, user at 2.7 m) the frame-to-frame
# jitter of hand tips and thumbs is 3-10 mm against <1 mm for spine, hips and shoulders, and
# clinical evaluations (Otte et al. 2016, PLoS ONE 11(11) e0166532) find hands and feet the least
# reliable joints. Engineering values: trunk/head 1, elbows/knees 1.5, wrists/ankles 2,
# hands/feet 2.5, hand tips/thumbs 4.
_DEFAULT_JOINT_SCALE = (
    1.0, 1.0, 1.0, 1.0,  # spine base, spine mid, neck, head
    1.0, 1.5, 2.0, 2.5,  # shoulder, elbow, wrist, hand (left)
    1.0, 1.5, 2.0, 2.5,  # shoulder, elbow, wrist, hand (right)
    1.0, 1.5, 2.0, 2.5,  # hip, knee, ankle, foot (left)
    1.0, 1.5, 2.0, 2.5,  # hip, knee, ankle, foot (right)
    1.0,  # spine shoulder
    4.0, 4.0, 4.0, 4.0,  # hand tip left, thumb left, hand tip right, thumb right
)  # fmt: skip


# --------------------------------------------------------------------------------------------------
# Specification


def _pair(value: object, name: str) -> tuple[float, float]:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (2,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be two finite numbers, got {value!r}")
    return float(arr[0]), float(arr[1])


def _check(cond: bool, msg: str) -> None:
    if not cond:
        raise ValueError(msg)


@dataclass(frozen=True)
class KinectSpec:
    """Parameters of the simulated Kinect v2 (all validated on construction).

    Sources are given per field. "Engineering choice" marks a value we set for a plausible sensor
    where no measurement was at hand; every such value is a field, so a study can vary it.
    """

    #: Body frame rate, Hz. Kinect v2 skeleton stream: 30 frames/s (Microsoft Kinect for Windows v2
    #: specification; seed 003 section 2.2).
    frame_rate_hz: float = 30.0
    #: Depth camera field of view (horizontal, vertical), deg: 70.6 x 60 (Microsoft specification).
    fov_deg: tuple[float, float] = (70.6, 60.0)
    #: Body-tracking depth range (near, far), m: 0.5-4.5 (Microsoft specification).
    depth_range_m: tuple[float, float] = (0.5, 4.5)
    #: Sensor position in the world, m. Default: 2.5 m east of the origin, 0.9 m above the floor
    #: (Kinect placed on a table, 0.8-1.0 m, as usual for body tracking), facing a user who stands
    #: at the origin facing east. Use :meth:`facing` to place it in front of any user.
    camera_position_m: tuple[float, float, float] = (2.5, 0.0, 0.9)
    #: Direction the sensor looks, rad, counter-clockwise from world +x (east). Default pi (west).
    camera_yaw_rad: float = math.pi
    #: Tilt of the sensor, deg; positive looks up. Range (-45, 45). Default 0 (level).
    camera_tilt_deg: float = 0.0

    #: Joint position noise std at depth z is ``a + b z^2`` (mm), times the per-joint scale. The
    #: quadratic growth is the Kinect v2 axial depth-noise model of Fankhauser et al. 2015 ("Kinect
    #: v2 for mobile robot navigation: evaluation and modeling", ICAR); the level is set to the
    #: 1-3 mm std of static joints (ankles, feet) in the kinect_laban recording at 2.7 m
    #: (a + b * 2.7^2 = 2.5 mm).
    joint_noise_a_mm: float = 1.0
    #: Quadratic coefficient of the joint noise std, mm/m^2 (see ``joint_noise_a_mm``).
    joint_noise_b_mm_per_m2: float = 0.2
    #: Fraction of the joint noise *variance* that is white; the rest is AR(1) with time constant
    #: ``joint_noise_tau_s``. The kinect_laban trunk joints wander by 1-3 mm but jitter frame to
    #: frame by only ~0.2-0.5 mm, so most of the noise is slow: 0.05 (engineering choice).
    joint_noise_white_fraction: float = 0.05
    #: Time constant of the correlated joint noise, s (engineering choice, matches the slow wander
    #: of kinect_laban's static joints).
    joint_noise_tau_s: float = 0.5
    #: Per-joint multiplier of the position noise, 25 values in JointType order (see module source
    #: for the reasoning: extremities noisier).
    joint_noise_scale: tuple[float, ...] = _DEFAULT_JOINT_SCALE
    #: Std of a per-session constant offset of each joint, m. Kinect joint centres sit centimetres
    #: away from the anatomical ones (Otte et al. 2016; Wang et al. 2015, "Evaluation of pose
    #: tracking accuracy in the first and second generations of Microsoft Kinect", ICHI). 0.01.
    joint_bias_std_m: float = 0.01
    #: Noise multiplier for an inferred joint (position and, for the wrist, orientation). The SDK
    #: guesses inferred joints; 3 (engineering choice).
    inferred_noise_factor: float = 3.0

    #: White part of the wrist orientation noise: std of a rotation vector about the hand frame's
    #: axes (x forearm, y thumb side, z back of hand), deg, at ``noise_ref_depth_m``.
    #:
    #: Level: the total variance per axis (white + AR(1); bursts come on top) is calibrated to
    #: seed 003 Tables 1-3, which give no spectrum: a static hand gives raw eq (1) variances of
    #: 0.5-14 deg^2 whose means over the 11 angles are "roll" 4.7 (about the forearm), "pitch" 3.5
    #: (about the thumb axis), "yaw" 6.5 deg^2 (about the back-of-hand normal); tests/test_kinect.py
    #: checks it at the paper's 11 angles. Totals (4.32, 3.22, 6.17) deg^2.
    #:
    #: Split (which share is white, frame to frame): measured on the real Kinect v2 recording
    #: kinect_laban/Ges01_wavehand.csv, whose left arm hangs still while the right hand waves. The
    #: SDK does not say how it computes a joint's orientation; the joints that carry the wrist's
    #: are the forearm's and the hand's, so a frame built from them (x ElbowLeft -> WristLeft,
    #: y toward ThumbLeft) stands for it. Its rotation-vector variogram, fitted with a white
    #: "nugget" plus an exponential (AR(1)) part plus a quadratic drift for the body's own motion
    #: (``agents.experiments.hand_variance.recording_orientation_noise``, printed by
    #: ``vrloco experiment hand-variance``), gives: about the forearm 76 % of the variance white
    #: (the thumb joint jitters frame to frame: its first differences are as large as its
    #: spread); about the two bending axes no white part at all (fitted nugget 0: the variogram
    #: starts near zero and rises steadily), as slow as the trunk joints, whose 5 % white share
    #: (``joint_noise_white_fraction``) we take. On simulated series of the recording's 154 frames
    #: the fit's white share spreads by about +-0.15 (tests/test_hand.py checks the estimator on
    #: known noise). So the split is 80 % white about the forearm and 5 % about y and z: std
    #: sqrt(share x total).
    hand_rot_white_std_deg: tuple[float, float, float] = (1.86, 0.40, 0.56)
    #: Correlated (AR(1)) part of the wrist orientation noise, deg: the rest of each axis's
    #: variance (see ``hand_rot_white_std_deg``), 20 % about the forearm, 95 % about y and z.
    hand_rot_ar_std_deg: tuple[float, float, float] = (0.93, 1.75, 2.42)
    #: Time constant of the correlated orientation noise, s. 0.5 s, the joints' own
    #: (``joint_noise_tau_s``, the slow wander of kinect_laban's static joints). The forearm
    #: frame's fits do not pin it down: 0.16 s about the forearm (a quarter of that axis's
    #: variance), 0.18 s about the normal, 1.1 s about the thumb axis (where the arm's own slow
    #: motion is not told apart from noise in 5 s of data).
    hand_rot_tau_s: float = 0.5
    #: Depth at which ``hand_rot_*_std_deg`` hold, m; the orientation noise scales with the joint
    #: noise std ``a + b z^2`` at the wrist's depth relative to this one. 2.2 m: the hand of a user
    #: standing 2.5 m away and reaching toward the sensor (seed 003 does not state its distance).
    noise_ref_depth_m: float = 2.2

    #: Probability per frame and body that a jitter burst starts (engineering choice: one every
    #: ~7 s, the rate of the visible limb glitches of a Kinect v2 skeleton).
    burst_prob: float = 0.005
    #: Burst duration range (min, max), frames, drawn uniformly (engineering choice: 2-8 frames,
    #: 70-270 ms).
    burst_frames: tuple[int, int] = (2, 8)
    #: Extra white position noise of the burst limb's joints, std in m (engineering choice).
    burst_position_std_m: float = 0.02
    #: Extra white wrist rotation noise when the burst hits the right arm, std per axis, deg
    #: (engineering choice).
    burst_rotation_std_deg: float = 4.0

    #: Delay between capture and delivery, whole frames (0 = none).
    latency_frames: int = 0

    #: Half-width added around the torso silhouette (shoulders/hips) for occlusion, m (engineering
    #: choice: arm and clothing thickness).
    torso_margin_m: float = 0.05
    #: A joint is hidden by a torso when it lies this much deeper than the torso's joints, m
    #: (engineering choice: about half a chest depth).
    occlusion_depth_m: float = 0.08
    #: Probability per joint and frame that a random inferred episode starts (self-occlusion by
    #: clothing, fingers; engineering choice).
    random_inferred_prob: float = 0.001
    #: Mean length of a random inferred episode, frames (exponential; engineering choice).
    random_inferred_frames: float = 5.0
    #: A body is lost when fewer than this fraction of its joints are in view and not hidden by
    #: another body (engineering choice: "most joints out of view").
    min_visible_fraction: float = 0.5
    #: Consecutive detectable frames before a (re)appearing body is tracked and given an id
    #: (engineering choice: 5 frames, 170 ms).
    acquire_frames: int = 5

    #: Other people in the room, 0-5 (Kinect tracks six bodies).
    n_bystanders: int = 2
    #: Distance of the bystanders' area from the sensor along its axis (near, far), m. It must lie
    #: beyond the user so that the target is the nearest body; the far end beyond the depth range
    #: lets bystanders walk out of range.
    bystander_distance_m: tuple[float, float] = (3.2, 5.0)
    #: Half-width of the bystanders' area across the sensor axis, m (wider than the field of view,
    #: 2.3-3.5 m at those distances, so they walk in and out of view).
    bystander_lateral_m: float = 3.5
    #: Mean time a bystander stands before walking to a new spot, s (engineering choice).
    bystander_dwell_s: float = 6.0
    #: Walking speed range of bystanders, m/s (typical indoor walking, 0.8-1.4 m/s).
    bystander_speed_mps: tuple[float, float] = (0.8, 1.4)
    #: Standing height range of bystanders, m (adult range).
    bystander_height_m: tuple[float, float] = (1.55, 1.90)

    def __post_init__(self) -> None:
        _check(
            math.isfinite(self.frame_rate_hz) and self.frame_rate_hz > 0,
            f"frame_rate_hz must be > 0 Hz, got {self.frame_rate_hz}",
        )
        h, v = _pair(self.fov_deg, "fov_deg")
        _check(
            0 < h < 180 and 0 < v < 180,
            f"fov_deg must be two angles in (0, 180) deg, got {self.fov_deg}",
        )
        near, far = _pair(self.depth_range_m, "depth_range_m")
        _check(0 < near < far, f"depth_range_m must satisfy 0 < near < far (m), got {(near, far)}")
        pos = np.asarray(self.camera_position_m, dtype=np.float64)
        _check(
            pos.shape == (3,) and bool(np.all(np.isfinite(pos))),
            f"camera_position_m must be three finite numbers (m), got {self.camera_position_m!r}",
        )
        _check(
            math.isfinite(self.camera_yaw_rad),
            f"camera_yaw_rad must be finite, got {self.camera_yaw_rad}",
        )
        _check(
            -45 < self.camera_tilt_deg < 45,
            f"camera_tilt_deg must lie in (-45, 45) deg, got {self.camera_tilt_deg}",
        )
        for name in (
            "joint_noise_a_mm", "joint_noise_b_mm_per_m2", "joint_bias_std_m",
            "burst_position_std_m", "burst_rotation_std_deg", "torso_margin_m",
            "occlusion_depth_m",
        ):  # fmt: skip
            val = getattr(self, name)
            _check(math.isfinite(val) and val >= 0, f"{name} must be >= 0, got {val}")
        _check(
            0 <= self.joint_noise_white_fraction <= 1,
            f"joint_noise_white_fraction must lie in [0, 1], got {self.joint_noise_white_fraction}",
        )
        for name in (
            "joint_noise_tau_s",
            "hand_rot_tau_s",
            "noise_ref_depth_m",
            "bystander_dwell_s",
        ):
            val = getattr(self, name)
            _check(math.isfinite(val) and val > 0, f"{name} must be > 0, got {val}")
        scale = np.asarray(self.joint_noise_scale, dtype=np.float64)
        _check(
            scale.shape == (NUM_JOINTS,) and bool(np.all(np.isfinite(scale) & (scale > 0))),
            f"joint_noise_scale must be {NUM_JOINTS} positive numbers, "
            f"got {self.joint_noise_scale!r}",
        )
        for name in ("hand_rot_white_std_deg", "hand_rot_ar_std_deg"):
            val = np.asarray(getattr(self, name), dtype=np.float64)
            _check(
                val.shape == (3,) and bool(np.all(np.isfinite(val) & (val >= 0))),
                f"{name} must be three numbers >= 0 (deg), got {getattr(self, name)!r}",
            )
        _check(
            math.isfinite(self.inferred_noise_factor) and self.inferred_noise_factor >= 1,
            f"inferred_noise_factor must be >= 1, got {self.inferred_noise_factor}",
        )
        for name in ("burst_prob", "random_inferred_prob"):
            val = getattr(self, name)
            _check(0 <= val <= 1, f"{name} must lie in [0, 1], got {val}")
        lo, hi = _pair(self.burst_frames, "burst_frames")
        _check(
            lo == int(lo) and hi == int(hi) and 1 <= lo <= hi,
            f"burst_frames must be whole numbers 1 <= min <= max, got {self.burst_frames}",
        )
        _check(
            isinstance(self.latency_frames, (int, np.integer)) and self.latency_frames >= 0,
            f"latency_frames must be an integer >= 0, got {self.latency_frames!r}",
        )
        _check(
            math.isfinite(self.random_inferred_frames) and self.random_inferred_frames >= 1,
            f"random_inferred_frames must be >= 1, got {self.random_inferred_frames}",
        )
        _check(
            0 < self.min_visible_fraction <= 1,
            f"min_visible_fraction must lie in (0, 1], got {self.min_visible_fraction}",
        )
        _check(
            isinstance(self.acquire_frames, (int, np.integer)) and self.acquire_frames >= 1,
            f"acquire_frames must be an integer >= 1, got {self.acquire_frames!r}",
        )
        _check(
            isinstance(self.n_bystanders, (int, np.integer))
            and 0 <= self.n_bystanders <= MAX_BODIES - 1,
            f"n_bystanders must be an integer in [0, {MAX_BODIES - 1}], got {self.n_bystanders!r}",
        )
        near_b, far_b = _pair(self.bystander_distance_m, "bystander_distance_m")
        _check(
            0 < near_b <= far_b,
            f"bystander_distance_m must satisfy 0 < near <= far (m), got {(near_b, far_b)}",
        )
        _check(
            math.isfinite(self.bystander_lateral_m) and self.bystander_lateral_m >= 0,
            f"bystander_lateral_m must be >= 0, got {self.bystander_lateral_m}",
        )
        s0, s1 = _pair(self.bystander_speed_mps, "bystander_speed_mps")
        _check(0 < s0 <= s1, f"bystander_speed_mps must satisfy 0 < min <= max, got {(s0, s1)}")
        h0, h1 = _pair(self.bystander_height_m, "bystander_height_m")
        _check(0 < h0 <= h1, f"bystander_height_m must satisfy 0 < min <= max, got {(h0, h1)}")

    @classmethod
    def facing(
        cls,
        user_position_m: ArrayLike,
        user_yaw_rad: float,
        distance_m: float = 2.5,
        height_m: float = 0.9,
        **kwargs: object,
    ) -> KinectSpec:
        """A spec with the sensor ``distance_m`` in front of a user, looking back at her.

        Args:
            user_position_m: the user's floor position in the world, (2,) or (3,) m.
            user_yaw_rad: the direction the user faces, rad (CCW from east).
            distance_m: horizontal distance from the user to the sensor, m (> 0).
            height_m: sensor height above the floor, m.
            **kwargs: any other :class:`KinectSpec` field.

        Returns:
            The spec.
        """
        p = np.asarray(user_position_m, dtype=np.float64)
        if p.shape not in ((2,), (3,)) or not np.all(np.isfinite(p)):
            raise ValueError(f"user_position_m must be 2 or 3 finite numbers, got {p.shape}")
        if not (math.isfinite(distance_m) and distance_m > 0):
            raise ValueError(f"distance_m must be > 0 m, got {distance_m}")
        fwd = np.array([math.cos(user_yaw_rad), math.sin(user_yaw_rad)])
        xy = p[:2] + distance_m * fwd
        return cls(
            camera_position_m=(float(xy[0]), float(xy[1]), float(height_m)),
            camera_yaw_rad=float(user_yaw_rad + math.pi),
            **kwargs,  # type: ignore[arg-type]
        )

    def joint_noise_std_m(self, depth_m: ArrayLike) -> NDArray[np.float64]:
        """Total position-noise std of a scale-1 tracked joint at a depth, m (white + AR(1))."""
        z = np.asarray(depth_m, dtype=np.float64)
        return (self.joint_noise_a_mm + self.joint_noise_b_mm_per_m2 * z**2) * 1e-3

    def with_(self, **changes: object) -> KinectSpec:
        """A copy with some fields changed (validated)."""
        return replace(self, **changes)  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------------
# Frames


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


# --------------------------------------------------------------------------------------------------
# Skeleton template

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


# --------------------------------------------------------------------------------------------------
# The sensor

# Each joint's place in each burst limb (-1: not in it): the target's burst noise normals.
_LIMB_INDEX = np.full((len(LIMB_GROUPS), NUM_JOINTS), -1.0)
for _g, _members in enumerate(LIMB_GROUPS):
    _LIMB_INDEX[_g, list(_members)] = np.arange(len(_members))
_ID_SCALE = float(2**53)
_BELOW_ONE = np.nextafter(1.0, 0.0)  # ndtr(z) rounds to 1.0 for z > 8.3; keep uniforms < 1
# A bystander: the standing skeleton of height 1 m facing +x with its pelvis over the origin, and
# its right hand's orientation (hand frame -> body frame). Joints scale with the height.
_BYSTANDER_TEMPLATE, _BYSTANDER_HAND = standing_skeleton(np.zeros(3), 0.0, 1.0)
if (len(LIMB_GROUPS), len(TORSO_JOINTS)) != (_k.N_LIMB_GROUPS, _k.N_TORSO_JOINTS) or max(
    map(len, LIMB_GROUPS)
) > _k.MAX_LIMB_JOINTS:  # pragma: no cover - the kernel's table sizes must match
    raise ImportError("vrloco_env.sensors._kinect_numba disagrees with the limb and torso tables")


def _unique_ids(ids: NDArray[np.int64], fresh: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Make the ``fresh`` ids of each row (user) differ from every other id of that row.

    Ids are 53 random bits, so two bodies of a user share one with probability ~N^2 / 2^54
    (never in practice); should it happen, the later fresh id is moved to the next free value
    (deterministic, per user, no draw), so ids are unique within a user's frame by construction.
    The capture kernel applies the same rule frame by frame (``_kinect_numba._unique_ids``).
    """
    if not fresh.any():  # the common case: no body (re)acquired in this frame
        return ids
    n = ids.shape[-1]
    earlier = np.tri(n, k=-1, dtype=bool)  # earlier[j, k]: body k comes before body j
    while True:
        same = ids[..., :, None] == ids[..., None, :]  # (B, N, N)
        # A fresh id clashes with a non-fresh one, or with an earlier fresh one.
        clash = fresh & np.any(same & (~fresh[..., None, :] | earlier), axis=-1)
        if not clash.any():
            return ids
        ids = np.where(clash, ids % (2**53) + 1, ids)


def _z_threshold(p: float) -> float:
    """The normal ``z`` below which an event of probability ``p`` happens: ndtr(z) < p."""
    return float(ndtri(p)) if 0.0 < p < 1.0 else (-math.inf if p <= 0.0 else math.inf)


class KinectV2:
    """Stateful, batched Kinect v2 body tracker for B simulated users (one sensor per user).

    Args:
        spec: sensor parameters.
        rng: per-user random streams; its batch size is B.

    Call :meth:`reset` at the start of every session, then :meth:`capture` with the target user's
    true skeleton at the Kinect rate, in one call or in chunks (identical results).
    ``reset(users=...)`` starts a new session for some users only; the others carry on.

    The frame loop runs in one compiled kernel, :func:`vrloco_env.sensors._kinect_numba.
    capture_frames` (its uncompiled ``py_func`` is the readable reference the tests compare with).
    """

    def __init__(self, spec: KinectSpec, rng: BatchRng) -> None:
        if not isinstance(spec, KinectSpec):
            raise TypeError(f"spec must be a KinectSpec, got {type(spec).__name__}")
        if not isinstance(rng, BatchRng):
            raise TypeError(
                f"rng must be a vrloco_env.batch_rng.BatchRng, got {type(rng).__name__}"
            )
        self.spec = spec
        self.rng = rng
        self.batch_size = rng.batch_size
        self.n_bodies = 1 + int(spec.n_bystanders)
        self._dt = 1.0 / spec.frame_rate_hz
        self._rho_joint = math.exp(-self._dt / spec.joint_noise_tau_s)
        self._rho_hand = math.exp(-self._dt / spec.hand_rot_tau_s)
        self._ready = np.zeros(self.batch_size, dtype=bool)  # per user: reset at least once
        self._arma = _k.arma_parameters(spec.joint_noise_white_fraction, self._rho_joint)
        self._draws = _k.draw_size(self.n_bodies)  # normals per user and frame
        self._id_cols = _k.Z_BODIES + _k.BODY_DRAWS * np.arange(self.n_bodies) + _k.B_NEW_ID
        self._prm = self._param_record()
        self._geo = self._geometry()

    def _param_record(self) -> NDArray:
        """The kernel's parameter record: the spec's numeric fields and the derived values the
        kernel reads (SI units)."""
        s = self.spec
        near, far = s.depth_range_m
        (by_d0, by_d1), (by_v0, by_v1) = s.bystander_distance_m, s.bystander_speed_mps
        burst_min, burst_max = s.burst_frames
        return param_record(
            s,
            tan_h=math.tan(math.radians(s.fov_deg[0]) / 2),
            tan_v=math.tan(math.radians(s.fov_deg[1]) / 2),
            near=near, far=far,
            noise_a=s.joint_noise_a_mm * 1e-3,  # m: joint noise std at depth z is a + b z^2
            noise_b=s.joint_noise_b_mm_per_m2 * 1e-3,  # m / m^2
            rho_joint=self._rho_joint,  # AR(1) coefficients per frame, joints and wrists
            rho_hand=self._rho_hand,
            arma_s=self._arma[0],  # the target's joint noise as ARMA(1, 1) (arma_parameters)
            arma_theta=self._arma[1],
            ref_std=float(s.joint_noise_std_m(s.noise_ref_depth_m)),  # m
            burst_rot=math.radians(s.burst_rotation_std_deg),
            burst_z=_z_threshold(s.burst_prob),
            inferred_q=math.exp(-1.0 / s.random_inferred_frames),  # ratio of episode lengths
            # a standing bystander starts walking when its normal lies below walk_z
            walk_z=_z_threshold(1.0 - math.exp(-self._dt / s.bystander_dwell_s)),
            dt=self._dt,
            by_d0=by_d0, by_d1=by_d1, by_v0=by_v0, by_v1=by_v1,
            cam_cos=math.cos(s.camera_yaw_rad), cam_sin=math.sin(s.camera_yaw_rad),
            burst_min=burst_min, burst_max=burst_max,
        )  # fmt: skip

    def _geometry(self) -> NDArray:
        """The kernel's record of the sensor's pose and the per-joint tables
        (``_kinect_numba.GEOMETRY_FIELDS``)."""
        s = self.spec
        geo = state_records(_k.GEOMETRY_FIELDS, 1)
        g = geo[0]
        q_cam = camera_quat(s)
        g["cam_rot"] = quat_to_matrix(q_cam)
        g["cam_pos"] = s.camera_position_m
        g["cam_quat"] = q_cam
        g["sdk_from_hand"] = HAND_FROM_SDK_WRIST
        g["by_template"] = _BYSTANDER_TEMPLATE
        g["by_hand_quat"] = _BYSTANDER_HAND
        g["joint_scale"] = s.joint_noise_scale
        g["hand_white_sd"] = np.radians(np.asarray(s.hand_rot_white_std_deg, np.float64))
        g["hand_ar_sd"] = np.radians(np.asarray(s.hand_rot_ar_std_deg, np.float64))
        p = s.random_inferred_prob
        g["inferred_z"] = [_z_threshold(1.0 - (1.0 - p) ** k) for k in range(NUM_JOINTS + 1)]
        g["limb_index"] = _LIMB_INDEX
        g["is_torso"][list(TORSO_JOINTS)] = 1.0
        g["torso_joints"] = TORSO_JOINTS
        return geo

    # ----------------------------------------------------------------------------------- session

    def reset(self, users: ArrayLike | None = None) -> None:
        """Start a session for some or all users: slots, ids, offsets, noise states, bystanders.

        Each reset user draws one block of normals from its own stream; the state of the other
        users (their slots, ids, noise and burst states, bystanders, delay line and frame counter)
        and their streams are untouched. So after ``rng.reseed(i, g)`` and ``reset(users=[i])``
        user i continues exactly as a single-user ``KinectV2`` on ``BatchRng([g])`` that was just
        reset (a vector env's autoreset), and the others as if nothing happened.

        Args:
            users: the users to reset, as indices or a (B,) boolean mask; None resets all. Every
                user must have been reset once before :meth:`capture`.

        Raises:
            ValueError: an index outside [0, B), a repeated index or a mask of the wrong shape.
        """
        s, B, N = self.spec, self.batch_size, self.n_bodies
        rows = stream_rows(users, B)
        if not hasattr(self, "_state"):
            self._allocate()
        R, nb = rows.size, N - 1
        st = self._state
        # One draw per reset user (uniforms are the normal CDF of the user's single stream).
        nj3 = NUM_JOINTS * 3
        sizes = (MAX_BODIES, N, N * nj3, nj3, nj3, N * 3, nb * 3, nb * 7)
        z = self.rng.normal((sum(sizes),), rows=rows)
        parts = np.split(z, np.cumsum(sizes)[:-1], axis=1)
        slot_u, id_u = ndtr(parts[0]), np.minimum(ndtr(parts[1]), _BELOW_ONE)
        # Slots: a random permutation of the 6 slots per user; body 0 (the target) takes the first.
        slots = np.argsort(slot_u, axis=1)[:, :N]
        self._target_slot[rows] = slots[:, :1]
        st["slot"][rows, :N] = slots
        st["body_id"][rows, :N] = _unique_ids(self._new_ids(id_u), np.ones((R, N), dtype=bool))
        st["acquired"][rows] = int(s.acquire_frames)
        st["prev_tracked"][rows] = 1.0
        st["bias"][rows, :N] = s.joint_bias_std_m * parts[2].reshape(R, N, NUM_JOINTS, 3)
        # Noise states, started stationary: the target's ARMA(1, 1) joint noise (y, e) with
        # var(y) = 1 and cov(y, e) = s; unit AR(1) states of every wrist and of the bystanders'
        # rigid joint noise.
        s_arma = self._arma[0]
        st["joint_innov"][rows] = parts[3].reshape(R, NUM_JOINTS, 3)
        st["joint_noise"][rows] = (
            s_arma * parts[3] + math.sqrt(max(1.0 - s_arma**2, 0.0)) * parts[4]
        ).reshape(R, NUM_JOINTS, 3)
        st["ar_hand"][rows, :N] = parts[5].reshape(R, N, 3)
        st["ar_by"][rows, :nb] = parts[6].reshape(R, nb, 3)
        st["burst_left"][rows] = 0.0
        st["burst_group"][rows] = 0.0
        st["inferred_left"][rows] = 0.0
        st["frame"][rows] = 0.0
        # Bystanders, in the sensor's floor frame (d along the axis, l to the sensor's left).
        u = np.minimum(ndtr(parts[7]), _BELOW_ONE).reshape(R, nb, 7)
        d0, d1 = s.bystander_distance_m
        local = np.stack(
            [d0 + (d1 - d0) * u[..., 0], s.bystander_lateral_m * (2 * u[..., 1] - 1)], axis=-1
        )
        st["by_pos"][rows, :nb] = self._floor_to_world(local)
        # Facing the sensor within +-30 deg (engineering choice: people near a screen face it).
        yaw = s.camera_yaw_rad + math.pi + math.radians(30.0) * (2 * u[..., 2] - 1)
        st["by_yaw"][rows, :nb] = yaw
        h0, h1 = s.bystander_height_m
        st["by_height"][rows, :nb] = h0 + (h1 - h0) * u[..., 3]
        # Quiet-standing sway: 5-20 mm at 0.15-0.4 Hz, the amplitude and band of the body's sway
        # in quiet stance (Winter 1995, "Human balance and posture control during standing and
        # walking", Gait & Posture 3(4)); applied as a lateral shift of the whole skeleton.
        st["by_sway_amp"][rows, :nb] = 0.005 + 0.015 * u[..., 4]
        st["by_sway_freq"][rows, :nb] = 0.15 + 0.25 * u[..., 5]
        st["by_sway_phase"][rows, :nb] = 2 * math.pi * u[..., 6]
        st["by_target"][rows] = st["by_pos"][rows]
        st["by_speed"][rows] = 0.0
        st["by_moving"][rows] = 0.0
        # Latency delay line, filled with empty frames: nothing delivered yet.
        empty = self._empty_slots(int(s.latency_frames))
        for k, v in self._delay.items():
            v[rows] = empty[k][rows]
        self._ready[rows] = True

    def _allocate(self) -> None:
        """Create the per-user session records (``_kinect_numba.STATE_FIELDS``) and the delay
        line, before the first :meth:`reset`."""
        self._state = state_records(_k.STATE_FIELDS, self.batch_size)
        self._target_slot = np.zeros((self.batch_size, 1), dtype=np.int64)
        self._delay = self._empty_slots(int(self.spec.latency_frames))

    def _new_ids(self, u: NDArray[np.float64]) -> NDArray[np.int64]:
        # A uniform double holds 53 random bits; ids are 1 .. 2^53 (the SDK's are opaque uint64).
        return (np.floor(u * _ID_SCALE) + 1).astype(np.int64)

    def _floor_to_world(self, local: NDArray[np.float64]) -> NDArray[np.float64]:
        s = self.spec
        c, sn = math.cos(s.camera_yaw_rad), math.sin(s.camera_yaw_rad)
        x = s.camera_position_m[0] + local[..., 0] * c - local[..., 1] * sn
        y = s.camera_position_m[1] + local[..., 0] * sn + local[..., 1] * c
        return np.stack([x, y], axis=-1)

    def _empty_slots(self, m: int) -> dict[str, NDArray]:
        B, K = self.batch_size, MAX_BODIES
        return {
            "body_id": np.zeros((B, m, K), dtype=np.int64),
            "body_tracked": np.zeros((B, m, K), dtype=bool),
            "joints": np.full((B, m, K, NUM_JOINTS, 3), np.nan),
            "joint_state": np.full((B, m, K, NUM_JOINTS), NOT_TRACKED, dtype=np.int8),
            "hand_quat": np.full((B, m, K, 4), np.nan),
        }

    # ----------------------------------------------------------------------------------- capture

    def _validate(
        self, t: ArrayLike, joints_world: ArrayLike, hand_quat_world: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        B = self.batch_size
        jw = np.asarray(joints_world, dtype=np.float64)
        if jw.ndim != 4 or jw.shape[0] != B or jw.shape[2:] != (NUM_JOINTS, 3):
            raise ValueError(
                f"joints_world must have shape (B={B}, M, {NUM_JOINTS}, 3) m, got {jw.shape}"
            )
        M = jw.shape[1]
        if M < 1:
            raise ValueError("joints_world must hold at least one frame (M >= 1)")
        if not np.isfinite(jw).all():
            raise ValueError(
                "joints_world contains NaN or infinite positions; truth must be finite"
            )
        q = np.asarray(hand_quat_world, dtype=np.float64)
        if q.shape != (B, M, 4):
            raise ValueError(f"hand_quat_world must have shape (B={B}, M={M}, 4), got {q.shape}")
        q = ensure_quaternion(q, "hand_quat_world")
        tt = np.asarray(t, dtype=np.float64)
        if tt.shape == (M,):
            tt = np.broadcast_to(tt, (B, M))
        if tt.shape != (B, M):
            raise ValueError(f"t must have shape (M={M},) or (B={B}, M={M}) s, got {tt.shape}")
        if not np.isfinite(tt).all():
            raise ValueError("t contains NaN or infinite times")
        return tt.copy(), np.ascontiguousarray(jw), q

    def capture(
        self,
        t: ArrayLike,
        joints_world: ArrayLike,
        hand_quat_world: ArrayLike,
        validated: bool = False,
    ) -> KinectFrames:
        """Sense M frames of the target user (and the bystanders).

        Args:
            t: frame times, (M,) or (B, M) s, at the Kinect rate (the model steps its noise and the
                bystanders by ``1 / frame_rate_hz`` per frame; ``t`` is passed through).
            joints_world: the target user's true joints in the world, (B, M, 25, 3) m, finite.
            hand_quat_world: the target's true right-hand orientation, hand frame -> world,
                (B, M, 4), finite and non-zero.

            validated: the caller promises float64 C-contiguous arrays of those shapes, finite,
                with unit quaternions (the env's motion model makes them so): the checks are
                skipped.

        Returns:
            The delivered frames (delayed by ``latency_frames``) and the undelayed truth.
        """
        if not self._ready.all():
            missing = np.flatnonzero(~self._ready).tolist()
            raise RuntimeError(
                f"call KinectV2.reset() before capture() (users {missing} never were)"
            )
        if validated:
            jw, qw = joints_world, hand_quat_world
            t = t[None, :].repeat(self.batch_size, 0) if t.ndim == 1 else t.copy()
        else:
            t, jw, qw = self._validate(t, joints_world, hand_quat_world)
        B, M, K = self.batch_size, jw.shape[1], MAX_BODIES
        # One draw per call, a fixed block of normals per frame (layout in _kinect_numba), so
        # that a capture in chunks equals one capture.
        z = self.rng.normal((M, self._draws))
        new_ids = self._new_ids(np.minimum(ndtr(z[:, :, self._id_cols]), _BELOW_ONE))
        out = {
            "body_id": np.empty((B, M, K), dtype=np.int64),
            "body_tracked": np.empty((B, M, K), dtype=bool),
            "joints": np.empty((B, M, K, NUM_JOINTS, 3)),
            "joint_state": np.empty((B, M, K, NUM_JOINTS), dtype=np.int8),
            "hand_quat": np.empty((B, M, K, 4)),
        }
        truth_joints = np.empty((B, M, NUM_JOINTS, 3))
        truth_hand = np.empty((B, M, 4))
        _k.capture_frames(B)(
            jw, qw, z, new_ids, self._prm, self._geo, self._state,
            (out["body_id"], out["body_tracked"], out["joints"], out["joint_state"],
             out["hand_quat"], truth_joints, truth_hand),
        )  # fmt: skip
        L = int(self.spec.latency_frames)
        if L:
            joined = {k: np.concatenate([self._delay[k], v], axis=1) for k, v in out.items()}
            out = {k: v[:, :M] for k, v in joined.items()}
            self._delay = {k: v[:, M:].copy() for k, v in joined.items()}
        truth = KinectTruth(
            slot=self._target_slot.repeat(M, 1),
            joints=truth_joints,
            hand_quat=truth_hand,
        )
        return KinectFrames(t=t, truth=truth, **out)
