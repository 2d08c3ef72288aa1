"""Configuration of the environment: one frozen dataclass per concern, validated on construction.

Pass any of them to ``gym.make`` as keyword arguments
(``sensors=SensorConfig(imu="consumer_mems")``, ``estimators=EstimatorConfig(locomotion="smooth")``,
``room=RoomConfig(...)``, ``reward=...``, ``config=EnvConfig(...)``) or use the shortcuts
``sensor_preset="consumer_mems"`` and ``locomotion="smooth"``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from estimators.hand import HandParams
from estimators.head_pose.visual_inertial import VioConfig
from estimators.validation import (
    check_bool,
    check_choice,
    check_condition,
    check_in_range,
    check_instance,
    check_value,
)
from vrloco_env.sensors.camera import CameraSpec, camera_spec
from vrloco_env.sensors.imu import EarthField, ImuSpec, MagneticDisturbance, get_imu_spec
from vrloco_env.sensors.kinect import KinectSpec
from vrloco_env.user import MotionParams, Population, get_population
from vrloco_env.user.play_area import PlayArea

__all__ = [
    "DEFAULT_IMU",
    "STAGE_FIELDS",
    "EnvConfig",
    "EstimatorConfig",
    "RewardConfig",
    "SensorConfig",
]

#: Where the virtual head pose comes from (:attr:`EnvConfig.pose_source`).
POSE_SOURCES = ("walk_in_place", "visual_inertial")


#: The IMU preset of a :class:`SensorConfig` that names none, without a technique: Zhang 2021's.
DEFAULT_IMU = "ig500n"


@dataclass(frozen=True)
class SensorConfig:
    """The head IMU and the Kinect v2.

    Attributes:
        imu: IMU preset name (``"ig500n"``, Zhang 2021's SBG IG-500N; ``"consumer_mems"``) or an
            :class:`~vrloco_env.sensors.imu.ImuSpec`. None (the default): the technique's preset,
            ``"ig500n"`` without a technique. An IMU given here is never replaced: one that
            contradicts the technique's preset is an error.
        imu_rate_hz: IMU sample rate (Hz), a multiple of the control rate, up to 1000.
        earth_field: the local geomagnetic field (intensity, inclination, declination).
        magnetic_disturbances: dipoles (metal, magnets) in the *physical* room, in the tracked
            space's frame where the user stands at the origin.
        kinect: Kinect v2 specification; the default stands 2.5 m in front of the user.
        head_camera: the helmet camera of the helmet-tracking paper, used with
            ``pose_source="visual_inertial"``
            (:mod:`vrloco_env.sensors.camera`; ``camera_spec("low_light", rate_hz=30)``
            etc.). The env's default runs it at 30 Hz, triggered by the IMU clock (the
            helmet-tracking paper's 120 Hz beside a 1 kHz IMU is the experiment's setting, ``vrloco
            experiment vio``).
        headset_position_noise_m: the tracked headset position's noise (m, 1-sigma per axis and
            sample), read by a step stage that uses the position (``uses_position``, the
            ``lee2018`` steps). Default 0.0005 m: lighthouse tracking is precise to well under a
            millimetre when still (Niehorster, Li & Lappe, "The accuracy and precision of
            position and orientation tracking in the HTC Vive virtual reality system for
            scientific research", i-Perception 8(3), 2017).
    """

    imu: str | ImuSpec | None = None
    imu_rate_hz: float = 100.0
    earth_field: EarthField = field(default_factory=EarthField)
    magnetic_disturbances: tuple[MagneticDisturbance, ...] = ()
    kinect: KinectSpec = field(default_factory=KinectSpec)
    head_camera: CameraSpec = field(default_factory=lambda: camera_spec("ideal", rate_hz=30.0))
    headset_position_noise_m: float = 0.0005

    def __post_init__(self) -> None:
        check_in_range(self, "headset_position_noise_m", 0.0, 0.1, "m")
        if self.imu is not None:
            check_instance(self, "imu", (str, ImuSpec))
            get_imu_spec(self.imu)  # raises with the valid names
        check_in_range(self, "imu_rate_hz", 10.0, 1000.0, "Hz")
        check_instance(self, "earth_field", EarthField)
        d = self.magnetic_disturbances
        ok = isinstance(d, tuple) and all(isinstance(x, MagneticDisturbance) for x in d)
        check_condition(self, "magnetic_disturbances", ok, "a tuple of MagneticDisturbance")
        check_instance(self, "kinect", KinectSpec)
        check_instance(self, "head_camera", CameraSpec)
        imu_hz = float(self.imu_rate_hz)
        triggered = f"<= imu_rate_hz ({imu_hz:g} Hz); frames are triggered by IMU samples"
        check_value(
            "SensorConfig.head_camera.rate_hz",
            self.head_camera.rate_hz,
            0.0,
            imu_hz,
            lo_open=True,
            allowed=triggered,
        )

    @property
    def imu_spec(self) -> ImuSpec:
        return get_imu_spec(DEFAULT_IMU if self.imu is None else self.imu)

    @property
    def preset_name(self) -> str:
        """The IMU preset's name (``"ig500n"`` where :attr:`imu` is None)."""
        if self.imu is None:
            return DEFAULT_IMU
        return self.imu if isinstance(self.imu, str) else self.imu.name


#: The stages of :class:`EstimatorConfig`, each with the registry it is resolved in.
STAGE_FIELDS = ("attitude", "steps", "hand", "steering", "locomotion")


@dataclass(frozen=True)
class EstimatorConfig:
    """The estimation stages that turn sensor samples into the virtual body's motion.

    Each stage field takes a registered name (:mod:`estimators.stages`: ``vrloco techniques``
    lists them), a ``"package.module:attr"`` string naming your own class or factory, or an
    object with a ``build(...)`` method such as a parameter dataclass
    (``attitude=AttitudeParams(acc_noise=0.03)``, ``steps=GaitParams(gamma=0.8)``).

    Attributes:
        attitude: head attitude from the IMU (default ``"ekf"``, Zhang 2021's error-state EKF;
            ``"ekf_paper_literal"``, ``"ekf_f_zero"``, ``"vqf"``, ``"madgwick"``, ``"mahony"``,
            ``"gyro_only"``).
        steps: step detector (default ``"zhang2021"``, eqs 15-16; ``"threshold"``,
            ``"nod_robust"``).
        hand: filter of the Kinect's wrist angles (default ``"yao2023"``, Kalman + median;
            ``"one_euro"``, ``"raw"``).
        steering: which yaw turns the walking direction (default ``"head"``; ``"torso"``, the
            Kinect's shoulder line).
        locomotion: ``"eq17"`` (Zhang 2021: jump one step length at each detected step),
            ``"smooth"`` (the smooth-locomotion paper: a planar filter moving the body continuously)
            or ``"cadence_speed"`` (speed proportional to the estimated cadence).
        step_length: SL of eq (17) (m).
        hand_pipeline: Yao 2023's Kinect processing (target selection, joint smoothing, eq 1/2,
            and the Kalman + median filter that the ``"yao2023"`` hand stage reports).
        visual_inertial: the helmet-tracking paper's visual-inertial filter
            (``pose_source="visual_inertial"``);
            Sage-Husa adaptive R by default, since the camera's noise changes with the light.
    """

    attitude: Any = "ekf"
    steps: Any = "zhang2021"
    hand: Any = "yao2023"
    steering: Any = "head"
    locomotion: Any = "eq17"
    step_length: float = 0.7
    hand_pipeline: HandParams = field(default_factory=HandParams)
    visual_inertial: VioConfig = field(default_factory=lambda: VioConfig(adaptive="sage_husa"))

    def __post_init__(self) -> None:
        from estimators import stages

        for name in STAGE_FIELDS:
            registry = getattr(stages, name.upper())
            value = registry.canonical(getattr(self, name))  # a deprecated name: today's
            object.__setattr__(self, name, value)
            if isinstance(value, HandParams):
                raise ValueError(
                    f"EstimatorConfig.{name}: HandParams configure the Kinect pipeline; pass "
                    "them as hand_pipeline=HandParams(...)"
                )
            try:
                registry.check(value)
            except ValueError as err:
                raise ValueError(f"EstimatorConfig.{err}") from None
        check_in_range(self, "step_length", 0.2, 1.5, "m")
        check_instance(self, "hand_pipeline", HandParams)
        check_instance(self, "visual_inertial", VioConfig)

    def label(self, stage: str) -> str:
        """The short name of a stage's choice (``"ekf"``, ``"custom:my.module:Filter"``)."""
        from estimators import stages

        return getattr(stages, stage.upper()).label(getattr(self, stage))


@dataclass(frozen=True)
class RewardConfig:
    """Reward terms (per control step). A Safety-Gymnasium style ``cost`` is reported apart.

    Attributes:
        progress: reward per metre of progress toward the goal (shortest-path distance).
        success: bonus on success.
        collision: penalty per blocked step (a step into an obstacle or wall).
        effort: penalty weight of the mean squared action.
        time: penalty per control step (encourages finishing).
        success_without_collision: pay the success bonus only for an episode without a
            collision (the objective of a user who must reach goals without colliding; the
            task's own success is unchanged).
        hand_progress: reward per radian by which the estimated hand comes closer to the
            target orientation of a task with one (Interact, Reach; the rotation angle of
            :func:`~vrloco_env.tasks.interact.hand_error`), as ``progress`` pays for metres:
            a difference of potentials, shaping that leaves the best policy unchanged (Ng,
            Harada & Russell, ICML 1999). Steps without a hand estimate pay nothing. 0 for
            every task without a hand target.
    """

    progress: float = 1.0
    success: float = 10.0
    collision: float = 1.0
    effort: float = 0.01
    time: float = 0.01
    success_without_collision: bool = False
    hand_progress: float = 0.0

    def __post_init__(self) -> None:
        for name in ("progress", "success", "collision", "effort", "time", "hand_progress"):
            check_in_range(self, name, 0.0, 1e3)
        check_bool(self, "success_without_collision")


@dataclass(frozen=True)
class EnvConfig:
    """Rates, horizon, what the user sees, and termination.

    Attributes:
        motion: the simulated body (rates, cadence range, turn and hand limits).
        max_episode_steps: control steps before truncation (600 = 60 s at 10 Hz); None: the
            env sets no horizon of its own and a wrapper ends the episode (what the ids'
            entry point builds under ``gym.make``, whose ``TimeLimit`` holds the horizon).
        terminate_on_collision: end the episode at the first blocked step.
        ray_count: rays cast from the virtual head, spread over ``ray_fov_deg``.
        ray_fov_deg: angular spread of the rays, centred on the virtual heading (deg).
        ray_range_m: rays report at most this range (m).
        view_vertical_fov_deg: the headset's vertical field of view (deg): what the rays see
            follows the head's estimated pitch, and pitched down past half of it the user sees
            the floor only up to where the view's upper edge meets it, not the obstacles beyond
            (:meth:`vrloco_env.core.LocoCore._rays`). A choice near the vertical field of
            consumer headsets, about 90-100 deg (their makers state the diagonal or the
            horizontal field: 101 deg for the Samsung Gear VR of Tregillus 2017, 110 deg for the
            HTC Vive).
        pose_source: where the virtual head pose comes from.
            ``"walk_in_place"`` (default, Zhang 2021): the user steps in place; the virtual body
            moves a step length along the IMU's estimated yaw per detected step (eq 17 or the
            smooth filter). ``"visual_inertial"`` (the helmet-tracking paper): the user really walks
            through a tracked space the size of the room, with markers on its walls where the room's
            landmarks are; the virtual head follows the visual-inertial estimate (head camera +
            PnP + adaptive Kalman filter) one to one, and its yaw gives the heading. A step into
            a virtual obstacle is still blocked (the avatar stays, counted as a collision) while
            the real user walks on, so the two drift apart by the blocked motion, as in a VR
            engine's collision response. The Kinect stands in front of the start marker, facing
            it (``KinectSpec`` in the start marker's frame): the hand is tracked while the user
            is in its view.
        population: the simulated humans' head behaviour (:mod:`vrloco_env.user.population`:
            ``"typical"``, ``"gaze_scanners"``, ``"nodders"``, ... or a ``Population``): gaze
            that turns the head on the torso, nods, looking down at the hand, the step impact,
            drawn per user and episode (:class:`vrloco_env.user.GazeBehaviour`). None (default)
            or ``"idealised"``: the head stays straight on the torso, as the action alone moves
            it. A population whose head turns on the torso adds the observation field
            ``head_on_torso`` (what proprioception tells the user).
        play_area: the walking-in-place user's physical tracked space (default 2 x 2 m centred
            on the start spot) and the drift model (:mod:`vrloco_env.user.play_area`); info
            reports the user's position in it. Unused with the visual-inertial pose source.
    """

    motion: MotionParams = field(default_factory=MotionParams)
    max_episode_steps: int | None = 600
    terminate_on_collision: bool = False
    ray_count: int = 15
    ray_fov_deg: float = 180.0
    ray_range_m: float = 5.0
    view_vertical_fov_deg: float = 90.0
    pose_source: str = "walk_in_place"
    population: str | Population | None = None
    play_area: PlayArea = field(default_factory=PlayArea)

    def __post_init__(self) -> None:
        check_instance(self, "motion", MotionParams)
        check_instance(self, "play_area", PlayArea)
        if self.population is not None:
            get_population(self.population, "EnvConfig.population")
        if self.max_episode_steps is not None:
            check_in_range(self, "max_episode_steps", 1, 100_000, integer=True)
        check_bool(self, "terminate_on_collision")
        check_in_range(self, "ray_count", 1, 360, integer=True)
        check_in_range(self, "ray_fov_deg", 0.0, 360.0, "deg", lo_open=True)
        check_in_range(self, "ray_range_m", 0.5, 50.0, "m")
        check_in_range(self, "view_vertical_fov_deg", 10.0, 180.0, "deg")
        check_choice(self, "pose_source", POSE_SOURCES)
