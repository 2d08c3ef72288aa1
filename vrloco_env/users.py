"""B simulated VR users, from intent to the estimates a headset would have: the user side of a step.

One control step, as data (SPEC section 1)::

    intent -> UserMotion        true head pose at the IMU rate, true heel strikes, true skeleton
           -> HeadImu, KinectV2 IMU samples, Kinect frames (bodies, ids, tracking states)
           -> AttitudeEKF       estimated head attitude (Zhang 2021)
           -> StepDetector      still/walk and step events (Zhang 2021)
           -> HandPipeline      hand orientation (Yao 2023)
           -> locomotion        eq (17) or the smooth filter (the smooth-locomotion paper): the
           virtual displacement

With ``pose_source="visual_inertial"`` (the helmet-tracking paper) the user really walks through the
tracked space and a head camera + PnP + visual-inertial filter (:mod:`vrloco_env.head_tracking`)
replace the attitude EKF and the locomotion model: the virtual head follows the estimated pose one
to one.

Every estimator (the five stages, the hand front end, the cadence estimate and the head tracker)
is batched over the B users and given to :class:`SimulatedUsers` ready-built, plug-ins already
behind their checked proxy (:func:`vrloco_env.pipeline.build_stages`); this module only composes
them (no estimator logic lives here). The virtual heading is the estimated yaw plus a per-user
offset fixed when the episode starts ("recentring", as a headset aligns the virtual world to where
the user faces), so estimation errors — drift, magnetic disturbances — turn into heading errors in
the virtual world.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import rotations as rot
from estimators.batching import TakesUsers, stream_rows
from estimators.hand import HandFrame
from estimators.kernels import param_record
from estimators.locomotion.steering import torso_yaw
from vrloco_env._core_numba import quat_to_ypr_rows, step_summary_kernel
from vrloco_env._hand_frame_numba import hand_relative_to_torso
from vrloco_env.batch_rng import BatchRng
from vrloco_env.config import SensorConfig
from vrloco_env.pipeline import Stages
from vrloco_env.sensors.camera import layout_landmarks
from vrloco_env.sensors.imu import HeadImu, ImuSamples
from vrloco_env.sensors.kinect import (
    HAND_FROM_SDK_WRIST,
    KinectFrames,
    KinectV2,
    camera_quat,
    camera_to_world,
)
from vrloco_env.user import Intent, Joint, MotionChunk, MotionParams, UserMotion
from vrloco_env.user.play_area import PlayArea
from vrloco_env.world import Layout

__all__ = ["SimulatedUsers", "UserStep"]


@dataclass
class UserStep:
    """What one control step produced for B users (truth and estimates).

    Attributes:
        motion: the true motion (head pose at the IMU rate, heel strikes, skeleton).
        imu: the IMU samples of the step.
        kinect: the Kinect frames of the step.
        ypr_est: estimated head [yaw, pitch, roll] at the step's end (rad; yaw physical).
        ypr_true: true head [yaw, pitch, roll] at the step's end (rad).
        virtual_yaw: estimated yaw + the episode's heading offset (rad, in the virtual room).
        true_virtual_yaw: true yaw + the true offset: the heading perfect sensing would give.
        walk_yaw: the direction the locomotion moves the body in the virtual room (rad): the
            steering stage's yaw (the estimated head's, or the torso's), the virtual heading with
            the visual-inertial pose source.
        true_body_yaw: the true torso yaw in the virtual room (rad): the direction the body
            faces, ``true_virtual_yaw`` less the head's yaw on the torso.
        steps: steps detected (confirmed) in this control step, (B,).
        step_peak_time: estimated heel-strike times (s, the detector's clock) of those steps,
            NaN-padded, (B, 2N).
        true_steps: true heel strikes in this control step, (B,).
        walking: the detector's still/walk state at the step's end, (B,) bool.
        cadence: estimated cadence (steps/s), (B,).
        displacement: the locomotion model's displacement in the virtual room this step (m), (B, 2)
            (with the visual-inertial pose source: the estimated head's horizontal displacement).
        true_displacement: what perfect sensing would have moved the virtual body (m), (B, 2).
        hand: the hand pipeline's output for the step's last Kinect frame.
        hand_est: estimated hand [yaw, pitch, roll] relative to the torso (rad), NaN when no
            estimate; (B, 3).
        hand_true: true hand [yaw, pitch, roll] relative to the torso (rad), (B, 3).
    """

    motion: MotionChunk
    imu: ImuSamples
    kinect: KinectFrames
    ypr_est: NDArray[np.float64]
    ypr_true: NDArray[np.float64]
    virtual_yaw: NDArray[np.float64]
    true_virtual_yaw: NDArray[np.float64]
    walk_yaw: NDArray[np.float64]
    true_body_yaw: NDArray[np.float64]
    steps: NDArray[np.float64]
    step_peak_time: NDArray[np.float64]
    true_steps: NDArray[np.float64]
    walking: NDArray[np.bool_]
    cadence: NDArray[np.float64]
    displacement: NDArray[np.float64]
    true_displacement: NDArray[np.float64]
    hand: HandFrame
    hand_est: NDArray[np.float64]
    hand_true: NDArray[np.float64]


def _derived_motion(motion: MotionParams, sensors: SensorConfig, overground: bool) -> MotionParams:
    """``motion`` with its sensor rates and ``overground`` taken from the sensors and the pose
    source; a field set to anything but its default that disagrees with them is an error."""
    derived = {
        "imu_rate_hz": ("SensorConfig.imu_rate_hz", sensors.imu_rate_hz),
        "kinect_rate_hz": ("SensorConfig.kinect.frame_rate_hz", sensors.kinect.frame_rate_hz),
        "overground": ("EnvConfig.pose_source", overground),
    }
    defaults = MotionParams()
    for name, (source, value) in derived.items():
        mine = getattr(motion, name)
        if mine != value and mine != getattr(defaults, name):
            raise ValueError(
                f"MotionParams.{name}={mine!r} contradicts {source} (which gives {value!r}); "
                f"leave MotionParams.{name} at its default, it follows from {source}"
            )
    fs = sensors.imu_rate_hz
    ratio = fs / motion.control_rate_hz
    if abs(ratio - round(ratio)) > 1e-9:
        raise ValueError(
            f"SensorConfig.imu_rate_hz={fs} must be a multiple of the control rate "
            f"{motion.control_rate_hz} Hz"
        )
    return replace(motion, **{k: v for k, (_, v) in derived.items()})


class SimulatedUsers(TakesUsers):
    """B simulated users with their sensors and estimators, advanced one control step at a time.

    Args:
        batch_size: B.
        rng: one random stream per user (:class:`~vrloco_env.batch_rng.BatchRng`).
        motion: the body model's parameters. Its sensor rates and ``overground`` follow from
            ``sensors`` and the stages' pose source; set to anything but their defaults, they
            must agree.
        sensors: IMU and Kinect configuration.
        stages: every estimator, built for these users and a pose source
            (:func:`vrloco_env.pipeline.build_stages`), whose pose source the users follow.
        play_area: the physical tracked space and drift model
            (:mod:`vrloco_env.user.play_area`; default: a 2 x 2 m area). Walking in place, a
            user whose drift rate is set (:meth:`set_drift`) drifts while stepping; each
            control step shifts the standing spots of all users at once.
    """

    # each user's offsets and start; the random streams (``rng``) belong to the caller
    per_user_fields = (
        "yaw_offset",
        "true_yaw_offset",
        "_last_loco",
        "_start_yaw",
        "_recentre",
        "_track_start",
        "_track_origin",
        "_tracked_xy",
        "_last_true",
        "last_tracked",
        "_start_xy3",
        "_drift",
    )
    # the motion, the sensors and every stage (each once, also where two names share one)
    per_user_parts = (
        "motion",
        "imu",
        "kinect",
        "hand_pipeline",
        "cadence",
        "attitude",
        "gait",
        "hand_filter",
        "steering",
        "locomotion",
        "tracker",
    )
    batch_size_field = "batch_size"

    def __init__(
        self,
        batch_size: int,
        rng: BatchRng,
        motion: MotionParams,
        sensors: SensorConfig,
        stages: Stages,
        play_area: PlayArea | None = None,
    ) -> None:
        self.pose_source = stages.pose_source
        self.overground = stages.pose_source == "visual_inertial"
        if rng.batch_size != batch_size:
            raise ValueError(f"rng has {rng.batch_size} streams, expected {batch_size}")
        self.batch_size = b = batch_size
        self.rng = rng
        self.sensors = sensors
        self.imu_rate_hz = fs = sensors.imu_rate_hz
        # motion
        self.motion_params = _derived_motion(motion, sensors, self.overground)
        self.dt = 1.0 / self.motion_params.control_rate_hz
        self.motion = UserMotion(self.motion_params, rng)
        self.play_area = PlayArea() if play_area is None else play_area
        # -> sensors
        self.imu = HeadImu(
            sensors.imu_spec,
            rng,
            rate_hz=fs,
            field=sensors.earth_field,
            disturbances=sensors.magnetic_disturbances,
        )
        self.kinect = KinectV2(sensors.kinect, rng)
        self._camera_q = camera_quat(sensors.kinect)
        self._sdk_to_hand = rot.quat_conjugate(HAND_FROM_SDK_WRIST)
        # -> estimators (the tracker, with the visual-inertial pose source, in place of the
        # attitude stage and the locomotion)
        self.stages = stages
        self.attitude = stages.attitude
        self.tracker = stages.tracker
        self.gait = stages.steps
        self.cadence = stages.cadence
        self.hand_pipeline = stages.hand_pipeline
        self.hand_filter = stages.hand
        self.steering = stages.steering
        self._steer_with_torso = getattr(stages.steering, "uses_torso", True)
        self._steer_with_hand = bool(getattr(stages.steering, "uses_hand", False))
        self._loco_pitch = bool(getattr(stages.locomotion, "uses_pitch", False))
        self._steps_position = bool(getattr(stages.steps, "uses_position", False))
        # -> locomotion
        self.locomotion = stages.locomotion
        self._summary_prm = param_record(
            step_length=stages.step_length, in_place=float(not self.overground)
        )
        # each user's episode state
        self.yaw_offset = np.zeros(b)
        self.true_yaw_offset = np.zeros(b)
        self._last_loco = np.zeros((b, 2))
        self._start_yaw = np.zeros(b)
        self._recentre = np.ones(b, bool)
        self._track_start = np.zeros(b, bool)  # users whose tracker starts at the next sample
        self._track_origin = np.zeros((b, 2))  # tracked head xy minus virtual body xy at start
        self._tracked_xy = np.zeros((b, 2))  # estimated virtual position at the step's end
        self._last_true = np.zeros((b, 2))  # true head xy at the last step's end
        self.last_tracked = None  # the last step's TrackedChunk (visual-inertial source only)
        self._start_xy3 = np.zeros((b, 3))  # start marker in the room (m), z = 0
        self._drift = np.zeros((b, 2))  # drift rates (m/s): [forward, left] of the torso
        if self.overground:
            steps_per_frame = sensors.head_camera.rate_hz / motion.control_rate_hz
            if abs(steps_per_frame - round(steps_per_frame)) > 1e-9:
                raise ValueError(
                    f"SensorConfig.head_camera.rate_hz={sensors.head_camera.rate_hz} must be a "
                    f"multiple of the control rate {motion.control_rate_hz} Hz (the same frame "
                    "times in every step, so that an episode does not depend on when it starts)"
                )

    def set_room(self, user: int, layout: Layout) -> None:
        """The room user ``user`` is in: with the visual-inertial pose source its walls carry the
        head camera's markers (the room's landmarks, in the room's local frame)."""
        if self.tracker is not None:
            points, normals = layout_landmarks(layout.with_origin((0.0, 0.0)))
            self.tracker.set_landmarks(user, points, normals)

    # ------------------------------------------------------------------------------ reset
    def reset(
        self,
        users: ArrayLike | None,
        start_yaw: ArrayLike,
        start_xy: ArrayLike,
        physical_yaw: ArrayLike = 0.0,
    ) -> None:
        """Start new episodes for ``users`` (indices or a (B,) mask; None: all).

        The reset users stand still facing ``physical_yaw`` (rad) in the tracked space; their
        estimators start afresh. At their first IMU sample the virtual heading offset is set so
        that the estimated yaw maps onto ``start_yaw`` (rad) — the headset's recentring — and the
        locomotion model starts at ``start_xy`` (m) in the virtual room. Callers reseed the users'
        streams (``rng.reseed``) before this for a new random episode. The other users are not
        touched, so a vector env's sub-env behaves as a single env would.
        """
        b = self.batch_size
        rows = stream_rows(users, b)
        mask = np.zeros(b, bool)
        mask[rows] = True
        every = rows.size == b
        u = rows.size
        start_yaw = np.broadcast_to(np.asarray(start_yaw, np.float64), (u,))
        physical_yaw = np.broadcast_to(np.asarray(physical_yaw, np.float64), (u,))
        if self.overground:  # the tracked space is the room: start at the room's start pose
            physical_yaw = start_yaw
            self.motion.reset(
                yaw=physical_yaw,
                base=np.broadcast_to(np.asarray(start_xy, np.float64), (u, 2)),
                users=None if every else rows,
            )
            self._track_start[rows] = True
            self._start_xy3[rows, :2] = np.broadcast_to(np.asarray(start_xy, np.float64), (u, 2))
        else:
            self.motion.reset(yaw=physical_yaw, users=None if every else rows)
        self.imu.reset() if every else self.imu.reset(users=rows)
        self.kinect.reset() if every else self.kinect.reset(users=rows)
        which = None if every else rows
        self.attitude.reset(which)
        self.gait.reset(which)
        self.hand_pipeline.reset(mask)
        self.hand_filter.reset(which)
        self.steering.reset(which)
        xy = np.broadcast_to(np.asarray(start_xy, np.float64), (u, 2))
        self._last_loco[rows] = xy
        self._start_yaw[rows] = start_yaw
        self.locomotion.reset(mask, position=self._last_loco.copy(), heading=self._start_yaw.copy())
        # Recentring: the IMU's yaw is aligned to the start heading at the first sample; the
        # tracker's yaw is already the room's.
        self._recentre[rows] = not self.overground
        self.yaw_offset[rows] = 0.0
        self.true_yaw_offset[rows] = rot.wrap_angle(start_yaw - physical_yaw)
        self.cadence.reset(rows)
        self._drift[rows] = 0.0

    def set_drift(self, users: ArrayLike, forward: ArrayLike, lateral: ArrayLike) -> None:
        """The drift rates (m/s) of ``users`` while stepping in place: ``forward`` along the
        torso's facing, ``lateral`` to its left (broadcast to the users). Reset sets them to 0."""
        rows = stream_rows(users, self.batch_size)
        self._drift[rows, 0] = np.broadcast_to(np.asarray(forward, np.float64), (rows.size,))
        self._drift[rows, 1] = np.broadcast_to(np.asarray(lateral, np.float64), (rows.size,))

    def play_area_position(self) -> NDArray[np.float64]:
        """Each user's physical standing spot in the play area (m), (B, 2): relative to the
        start spot (the tracked space's origin walking in place; the start marker overground)."""
        return self.motion.base - self._start_xy3[:, :2]

    def _apply_drift(self, chunk: MotionChunk) -> None:
        """Shift the standing spots by this step's drift: the drift rate times the time spent
        mid-step, along the torso's facing at the step's end."""
        stepping_s = chunk.walking.mean(axis=1) * self.dt
        yaw = chunk.body_yaw[:, -1]
        c, s = np.cos(yaw), np.sin(yaw)
        f, left = self._drift[:, 0] * stepping_s, self._drift[:, 1] * stepping_s
        self.motion.shift_base(np.stack([c * f - s * left, s * f + c * left], axis=-1))

    # ------------------------------------------------------------------------------ step
    def step(self, intent: Intent, validated: bool = False) -> UserStep:
        """Advance every user by one control step under ``intent``.

        ``validated=True`` promises that the intent's arrays have the batch shapes and lie in
        the motion model's ranges (the env's actions are checked and mapped into them).
        """
        chunk = self.motion.advance(intent, validate=not validated)
        if not self.overground and self._drift.any():
            self._apply_drift(chunk)
        imu = self.imu.sample(chunk.quat, chunk.omega, chunk.acc, chunk.pos)
        kin = chunk.kinect
        joints, hand_quat = kin.joints, kin.hand_quat
        if self.overground:  # the Kinect stands in front of the start marker, facing it
            zero = np.zeros(self.batch_size)  # room -> start-marker frame: a turn by -start yaw
            q_start = rot.quat_from_ypr(np.stack([-self._start_yaw, zero, zero], -1))[:, None, :]
            joints = rot.quat_rotate(
                q_start[:, :, None, :], joints - self._start_xy3[:, None, None, :]
            )
            hand_quat = rot.quat_multiply(q_start, hand_quat)
        frames = self.kinect.capture(kin.t, joints, hand_quat, validated=True)
        if self.tracker is None:
            q = self.attitude.update(imu.gyr, imu.acc, imu.mag)
        else:
            q = self._track(chunk, imu)
        if self._steps_position:  # a detector on the tracked headset's position (Lee 2018)
            noise = self.rng.normal(chunk.pos.shape[1:], rows=None)
            tracked = chunk.pos + self.sensors.headset_position_noise_m * noise
            gait = self.gait.update(imu.acc, imu.gyr, q, position=tracked)
        else:
            gait = self.gait.update(imu.acc, imu.gyr, q)
        ypr_est = np.empty((self.batch_size, 3))
        quat_to_ypr_rows(self.batch_size)(q[:, -1], ypr_est)  # rot.quat_to_ypr, compiled
        if self._recentre.any():  # first samples of an episode: align virtual and estimated yaw
            first = rot.quat_to_ypr(q[:, 0])[:, 0]
            self.yaw_offset = np.where(
                self._recentre, rot.wrap_angle(self._start_yaw - first), self.yaw_offset
            )
            self._recentre[:] = False
        ypr_true = chunk.ypr[:, -1]
        steps, true_steps, virtual_yaw, true_virtual_yaw, true_displacement = self._summary(
            gait.steps, chunk.step, ypr_est[:, 0], ypr_true[:, 0]
        )
        if frames.body_id.shape[1] == 0:
            raise RuntimeError("a control step must contain at least one Kinect frame")
        hand_frames = self.hand_pipeline.update_frames(
            frames.body_id,
            frames.body_tracked,
            frames.joints,
            frames.joint_state,
            frames.hand_quat,
        )
        hand = self._filtered_hand(hand_frames)
        hand_est = self._hand_relative_to_torso(hand)
        walk_yaw = virtual_yaw
        if self.tracker is None:
            if self._steer_with_torso:
                walk_yaw = self._steering_yaw(hand, virtual_yaw, hand_est[:, 0])
            if self._loco_pitch:  # a technique moved by the head's pitch (head tilt, look down)
                pos = self.locomotion.update(steps, walk_yaw, self.dt, pitch=ypr_est[:, 1])
            else:
                pos = self.locomotion.update(steps, walk_yaw, self.dt)
        else:  # the virtual head follows the estimated one; the truth is the real head
            pos = self._tracked_xy
            true_xy = chunk.pos[:, -1, :2]
            true_displacement = true_xy - self._last_true
            self._last_true = true_xy.copy()
        displacement = pos - self._last_loco
        self._last_loco = pos.copy()
        return UserStep(
            motion=chunk,
            imu=imu,
            kinect=frames,
            ypr_est=ypr_est,
            ypr_true=ypr_true,
            virtual_yaw=virtual_yaw,
            true_virtual_yaw=true_virtual_yaw,
            walk_yaw=walk_yaw,
            true_body_yaw=true_virtual_yaw - (ypr_true[:, 0] - chunk.body_yaw[:, -1]),
            steps=steps,
            step_peak_time=gait.peak_time.reshape(self.batch_size, -1),
            true_steps=true_steps,
            walking=gait.state[:, -1] > 0,
            cadence=self.cadence.update(steps, self.dt),
            displacement=displacement,
            true_displacement=true_displacement,
            hand=hand,
            hand_est=hand_est,
            hand_true=kin.hand_ypr[:, -1],
        )

    def _filtered_hand(self, frames: HandFrame) -> HandFrame:
        """The last frame of the step, its angles and validity from the hand stage."""
        last = frames.at(-1)
        ypr, valid = self.hand_filter.update(frames)
        last.ypr = ypr[:, -1]
        last.valid = np.asarray(valid[:, -1], dtype=bool)
        return last

    def _steering_yaw(
        self, hand: HandFrame, head_virtual_yaw: NDArray, hand_yaw: NDArray
    ) -> NDArray[np.float64]:
        """The walking yaw in the virtual room from the steering stage: the estimated head yaw
        and the Kinect's torso yaw, each mapped into the room (the head's through the headset's
        recentring offset, the torso's through the play area's fixed calibration), and for a
        stage that steers by the hand (``uses_hand``) the estimated hand yaw on the torso."""
        spec = self.sensors.kinect
        sh = camera_to_world(spec, hand.joints[:, [Joint.SHOULDER_LEFT, Joint.SHOULDER_RIGHT]])
        yaw, valid = torso_yaw(sh[:, 0], sh[:, 1])
        torso_virtual = rot.wrap_angle(yaw + self.true_yaw_offset)
        if self._steer_with_hand:
            return self.steering.update(
                head_virtual_yaw, torso_virtual, valid & hand.has_target, hand_yaw=hand_yaw
            )
        return self.steering.update(head_virtual_yaw, torso_virtual, valid & hand.has_target)

    def _track(self, chunk: MotionChunk, imu: ImuSamples) -> NDArray[np.float64]:
        """Visual-inertial tracking of one step; returns the estimated attitudes (B, N, 4) and
        keeps the estimated head's horizontal position at the step's end. Users reset since the
        last step start their filter at their first sample's pose, standing at the start marker
        (where the tracked space's origin is defined)."""
        assert self.tracker is not None
        if self._track_start.any():
            rows = np.flatnonzero(self._track_start)
            self.tracker.reset(rows, chunk.pos[rows, 0], chunk.quat[rows, 0])
            start_xy = chunk.pos[rows, 0, :2]
            self._last_true[rows] = start_xy
            # The locomotion origin is the room's start point; the tracker's is the head's start.
            self._track_origin[rows] = start_xy - self._last_loco[rows]
            self._track_start[:] = False
        tracked = self.tracker.step(chunk.t, imu.gyr, imu.acc, chunk.pos, chunk.quat, chunk.omega)
        self.last_tracked = tracked
        self._tracked_xy = tracked.position[:, -1, :2] - self._track_origin
        return tracked.quat

    def _summary(self, gait_steps, true_step, yaw_est, yaw_true) -> tuple[NDArray, ...]:
        """Step counts, virtual yaws and the true displacement, in one compiled call
        (:func:`~vrloco_env._core_numba.step_summary_kernel`)."""
        b = self.batch_size
        steps, true_steps = np.empty(b), np.empty(b)
        virtual_yaw, true_virtual_yaw = np.empty(b), np.empty(b)
        true_displacement = np.zeros((b, 2))
        step_summary_kernel(b)(
            gait_steps,
            true_step,
            (yaw_est, yaw_true),
            (self.yaw_offset, self.true_yaw_offset),
            self._summary_prm,
            (steps, true_steps, virtual_yaw, true_virtual_yaw, true_displacement),
        )
        return steps, true_steps, virtual_yaw, true_virtual_yaw, true_displacement

    def _hand_relative_to_torso(self, hand: HandFrame) -> NDArray[np.float64]:
        """The hand's [yaw, pitch, roll] relative to the torso, all from the Kinect's estimates:
        the filtered wrist orientation (camera space, SDK wrist frame) taken to the world and to
        the hand frame, the torso's heading from the smoothed shoulder joints (compiled)."""
        out = np.empty((self.batch_size, 3))
        joints = hand.joints
        hand_relative_to_torso(self.batch_size)(
            np.ascontiguousarray(hand.ypr),
            np.ascontiguousarray(hand.valid),
            np.ascontiguousarray(joints[:, Joint.SHOULDER_LEFT]),
            np.ascontiguousarray(joints[:, Joint.SHOULDER_RIGHT]),
            self._camera_q,
            self._sdk_to_hand,
            out,
        )
        return out
