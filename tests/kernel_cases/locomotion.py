"""Pitch-driven locomotion (head tilt, the look-down toggle) on a pitch stream that crosses the
dead zone, full speed, the toggle threshold and the re-arm pitch, with a mid-run reset."""

import numpy as np

from estimators.locomotion import HeadTilt, HeadTiltParams, LookDownParams, LookDownToMove


def _pitch(n: int = 120, b: int = 3) -> np.ndarray:
    t = np.arange(n)[:, None] * 0.1
    return np.deg2rad(25.0 + 30.0 * np.sin(0.7 * t + np.arange(b)[None, :]))


def _play(model) -> dict[str, np.ndarray]:
    pitch = _pitch()
    n, b = pitch.shape
    yaw = np.cumsum(np.random.default_rng(3).normal(0.0, 0.05, (n, b)), axis=0)
    out = {"position": [], "speed": []}
    for k in range(n):
        if k == 60:
            model.reset(np.array([False, True, False]), position=[1.0, -2.0])
        out["position"].append(model.update(np.zeros(b), yaw[k], 0.1, pitch=pitch[k]))
        out["speed"].append(model.speed)
    return {key: np.stack(v) for key, v in out.items()}


CASES = {
    "head_tilt": lambda: _play(HeadTilt(3, params=HeadTiltParams(dead_zone_deg=8.0))),
    "look_down_to_move": lambda: _play(LookDownToMove(3, params=LookDownParams(speed_mps=1.2))),
}
