"""Plug your own attitude filter into vrloco: a complementary filter in thirty lines.

    python examples/custom_estimator.py             # one episode with it, beside Zhang 2021's EKF
    vrloco benchmark --techniques zhang2021,examples/custom_estimator.py:TECHNIQUE --episodes 10

The filter needs nothing from vrloco but the stage protocol (:mod:`estimators.stages`,
``docs/protocols.md``): a class built as ``Cls(batch_size, fs)`` with ``reset(rows)`` and
``update(gyr, acc, mag)`` taking (B, N, 3) samples and returning (B, N, 4) unit quaternions
``[w, x, y, z]`` (sensor -> ENU world; their norm within 1e-3 of 1, or the step is an error).
The other stages have an example each: ``custom_steps.py``, ``custom_hand.py``,
``custom_steering.py``, ``custom_locomotion.py``.
``EstimatorConfig(attitude="examples/custom_estimator.py:ComplementaryFilter")`` (or
``"package.module:ComplementaryFilter"`` once it lives in a package) selects it; the benchmark
takes a :class:`~vrloco_env.techniques.Technique` the same way.
"""

from __future__ import annotations

import numpy as np

from estimators import rotations as rot
from vrloco_env.config import EstimatorConfig
from vrloco_env.techniques import Technique


def _triad(acc: np.ndarray, mag: np.ndarray) -> np.ndarray:
    """Sensor -> ENU quaternions (B, 4) from gravity and the magnetic field (TRIAD)."""
    up = acc / np.linalg.norm(acc, axis=-1, keepdims=True)
    east = np.cross(mag, up)
    east /= np.linalg.norm(east, axis=-1, keepdims=True)
    north = np.cross(up, east)
    return rot.matrix_to_quat(np.stack([east, north, up], axis=-2))  # rows: world axes


class ComplementaryFilter:
    """Gyro integration, pulled toward the accelerometer's tilt and the magnetometer's heading
    by a fraction ``gain`` per sample (a 0.5 s time constant at 100 Hz)."""

    def __init__(self, batch_size: int, fs: float, gain: float = 0.02) -> None:
        self.dt, self.gain = 1.0 / fs, gain
        self.q = np.tile([1.0, 0.0, 0.0, 0.0], (batch_size, 1))
        self.fresh = np.ones(batch_size, bool)

    def reset(self, rows=None) -> None:
        rows = slice(None) if rows is None else rows
        self.q[rows], self.fresh[rows] = [1.0, 0.0, 0.0, 0.0], True

    def update(self, gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray | None) -> np.ndarray:
        if mag is None:  # a 6D IMU: no heading reference; the yaw is the gyro's alone
            raise ValueError("ComplementaryFilter needs a magnetometer")
        out = np.empty((*gyr.shape[:2], 4))
        for k in range(gyr.shape[1]):  # the N samples of the step; all users at once
            target = _triad(acc[:, k], mag[:, k])
            self.q[self.fresh], self.fresh[:] = target[self.fresh], False
            q = rot.quat_multiply(self.q, rot.quat_from_rotvec(gyr[:, k] * self.dt))
            err = rot.quat_to_rotvec(rot.quat_multiply(target, rot.quat_conjugate(q)))
            self.q = rot.quat_normalize(rot.quat_multiply(rot.quat_from_rotvec(self.gain * err), q))
            out[:, k] = self.q
        return out


#: The filter in Zhang 2021's chain, for ``vrloco benchmark --techniques``.
TECHNIQUE = Technique(
    "complementary",
    "a 30-line complementary filter (examples/custom_estimator.py)",
    estimators=EstimatorConfig(attitude=f"{__file__}:ComplementaryFilter"),
)


if __name__ == "__main__":
    import gymnasium as gym

    import vrloco_env  # noqa: F401  (registers the ids)

    for technique in ("zhang2021", TECHNIQUE):
        env = gym.make("VRLoco-Approach-v0", technique=technique)
        obs, info = env.reset(seed=0)
        errors = []
        for _ in range(200):
            obs, reward, terminated, truncated, info = env.step(np.array([0.8, 0.2, 0, 0, 0]))
            errors.append(info["attitude_error_deg"])
            if terminated or truncated:
                break
        name = env.unwrapped.technique
        print(
            f"{name:>14}: attitude error {np.sqrt(np.mean(np.square(errors))):.2f} deg RMS, "
            f"success {info['is_success']}, {info['collisions']} collisions"
        )
        env.close()
