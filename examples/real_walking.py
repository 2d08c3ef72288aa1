"""A goal-seeking user who really walks (the helmet-tracking paper), tracked by the head camera and
the IMU.

Runs one Approach episode with ``pose_source="visual_inertial"`` under a chosen lighting
condition and prints how far the avatar (the visual-inertial estimate) was from the real head.

Usage: python examples/real_walking.py [ideal|low_light|occlusion|motion_blur] [SEED]
"""

import sys

import gymnasium as gym
import numpy as np

import vrloco_env  # noqa: F401  (registers the ids)
from vrloco_env.config import EnvConfig, SensorConfig
from vrloco_env.observation import env_spec
from vrloco_env.sensors.camera import camera_spec

NAMES = env_spec(EnvConfig().ray_count, EnvConfig().ray_range_m).names  # the common entries


def seek(obs: np.ndarray) -> np.ndarray:
    """Turn toward the goal, walk when roughly facing it."""
    bearing = np.arctan2(obs[NAMES.index("goal_bearing_sin")], obs[NAMES.index("goal_bearing_cos")])
    walk = 0.4 if abs(bearing) < 0.35 else -1.0
    return np.array([walk, np.clip(2.0 * bearing, -1, 1), 0, 0, 0], np.float32)


if __name__ == "__main__":
    condition = sys.argv[1] if len(sys.argv) > 1 else "ideal"
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 0
    env = gym.make(
        "VRLoco-Approach-v0",
        pose_source="visual_inertial",
        sensors=SensorConfig(head_camera=camera_spec(condition, rate_hz=30.0)),
    )
    obs, _ = env.reset(seed=seed)
    errors = []
    for _ in range(600):
        obs, _, terminated, truncated, info = env.step(seek(obs))
        if info["collisions"] == 0:  # a blocked step separates avatar and real head on purpose
            errors.append(np.linalg.norm(info["position"] - info["true_position"]))
        if terminated or truncated:
            break
    tracker = env.unwrapped.core.users.tracker
    print(
        f"{condition}: success={info['is_success']} after {info['elapsed_time']:.1f} s, "
        f"collisions={info['collisions']}"
    )
    print(
        f"avatar vs real head: RMS {np.sqrt(np.mean(np.square(errors))):.3f} m, "
        f"max {np.max(errors):.3f} m; frames used {tracker.filter.updates[0]}, "
        f"refused {tracker.filter.rejected[0]}"
    )
