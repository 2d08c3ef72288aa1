"""The env's per-step glue kernels (observation, attitude error) over a short episode.

A reset (every user fresh), steps, a reset of one user of a vector env in the middle (fresh and
stepped users in one call), and a last observation with one user's hand estimate missing.
"""

import gymnasium as gym
import numpy as np

import vrloco_env  # noqa: F401  (registers the ids)

STEPS = 24


def episode(env_id: str = "VRLoco-Interact-v0", num_envs: int = 2, steps: int = STEPS):
    """Observations (steps + 3, B, obs), attitude errors (steps, B) deg and whether each user
    had a hand estimate (steps, B) of a seeded vector env; user 0 is reset half-way, and the last
    observation is taken again without user 1's hand estimate."""
    env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
    try:
        core = env.unwrapped.core
        obs, _ = env.reset(seed=3)
        rng = np.random.default_rng(3)
        space = env.single_action_space
        rows, errors, hands = [obs], [], []
        for k in range(steps):
            actions = rng.uniform(space.low, space.high, (num_envs, *space.shape))
            obs, _, _, _, info = env.step(actions.astype(space.dtype))
            rows.append(obs)
            errors.append(info["attitude_error_deg"])
            hands.append(np.isfinite(core.last.hand_est).all(axis=1))
            if k == steps // 2:
                rows.append(core.reset(users=[0]))
        core.last.hand_est[1, 0] = np.nan
        rows.append(core.observe())
        return np.stack(rows), np.stack(errors), np.stack(hands)
    finally:
        env.close()


def _play():
    obs, errors, _ = episode()
    return {"observations": obs, "attitude_error_deg": errors}


CASES = {"core_observation": _play}
