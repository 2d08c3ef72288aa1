"""Rates, limits and body measurements of the simulated user (:class:`MotionParams`): the
settings of :class:`~vrloco_env.user.motion.UserMotion`, validated on construction."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators.validation import (
    check_bool,
    check_condition,
    check_in_range,
    check_numbers,
)

__all__ = ["MotionParams"]


@dataclass(frozen=True)
class MotionParams:
    """Rates, limits and body measurements of the simulated user.

    Every field is validated on construction; units in the names or docs.
    """

    imu_rate_hz: float = 100.0
    """Head IMU sample rate (Hz), 10-1000. Zhang 2021's IG-500N ran at 100 Hz."""
    kinect_rate_hz: float = 30.0
    """Kinect v2 skeleton frame rate (Hz); the sensor delivers 30 frames/s (Yao 2023)."""
    control_rate_hz: float = 10.0
    """Rate at which the intent changes (Hz): one env step."""
    cadence_range_hz: tuple[float, float] = (1.2, 2.2)
    """Allowed stepping cadence while walking (steps/s); 0 stands still."""
    max_turn_rate: float = np.deg2rad(120.0)
    """Largest body yaw rate (rad/s): a brisk in-place turn."""
    turn_lag_s: float = 0.1
    """Time constant (s) of the yaw rate following its command (head inertia)."""
    max_hand_rate: float = np.deg2rad(180.0)
    """Largest hand angular rate about each axis (rad/s)."""
    hand_limits_deg: tuple[float, float, float] = (90.0, 80.0, 90.0)
    """Hand yaw, pitch, roll limits (deg, symmetric) relative to the torso heading."""
    peak_accel_g: tuple[float, float] = (0.12, 0.45)
    """Peak vertical head acceleration (g) at the lowest and highest cadence (interpolated)."""
    sway_m: float = 0.02
    """Lateral body sway amplitude (m), one sway per stride."""
    sway_roll_deg: float = 1.5
    """Head roll (deg) accompanying the lateral sway."""
    gesture_lag_s: float = 0.4
    """Time constant (s) of the critically damped response of gesture amplitudes and lean."""
    head_turn_lag_s: float = 0.1
    """Time constant (s) of the critically damped response of the head-on-torso yaw to its target
    (:attr:`Intent.head_yaw`), in [0.02, 1]. A linear response has a peak speed proportional to
    the amplitude, the "main sequence" of head movements (Zangemeister, Jones & Stark, Exp.
    Neurol. 1981; Freedman, Biol. Cybern. 2008): with 0.1 s a 40 deg turn peaks at
    40 / (e * 0.1) ~ 150 deg/s and settles (95 %) in ~0.47 s, inside the 0.3-0.6 s and
    100-300 deg/s those studies report for 20-60 deg head movements."""
    neck_height_m: float = 1.55
    """Height (m) of the head's pivot (upper neck) when standing."""
    imu_offset_m: tuple[float, float, float] = (0.09, 0.0, 0.12)
    """Forehead IMU position (m) in the head frame relative to the neck pivot."""
    style_spread: float = 0.1
    """Relative spread (1-sigma) of each user's step-impact and sway style, drawn at reset."""
    overground: bool = False
    """False (default): the user steps in place, as in Zhang 2021 — the virtual body moves by the
    estimated steps. True: the user really walks through the tracked space (the helmet-tracking
    paper's helmet users; the env's ``pose_source="visual_inertial"``): the body advances along its
    heading at ``stride_m`` per step, with the speed following the cadence with lag
    ``speed_lag_s``."""
    stride_m: float = 0.65
    """Distance (m) covered per step when walking overground, in [0.2, 1.2]."""
    speed_lag_s: float = 0.4
    """Time constant (s) of the overground walking speed following cadence * stride_m."""

    def __post_init__(self) -> None:
        check_in_range(self, "imu_rate_hz", 10.0, 1000.0, "Hz")
        check_in_range(self, "kinect_rate_hz", 1.0, 120.0, "Hz")
        check_in_range(
            self,
            "control_rate_hz",
            0.5,
            self.imu_rate_hz,
            allowed=f"in [0.5, imu_rate_hz={float(self.imu_rate_hz):g}] Hz",
        )
        ratio = self.imu_rate_hz / self.control_rate_hz
        whole_samples = abs(ratio - round(ratio)) < 1e-9
        divisor = "a divisor of imu_rate_hz (whole IMU samples per control step)"
        check_condition(self, "control_rate_hz", whole_samples, divisor)
        check_numbers(self, "cadence_range_hz", 0.3, 4.0, "Hz", length=2, ordered=True, strict=True)
        check_in_range(self, "max_turn_rate", 0.0, 2 * np.pi, "rad/s", lo_open=True)
        check_in_range(self, "turn_lag_s", 0.0, 2.0, "s", lo_open=True)
        check_in_range(self, "max_hand_rate", 0.0, 4 * np.pi, "rad/s", lo_open=True)
        check_numbers(self, "hand_limits_deg", 0.0, 180.0, "deg", length=3, lo_open=True)
        check_numbers(self, "peak_accel_g", 0.0, 2.0, "g", length=2, ordered=True)
        check_in_range(self, "sway_m", 0.0, 0.1, "m")
        check_in_range(self, "sway_roll_deg", 0.0, 10.0, "deg")
        check_in_range(self, "gesture_lag_s", 0.0, 5.0, "s", lo_open=True)
        check_in_range(self, "head_turn_lag_s", 0.02, 1.0, "s")
        check_in_range(self, "neck_height_m", 0.8, 2.2, "m")
        check_in_range(self, "style_spread", 0.0, 0.5)
        check_bool(self, "overground")
        check_in_range(self, "stride_m", 0.2, 1.2, "m")
        check_in_range(self, "speed_lag_s", 0.01, 5.0, "s")

    @property
    def samples_per_step(self) -> int:
        """IMU samples per control step."""
        return round(self.imu_rate_hz / self.control_rate_hz)
