"""Gymnasium ids of the vrloco tasks; ``import vrloco_env`` registers them."""

from __future__ import annotations

import gymnasium as gym

#: id -> task name.
ENV_IDS = {
    "VRLoco-Approach-v0": "approach",
    "VRLoco-Avoid-v0": "avoid",
    "VRLoco-Interact-v0": "interact",
}
MAX_EPISODE_STEPS = 600  # 60 s at the 10 Hz control rate


def register_envs() -> None:
    """Register every id (idempotent)."""
    for env_id, task in ENV_IDS.items():
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point="vrloco_env.env:VRLocoEnv",
            vector_entry_point="vrloco_env.vector:VRLocoVectorEnv",
            max_episode_steps=MAX_EPISODE_STEPS,
            kwargs={"task": task},
        )
