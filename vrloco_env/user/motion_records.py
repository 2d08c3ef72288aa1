"""The true motion :class:`~vrloco_env.user.motion.UserMotion` returns: one control step at the
IMU rate (:class:`MotionChunk`) with the skeleton frames that fall in it (:class:`KinectChunk`),
and the chunks of a whole run concatenated along time (:class:`MotionRecord`)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

__all__ = ["KinectChunk", "MotionChunk", "MotionRecord"]


@dataclass
class MotionChunk:
    """True motion over one control step, at the IMU rate (N samples, times ``t``).

    Attributes:
        t: sample times (s), (N,), the end of each IMU sample interval.
        quat: head/IMU orientation, sensor -> world, (B, N, 4).
        omega: body-frame angular rate (rad/s), (B, N, 3).
        pos: IMU position in the world (m), (B, N, 3).
        acc: IMU linear acceleration in the world (m/s^2, gravity excluded), (B, N, 3).
        ypr: head [yaw, pitch, roll] (rad; yaw unwrapped), (B, N, 3).
        body_yaw: the body's (torso's) yaw (rad, unwrapped), (B, N): the head's yaw is this plus
            the head-on-torso yaw (the intent's ``head_yaw`` and yaw gestures: looking around),
            :attr:`head_on_torso_yaw`.
        step: a heel strike happened in this sample's interval, (B, N) bool.
        step_time: time (s) of that heel strike, NaN where none, (B, N).
        step_offset: the same heel strikes as time (s) after the start of this control step,
            NaN where none, (B, N): independent of how long the model has run.
        walking: the user is mid-step at this sample, (B, N) bool.
        kinect: skeleton frames that fall in this control step.
    """

    shared_fields: ClassVar[tuple[str, ...]] = ("t",)  # one clock for the batch: not per user

    t: NDArray[np.float64]
    quat: NDArray[np.float64]
    omega: NDArray[np.float64]
    pos: NDArray[np.float64]
    acc: NDArray[np.float64]
    ypr: NDArray[np.float64]
    body_yaw: NDArray[np.float64]
    step: NDArray[np.bool_]
    step_time: NDArray[np.float64]
    step_offset: NDArray[np.float64]
    walking: NDArray[np.bool_]
    kinect: KinectChunk

    @property
    def head_on_torso_yaw(self) -> NDArray[np.float64]:
        """The head's yaw relative to the torso (rad), (B, N)."""
        return self.ypr[..., 0] - self.body_yaw


@dataclass
class KinectChunk:
    """True skeleton at the Kinect rate (M frames in this control step; M may be 0).

    Attributes:
        t: frame times (s), (M,).
        joints: 25 Kinect v2 joints in the world frame (m), (B, M, 25, 3).
        hand_quat: right-hand orientation, hand frame -> world, (B, M, 4).
        hand_ypr: right-hand [yaw, pitch, roll] relative to the torso heading (rad), (B, M, 3).
    """

    shared_fields: ClassVar[tuple[str, ...]] = ("t",)  # one clock for the batch: not per user

    t: NDArray[np.float64]
    joints: NDArray[np.float64]
    hand_quat: NDArray[np.float64]
    hand_ypr: NDArray[np.float64]


@dataclass
class MotionRecord(MotionChunk):
    """Chunks of a whole run concatenated along time (the fields of :class:`MotionChunk`)."""

    @classmethod
    def concatenate(cls, chunks: list[MotionChunk]) -> MotionRecord:
        if not chunks:
            raise ValueError("chunks must hold at least one MotionChunk")
        kw = {}
        for f in fields(MotionChunk):
            if f.name == "kinect":
                continue
            axis = 0 if f.name == "t" else 1
            kw[f.name] = np.concatenate([getattr(c, f.name) for c in chunks], axis=axis)
        kin = [c.kinect for c in chunks]
        kw["kinect"] = KinectChunk(
            t=np.concatenate([k.t for k in kin]),
            joints=np.concatenate([k.joints for k in kin], axis=1),
            hand_quat=np.concatenate([k.hand_quat for k in kin], axis=1),
            hand_ypr=np.concatenate([k.hand_ypr for k in kin], axis=1),
        )
        return cls(**kw)

    @property
    def step_times(self) -> list[NDArray[np.float64]]:
        """True heel-strike times (s) of each user."""
        return [st[~np.isnan(st)] for st in self.step_time]
