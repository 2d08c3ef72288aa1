"""The trials of :mod:`agents.experiments.hand_variance`: users through the real chain
(motion model -> Kinect model -> :class:`estimators.hand.HandPipeline`) with the hand still
(:func:`static_trial`) or sweeping about the forearm (:func:`moving_trial`), and every reported
filter's angles on a trial (:func:`filter_outputs`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from agents.experiments.hand_variance.settings import _FS, COMPETITORS, PAPER_ANGLES_DEG
from estimators.hand import HandFrame, HandParams, HandPipeline, quat_to_euler_paper
from estimators.stages import HAND
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.kinect import KinectSpec, KinectV2
from vrloco_env.user import Intent, MotionParams, UserMotion

__all__ = ["HandTrial", "filter_outputs", "moving_trial", "simulate_trial", "static_trial"]


@dataclass
class HandTrial:
    """One simulated trial of B users: the pipeline's frames and the truth.

    Attributes:
        frames: :class:`~estimators.hand.HandFrame` stacked over all N Kinect frames ((B, N, ...)).
        steps: frames per control step, in order (they sum to N): how the env hands them over.
        truth: (B, N, 3) true wrist orientation, our ``[yaw, pitch, roll]``, rad.
    """

    frames: HandFrame
    steps: list[int]
    truth: NDArray[np.float64]

    def step_frames(self) -> list[HandFrame]:
        """The frames cut into the control steps' (B, M) stacks, as a hand stage receives them."""
        cuts = np.cumsum([0, *self.steps])
        return [
            HandFrame(*(getattr(self.frames, f.name)[:, a:b] for f in fields(HandFrame)))
            for a, b in itertools.pairwise(cuts)
        ]


def simulate_trial(
    hand_roll: NDArray[np.float64],
    roll_rate: NDArray[np.float64] | None,
    seconds: float,
    seed: int,
    params: HandParams | None = None,
) -> HandTrial:
    """Users standing still, hand at ``hand_roll`` (rad, about the forearm), through the chain.

    With ``roll_rate`` (B,) rad/s the hand sweeps about the forearm between +-75 deg at that rate.
    User ``i`` draws from ``numpy.random.default_rng([seed, i])``.
    """
    b = hand_roll.shape[0]
    mp = MotionParams()
    rng = BatchRng([np.random.default_rng([seed, i]) for i in range(b)])
    motion = UserMotion(mp, rng)
    motion.reset(hand_ypr=np.stack([np.zeros(b), np.zeros(b), hand_roll], axis=-1))
    kinect = KinectV2(KinectSpec(), rng)
    kinect.reset()
    pipe = HandPipeline(b, params)
    direction = np.ones(b)
    hand = hand_roll.copy()
    out, truth = [], []
    for _ in range(round(seconds * mp.control_rate_hz)):
        rates = np.zeros((b, 3))
        if roll_rate is not None:  # sweep between +-75 deg
            direction = np.where(hand > np.deg2rad(75), -1.0, direction)
            direction = np.where(hand < np.deg2rad(-75), 1.0, direction)
            rates[:, 2] = direction * roll_rate
            hand = hand + rates[:, 2] / mp.control_rate_hz
        chunk = motion.advance(Intent(hand_rates=rates))
        fr = kinect.capture(chunk.kinect.t, chunk.kinect.joints, chunk.kinect.hand_quat)
        out.append(
            pipe.update_frames(fr.body_id, fr.body_tracked, fr.joints, fr.joint_state, fr.hand_quat)
        )
        truth.append(quat_to_euler_paper(fr.truth.hand_quat)[..., ::-1])
    frames = HandFrame(
        *(np.concatenate([getattr(o, f.name) for o in out], axis=1) for f in fields(HandFrame))
    )
    return HandTrial(frames, [o.ypr.shape[1] for o in out], np.concatenate(truth, axis=1))


def filter_outputs(trial: HandTrial, stages: dict | None = None) -> dict[str, NDArray[np.float64]]:
    """(B, N, 3) angles of every filter of :data:`FILTERS` on ``trial``.

    ``raw``, ``kalman``, ``kalman_median`` are the pipeline's own outputs; each competitor is its
    registered stage (built with defaults, or taken from ``stages`` by name) fed the trial's
    control steps in order.
    """
    fr = trial.frames
    out = {"raw": fr.ypr_raw, "kalman": fr.ypr_kalman, "kalman_median": fr.ypr}
    b = fr.ypr.shape[0]
    for name in COMPETITORS:
        stage = (stages or {}).get(name) or HAND.build(name, b, _FS)
        out[name] = np.concatenate([stage.update(f)[0] for f in trial.step_frames()], axis=1)
    return out


def static_trial(repeats: int, seed: int, seconds: float = 10.0) -> HandTrial:
    """The hand still at the paper's 11 angles, ``repeats`` users each (pose-major order)."""
    angles = np.deg2rad(np.repeat(np.asarray(PAPER_ANGLES_DEG, float), repeats))
    return simulate_trial(angles, None, seconds, seed)


def moving_trial(
    users: int, seed: int, seconds: float = 10.0, rate_deg_s: float = 90.0
) -> HandTrial:
    """The hand sweeping about the forearm at ``rate_deg_s`` from a random start in +-60 deg."""
    start = np.deg2rad(np.random.default_rng(seed).uniform(-60, 60, users))
    return simulate_trial(start, np.full(users, np.deg2rad(rate_deg_s)), seconds, seed)
