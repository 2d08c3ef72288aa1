"""Plug your own step detector into vrloco: a peak picker on the specific force's norm.

    python examples/custom_steps.py      # one walk with it, beside Zhang 2021's detector

A step stage is built as ``Cls(batch_size, fs)`` (fs: the IMU rate, Hz) and has
``reset(rows)`` and ``update(acc, gyr, quat)`` returning an :class:`estimators.stages.GaitChunk`:
per sample of the step, still (0) or walking (1), the steps confirmed there (0, 1 or 2) and
their heel-strike times on the stream's own clock (sample k after the user's last reset is at
k / fs s), never later than the sample that confirms them (``docs/protocols.md``).
``EstimatorConfig(steps="examples/custom_steps.py:PeakSteps")`` selects it. Subclassing
:class:`~estimators.batching.TakesUsers` and naming the per-user attributes lets the benchmark's
batches drop finished users.
"""

from __future__ import annotations

import numpy as np

from estimators.batching import TakesUsers
from estimators.stages import GaitChunk

GRAVITY = 9.81  # m/s^2


class PeakSteps(TakesUsers):
    """A step at each local maximum of |f| more than ``threshold`` (m/s^2) above gravity and at
    least ``min_interval`` (s) after the previous step; confirmed one sample later. Walking while
    the last step is less than ``walk_hold`` (s) old."""

    per_user_fields = ("clock", "prev", "last_step")
    batch_size_field = "batch_size"

    def __init__(
        self,
        batch_size: int,
        fs: float,
        threshold: float = 1.5,
        min_interval: float = 0.3,
        walk_hold: float = 1.0,
    ) -> None:
        self.batch_size, self.fs = batch_size, fs
        self.threshold, self.min_interval, self.walk_hold = threshold, min_interval, walk_hold
        self.report_delay_s = 1.0 / fs  # a peak is known at the next sample
        self.clock = np.zeros(batch_size, np.int64)  # samples since each user's reset
        self.prev = np.full((batch_size, 2), np.nan)  # |f| one and two samples back
        self.last_step = np.full(batch_size, -np.inf)  # time of each user's last step (s)
        self.seen = 0  # samples since construction (the chunks' sample_time)

    def reset(self, rows=None) -> None:
        rows = slice(None) if rows is None else rows
        self.clock[rows], self.prev[rows], self.last_step[rows] = 0, np.nan, -np.inf

    def update(self, acc: np.ndarray, gyr: np.ndarray, quat: np.ndarray) -> GaitChunk:
        b, n = acc.shape[:2]
        norm = np.linalg.norm(acc, axis=-1)
        state, steps = np.zeros((b, n), np.int8), np.zeros((b, n), np.int8)
        peak_time = np.full((b, n, 2), np.nan)
        for k in range(n):  # the N samples of the step; all users at once
            before, peak, now = self.prev[:, 1], self.prev[:, 0], norm[:, k]
            t_peak = (self.clock + k - 1) / self.fs  # the previous sample's time
            step = (
                (peak > before)
                & (peak >= now)
                & (peak > GRAVITY + self.threshold)
                & (t_peak - self.last_step >= self.min_interval)
            )
            steps[step, k], peak_time[step, k, 0] = 1, t_peak[step]
            self.last_step[step] = t_peak[step]
            state[:, k] = (self.clock + k) / self.fs - self.last_step < self.walk_hold
            self.prev = np.stack([now, peak], axis=-1)
        self.clock += n
        self.seen += n
        sample_time = (self.seen - n + np.arange(n)) / self.fs
        return GaitChunk(state=state, steps=steps, peak_time=peak_time, sample_time=sample_time)


if __name__ == "__main__":
    import gymnasium as gym

    import vrloco_env  # noqa: F401  (registers the ids)
    from vrloco_env.config import EstimatorConfig

    for name, steps in (("zhang2021", "zhang2021"), ("PeakSteps", f"{__file__}:PeakSteps")):
        env = gym.make("VRLoco-Approach-v0", estimators=EstimatorConfig(steps=steps))
        env.reset(seed=0)
        detected = true = 0
        for _ in range(100):
            *_, info = env.step(np.array([0.8, 0.0, 0, 0, 0]))
            detected, true = detected + info["detected_steps"], true + info["true_steps"]
        print(f"{name:>9}: {detected} steps detected, {true} taken in 10 s")
        env.close()
