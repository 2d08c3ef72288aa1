"""The walking-in-place body: cadence changes mid-step, standing, turns, gestures, lean, the head
turning on the torso, hand limits, a reset of one user, overground walking, and a batch large
enough for the parallel build."""

import numpy as np

from vrloco_env.batch_rng import BatchRng
from vrloco_env.user import Intent, MotionParams, MotionRecord, UserMotion


def _intent(k: int, b: int) -> Intent:
    user = np.arange(b)
    return Intent(
        cadence=np.where(user % 3 == 1, 0.0 if k > 6 else 2.0, 1.5 + 0.1 * (user % 5)),
        turn_rate=0.4 * np.sin(k / 3),
        hand_rates=(0.2, 0.0, 0.1 + 3.0 * (k > 8)),  # the roll runs into its limit
        gesture_amplitude=(0.3 * (k % 6 > 2), 0.1, 0.05),
        gesture_frequency=(0.4, 0.3, 0.2),
        lean=-0.1 * (k > 4),
        head_yaw=np.where(user % 2 == 0, 0.8 * np.sin(k / 2), 0.0),  # some heads stay straight
    )


def _run(b: int, steps: int, **params):
    def play():
        motion = UserMotion(MotionParams(**params), BatchRng.from_seeds(range(1, b + 1)))
        motion.reset(yaw=np.linspace(-2.0, 1.0, b))
        chunks = []
        for k in range(steps):
            chunks.append(motion.advance(_intent(k, b)))
            if k == 5:  # a new episode for user 1
                motion.rng.reseed(1, np.random.default_rng(99))
                motion.reset(yaw=0.5, base=(1.0, 2.0), users=[1])
        rec = MotionRecord.concatenate(chunks)
        out = {
            name: np.asarray(getattr(rec, name), dtype=np.float64)
            for name in (
                "quat",
                "omega",
                "pos",
                "acc",
                "ypr",
                "body_yaw",
                "step",
                "step_time",
                "walking",
            )
        }
        out.update(
            joints=rec.kinect.joints, hand_quat=rec.kinect.hand_quat, hand_ypr=rec.kinect.hand_ypr
        )
        return out

    return play


CASES = {
    "motion_in_place": _run(3, 12),
    "motion_overground": _run(2, 8, overground=True, imu_rate_hz=200.0, kinect_rate_hz=15.0),
    "motion_parallel_batch": _run(16, 3),
}
