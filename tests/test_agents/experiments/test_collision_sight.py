"""When a user's rays last showed what it walked into: the rays' hit points placed in the room,
and a user that walks straight ahead into what its centre ray shows."""

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401  (registers the ids)
from agents.experiments.collision_sight import SIGHT, collision_sight, ray_hits
from vrloco_env.world.geometry import solid_distance


def test_every_ray_hit_lies_on_a_solid_of_the_room():
    env = gym.make("VRLoco-Approach-v0")
    obs, _ = env.reset(seed=3)
    rng = np.random.default_rng(0)
    counted = 0
    for _ in range(60):
        pts = ray_hits(env, obs)
        if pts.size:
            d = solid_distance(env.unwrapped.core.layouts[0].solids, pts)
            assert np.abs(d).max() < 1e-3  # float32 ranges over 5 m: well under a millimetre
            counted += pts.shape[0]
        obs, *_ = env.step(rng.uniform(-1.0, 1.0, env.action_space.shape))
    env.close()
    assert counted > 100


class _WalkAhead:
    """Walks in place at full cadence and never turns: it walks into what lies dead ahead."""

    def __init__(self, env):
        self.action = np.zeros(env.action_space.shape, dtype=np.float32)
        self.action[0] = 1.0

    def reset(self, rng=None, rows=None):
        pass

    def act(self, obs):
        return self.action


def test_a_user_walking_straight_ahead_saw_what_it_walked_into_in_its_last_observation(
    monkeypatch,
):
    monkeypatch.setattr("agents.benchmark.policies.build_policy", lambda spec, env: _WalkAhead(env))
    r = collision_sight("approach", episodes=4, seed=1000, policy="walk_ahead")
    assert r["collisions"] >= 1 and r["episodes_colliding"] >= 1
    assert r["sight"] == {**dict.fromkeys(SIGHT, 0), "last_frame": r["collisions"]}
    assert sum(r["walked_into"].values()) == r["collisions"]
    assert sum(r["first"].values()) == r["episodes_colliding"]
    assert r["blocked_steps"] >= r["collisions"]


def test_bad_settings_are_named():
    with pytest.raises(ValueError, match="episodes=0: must be >= 1"):
        collision_sight("approach", episodes=0, seed=0)
    with pytest.raises(ValueError, match="frames=0"):
        collision_sight("approach", episodes=1, seed=0, frames=0)
