"""Plug your own hand filter into vrloco: exponential smoothing of the wrist angles.

    python examples/custom_hand.py       # one episode with it, beside Yao 2023's filter

A hand stage is built as ``Cls(batch_size, fs)`` (fs: the Kinect frame rate, Hz) and has
``reset(rows)`` and ``update(frames)``: ``frames`` is an :class:`estimators.hand.HandFrame`
stacked over the step's M Kinect frames (``ypr_raw`` (B, M, 3): the raw wrist
``[yaw, pitch, roll]`` in rad, NaN before a target's first usable frame; ``reselected`` (B, M):
a new target was picked), and it returns (B, M, 3) angles in [-pi, pi] with their (B, M)
validity; NaN is allowed only where the validity is False (``docs/protocols.md``).
``EstimatorConfig(hand="examples/custom_hand.py:SmoothedHand")`` selects it.
"""

from __future__ import annotations

import numpy as np

from estimators.rotations import wrap_angle


class SmoothedHand:
    """First-order low-pass filter on each angle (time constant ``time_constant`` s), taking
    the short way round at +-pi; it restarts from the raw angles at a new target and holds its
    value while the raw angles are missing."""

    def __init__(self, batch_size: int, fs: float, time_constant: float = 0.1) -> None:
        self.alpha = 1.0 - np.exp(-1.0 / (fs * time_constant))  # per-frame smoothing factor
        self.ypr = np.full((batch_size, 3), np.nan)

    def reset(self, rows=None) -> None:
        self.ypr[slice(None) if rows is None else rows] = np.nan

    def update(self, frames) -> tuple[np.ndarray, np.ndarray]:
        raw = frames.ypr_raw
        out = np.empty(raw.shape)
        for j in range(raw.shape[1]):  # the M frames of the step; all users at once
            x, y = raw[:, j], self.ypr
            seen = np.isfinite(x).all(axis=-1, keepdims=True)
            start = frames.reselected[:, j, None] | ~np.isfinite(y).all(axis=-1, keepdims=True)
            moved = wrap_angle(y + self.alpha * wrap_angle(x - y))
            self.ypr = np.where(seen, np.where(start, x, moved), np.where(start, np.nan, y))
            out[:, j] = self.ypr
        return out, np.isfinite(out).all(axis=-1)


if __name__ == "__main__":
    import gymnasium as gym

    import vrloco_env  # noqa: F401  (registers the ids)
    from vrloco_env.config import EstimatorConfig

    action = np.array([0.0, 0.0, 0.6, -0.4, 0.3])  # stand still, rotate the hand
    for name, hand in (("yao2023", "yao2023"), ("SmoothedHand", f"{__file__}:SmoothedHand")):
        env = gym.make("VRLoco-Interact-v0", estimators=EstimatorConfig(hand=hand))
        env.reset(seed=0)
        errors = [env.step(action)[-1]["hand_error_deg"] for _ in range(60)]
        print(f"{name:>12}: hand error {np.sqrt(np.nanmean(np.square(errors))):.1f} deg RMS")
        env.close()
