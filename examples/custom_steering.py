"""Plug your own steering rule into vrloco: walk between where the head and the torso point.

    python examples/custom_steering.py   # a head-scanning user, head / torso / blended steering

A steering stage is built as ``Cls(batch_size)`` and has ``reset(rows)`` and
``update(head_yaw, torso_yaw, torso_valid)``: the estimated head yaw and the Kinect's torso yaw
(rad, both in the virtual room's frame, (B,)) and whether the torso yaw holds; it returns the
(B,) walking yaw, finite (``docs/protocols.md``). ``uses_torso = False`` would tell the
environment not to compute the torso yaw at all.
``EstimatorConfig(steering="examples/custom_steering.py:BlendedSteering")`` selects it.
"""

from __future__ import annotations

import numpy as np


class BlendedSteering:
    """The circular mean of the head yaw and the torso yaw, the torso weighted ``torso_weight``;
    the head yaw alone while the Kinect has no torso. Stateless."""

    uses_torso = True

    def __init__(self, batch_size: int, torso_weight: float = 0.5) -> None:
        self.torso_weight = torso_weight

    def reset(self, rows=None) -> None:
        pass

    def update(self, head_yaw, torso_yaw, torso_valid) -> np.ndarray:
        w = np.where(torso_valid, self.torso_weight, 0.0)
        torso_yaw = np.where(torso_valid, torso_yaw, 0.0)
        x = (1.0 - w) * np.cos(head_yaw) + w * np.cos(torso_yaw)
        y = (1.0 - w) * np.sin(head_yaw) + w * np.sin(torso_yaw)
        return np.arctan2(y, x)


if __name__ == "__main__":
    import gymnasium as gym

    import vrloco_env  # noqa: F401  (registers the ids)
    from vrloco_env.config import EstimatorConfig

    blended = f"{__file__}:BlendedSteering"
    for name, steering in (("head", "head"), ("torso", "torso"), ("BlendedSteering", blended)):
        env = gym.make(
            "VRLoco-Approach-v0",
            estimators=EstimatorConfig(steering=steering),
            population="gaze_scanners",
        )
        env.reset(seed=0)
        off = []
        for _ in range(100):  # walk straight while the head scans around
            info = env.step(np.array([0.8, 0.0, 0, 0, 0]))[-1]
            off.append(info["walk_yaw_deg"] - info["true_body_yaw_deg"])
        off = (np.array(off) + 180.0) % 360.0 - 180.0
        print(f"{name:>15}: walking {np.sqrt(np.mean(off**2)):.1f} deg RMS off the torso's facing")
        env.close()
