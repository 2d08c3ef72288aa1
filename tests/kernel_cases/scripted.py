"""The goal seeker's route planner on a few control steps of an Avoid episode (obstacles seen)."""

import gymnasium as gym
import numpy as np

import vrloco_env  # noqa: F401  (registers the ids)
from agents.benchmark.policies import build_policy


def _plan():
    env = gym.make("VRLoco-Avoid-v0")
    policy = build_policy("goal_seeker", env)
    obs, _ = env.reset(seed=2)
    policy.reset(np.random.default_rng(0))
    actions = []
    for _ in range(12):
        action = policy.act(obs)
        actions.append(action)
        obs = env.step(action)[0]
    return np.array(actions)


CASES = {"goal_seeker_plan": _plan}
