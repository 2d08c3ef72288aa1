"""pose_source="visual_inertial": the user really walks; the helmet-tracking paper's tracker moves
the avatar."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import vrloco_env  # noqa: F401
from vrloco_env.config import EnvConfig, SensorConfig
from vrloco_env.observation import env_spec
from vrloco_env.sensors.camera import camera_spec

NAMES = env_spec(EnvConfig().ray_count, EnvConfig().ray_range_m).names  # the common entries
VIO = {"pose_source": "visual_inertial"}


def goal_seeker(obs):
    s, c = obs[NAMES.index("goal_bearing_sin")], obs[NAMES.index("goal_bearing_cos")]
    bearing = np.arctan2(s, c)
    walk = 0.4 if abs(bearing) < 0.35 else -1.0
    return np.array([walk, np.clip(2.0 * bearing, -1.0, 1.0), 0.0, 0.0, 0.0], np.float32)


def test_checker_passes_and_the_avatar_follows_the_real_head():
    env = gym.make("VRLoco-Approach-v0", **VIO)
    check_env(env.unwrapped, skip_render_check=True)
    successes, errors = 0, []
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        for _ in range(400):
            obs, _, te, tr, info = env.step(goal_seeker(obs))
            if info["collisions"] == 0:  # blocked moves separate avatar and real head by design
                errors.append(np.linalg.norm(info["position"] - info["true_position"]))
            if te or tr:
                break
        successes += info["is_success"]
    assert successes >= 2
    errors = np.array(errors)
    assert errors.size > 100
    assert np.sqrt(np.mean(errors**2)) < 0.05  # the visual-inertial estimate, metres
    # The camera was used, not the IMU alone: most of the last episode's frames updated it.
    frames = info["elapsed_time"] * env.unwrapped.sensors.head_camera.rate_hz
    assert env.unwrapped.core.users.tracker.filter.updates[0] > 0.5 * frames
    env.close()


def test_real_walking_moves_the_avatar_by_stride_times_cadence():
    env = gym.make("VRLoco-Avoid-v0", **VIO)
    env.reset(seed=1)
    start = env.unwrapped.core.ep.position[0].copy()
    for _ in range(20):  # 2 s at walk=0.5: cadence 1.7 steps/s, 0.65 m per step
        _, _, _, _, info = env.step(np.array([0.5, 0, 0, 0, 0], np.float32))
    moved = np.linalg.norm(info["position"] - start)
    assert 1.0 < moved < 0.65 * 1.7 * 2.0 + 0.1  # the speed ramps up with a 0.4 s lag
    assert moved == pytest.approx(np.linalg.norm(info["true_position"] - start), abs=0.05)
    env.close()


def test_vector_sub_env_equals_the_single_env_across_autoresets():
    n, seed, steps = 2, 5, 30
    actions = np.random.default_rng(0).uniform(-1, 1, (steps, n, 5)).astype(np.float32)
    envs = gym.make_vec("VRLoco-Approach-v0", num_envs=n, max_episode_steps=11, **VIO)
    first, _ = envs.reset(seed=seed)
    vec = [[first[i]] for i in range(n)]
    for k in range(steps):
        obs, reward, *_ = envs.step(actions[k])
        for i in range(n):
            vec[i] += [obs[i], np.array([reward[i]])]
    for i in range(n):
        env = gym.make("VRLoco-Approach-v0", max_episode_steps=11, **VIO)
        obs, _ = env.reset(seed=seed + i)
        single = [obs]
        for k in range(steps):
            obs, reward, te, tr, _ = env.step(actions[k, i])
            if te or tr:
                obs, _ = env.reset()
            single += [obs, np.array([reward])]
        for a, b in zip(vec[i], single, strict=True):
            np.testing.assert_array_equal(a, b)


def test_bad_pose_source_configuration_is_rejected_clearly():
    with pytest.raises(ValueError, match="pose_source"):
        gym.make("VRLoco-Approach-v0", pose_source="teleport")
    with pytest.raises(ValueError, match="multiple of the control rate"):
        gym.make(
            "VRLoco-Approach-v0",
            sensors=SensorConfig(head_camera=camera_spec("ideal", rate_hz=25.0)),
            **VIO,
        )
    with pytest.raises(ValueError, match=r"head_camera\.rate_hz"):
        SensorConfig(imu_rate_hz=100.0, head_camera=camera_spec("ideal", rate_hz=120.0))
