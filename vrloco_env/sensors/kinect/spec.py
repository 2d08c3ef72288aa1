"""The Kinect v2 sensor's specification (:class:`KinectSpec`) and the joint tables its model uses
(:data:`TORSO_JOINTS`, :data:`LIMB_GROUPS`); the sources of every value are given per field."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.validation import check_in_range, check_numbers
from vrloco_env.sensors.kinect import _kernel as _k
from vrloco_env.user import NUM_JOINTS, Joint

__all__ = ["LIMB_GROUPS", "MAX_BODIES", "TORSO_JOINTS", "KinectSpec"]

#: Bodies the Kinect v2 tracks at once (Microsoft Kinect for Windows v2 specification: six).
MAX_BODIES = _k.MAX_BODIES

J = Joint

#: Joints that make up the torso silhouette used for occlusion (they never hide behind their own
#: torso).
TORSO_JOINTS = (
    J.SPINE_BASE,
    J.SPINE_MID,
    J.NECK,
    J.SPINE_SHOULDER,
    J.SHOULDER_LEFT,
    J.SHOULDER_RIGHT,
    J.HIP_LEFT,
    J.HIP_RIGHT,
)

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
    1.0,
    1.0,
    1.0,
    1.0,  # spine base, spine mid, neck, head
    1.0,
    1.5,
    2.0,
    2.5,  # shoulder, elbow, wrist, hand (left)
    1.0,
    1.5,
    2.0,
    2.5,  # shoulder, elbow, wrist, hand (right)
    1.0,
    1.5,
    2.0,
    2.5,  # hip, knee, ankle, foot (left)
    1.0,
    1.5,
    2.0,
    2.5,  # hip, knee, ankle, foot (right)
    1.0,  # spine shoulder
    4.0,
    4.0,
    4.0,
    4.0,  # hand tip left, thumb left, hand tip right, thumb right
)


# --------------------------------------------------------------------------------------------------
# Specification


@dataclass(frozen=True)
class KinectSpec:
    """Parameters of the simulated Kinect v2 (all validated on construction).

    Sources are given per field. "Engineering choice" marks a value we set for a plausible sensor
    where no measurement was at hand; every such value is a field, so a study can vary it.
    """

    #: Body frame rate, Hz. Kinect v2 skeleton stream: 30 frames/s (Microsoft Kinect for Windows v2
    #: specification; Yao 2023 section 2.2).
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
    #: Yao 2023 Tables 1-3, which give no spectrum: a static hand gives raw eq (1) variances of
    #: 0.5-14 deg^2 whose means over the 11 angles are "roll" 4.7 (about the forearm), "pitch" 3.5
    #: (about the thumb axis), "yaw" 6.5 deg^2 (about the back-of-hand normal);
    #: tests/test_vrloco_env/sensors/test_kinect.py
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
    #: the fit's white share spreads by about +-0.15 (tests/test_estimators/hand/test_hand.py checks
    #: the estimator on known noise). So the split is 80 % white about the forearm and 5 % about y
    #: and z: std sqrt(share x total).
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
    #: standing 2.5 m away and reaching toward the sensor (Yao 2023 does not state its distance).
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
    #: Torso facing, deg, beyond which the far-side limbs are inferred. A body's facing is the
    #: horizontal angle between its torso's forward direction (normal to the shoulder and hip
    #: lines) and its line of sight to the sensor, 0-180 deg (0: facing the sensor, 90: side-on).
    #: Beyond this angle the joints of the arm and leg on the side away from the sensor (elbow to
    #: hand tip and thumb, knee to foot) are reported inferred: the SDK's tracker is trained on
    #: people facing the sensor, and a turned body hides its far side behind itself. Evidence,
    #: thin and qualitative: a Kinect v2 tracks an arm best with the sensor 30-45 deg off the
    #: front on the side away from that arm (Cai, Liu & Ma 2021, "Placement recommendations for
    #: single Kinect-based motion capture system in unilateral dynamic motion analysis",
    #: Healthcare 9(8) 1076, seven orientations tested), so the far arm is still tracked at 45
    #: deg; a person standing sideways (90 deg) shows 72 % of the skeleton, with the hands out
    #: of proportion and a shoulder misplaced, against 100 % facing the sensor (Table 2 of
    #: "Multiple Kinect based system to monitor and analyze key performance indicators of
    #: physical training", Human-centric Computing and Information Sciences 10, 2020). The 60 deg
    #: between the two is an engineering choice.
    facing_inferred_deg: float = 60.0
    #: Torso facing, deg, beyond which the body is not detected (it counts as not visible: the
    #: tracked body is lost, and it is acquired again, with a new id, after ``acquire_frames``
    #: detectable frames once it turns back). Beyond side-on the sensor sees the back; the Kinect
    #: v2 tracker, trained on frontal poses, then fits a frontal skeleton to it with left and
    #: right swapped or loses the body (the Kinect SDK's guidance that users face the sensor, and
    #: the side-view failures above). No measurement gives the angle: 120 deg, 30 deg past
    #: side-on, is an engineering choice.
    facing_lost_deg: float = 120.0

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
        inf = math.inf
        check_in_range(self, "frame_rate_hz", 0.0, inf, "Hz", lo_open=True)
        check_numbers(self, "fov_deg", 0.0, 180.0, "deg", length=2, lo_open=True, hi_open=True)
        check_numbers(
            self, "depth_range_m", 0.0, inf, "m", length=2, ordered=True, strict=True, lo_open=True
        )
        check_numbers(self, "camera_position_m", -inf, inf, "m", length=3)
        check_in_range(self, "camera_yaw_rad", -inf, inf, "rad")
        check_in_range(self, "camera_tilt_deg", -45.0, 45.0, "deg", lo_open=True, hi_open=True)
        for name in (
            "joint_noise_a_mm",
            "joint_noise_b_mm_per_m2",
            "joint_bias_std_m",
            "burst_position_std_m",
            "burst_rotation_std_deg",
            "torso_margin_m",
            "occlusion_depth_m",
            "bystander_lateral_m",
        ):
            check_in_range(self, name, 0.0, inf)
        for name in ("joint_noise_white_fraction", "burst_prob", "random_inferred_prob"):
            check_in_range(self, name, 0.0, 1.0)
        for name in (
            "joint_noise_tau_s",
            "hand_rot_tau_s",
            "noise_ref_depth_m",
            "bystander_dwell_s",
        ):
            check_in_range(self, name, 0.0, inf, lo_open=True)
        check_numbers(self, "joint_noise_scale", 0.0, inf, length=NUM_JOINTS, lo_open=True)
        for name in ("hand_rot_white_std_deg", "hand_rot_ar_std_deg"):
            check_numbers(self, name, 0.0, inf, "deg", length=3)
        check_in_range(self, "inferred_noise_factor", 1.0, inf)
        check_numbers(self, "burst_frames", 1.0, inf, "frames", length=2, ordered=True, whole=True)
        check_in_range(self, "latency_frames", 0, inf, "frames", integer=True)
        check_in_range(self, "random_inferred_frames", 1.0, inf, "frames")
        check_in_range(self, "min_visible_fraction", 0.0, 1.0, lo_open=True)
        check_in_range(self, "acquire_frames", 1, inf, "frames", integer=True)
        check_in_range(self, "facing_inferred_deg", 0.0, 180.0, "deg")
        check_in_range(
            self,
            "facing_lost_deg",
            self.facing_inferred_deg,
            180.0,
            lo_open=True,
            allowed=f"in (facing_inferred_deg = {self.facing_inferred_deg:g}, 180] deg",
        )
        check_in_range(self, "n_bystanders", 0, MAX_BODIES - 1, integer=True)
        for name, unit in (
            ("bystander_distance_m", "m"),
            ("bystander_speed_mps", "m/s"),
            ("bystander_height_m", "m"),
        ):
            check_numbers(self, name, 0.0, inf, unit, length=2, ordered=True, lo_open=True)

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
