"""The Gymnasium environments: API contracts, determinism, physics of the virtual body, errors."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import vrloco_env
from vrloco_env.config import EnvConfig, EstimatorConfig
from vrloco_env.env import VRLocoEnv
from vrloco_env.observation import env_spec
from vrloco_env.world import signed_distance
from vrloco_env.world.sim import display_available

IDS = list(vrloco_env.ENV_IDS)


NAMES = env_spec(EnvConfig().ray_count, EnvConfig().ray_range_m).names  # the common entries


def goal_seeker(obs, names=NAMES):
    """Turn toward the goal bearing (from the observation), step when roughly aligned."""
    s, c = obs[names.index("goal_bearing_sin")], obs[names.index("goal_bearing_cos")]
    bearing = np.arctan2(s, c)
    turn = np.clip(2.0 * bearing, -1.0, 1.0)
    walk = 0.5 if abs(bearing) < 0.35 else -1.0
    return np.array([walk, turn, 0.0, 0.0, 0.0], np.float32)


@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_and_sb3_checkers_pass(env_id):
    env = gym.make(env_id)
    check_env(env.unwrapped)  # every mode it declares renders (headless: "human" is not one)
    sb3_check_env(env.unwrapped, warn=True)
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_same_seed_same_episode_bit_for_bit(env_id):
    def run(seed):
        env = gym.make(env_id)
        env.action_space.seed(seed)
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for _ in range(40):
            obs, r, te, tr, info = env.step(env.action_space.sample())
            out += [obs, np.array([r, te, tr, info["collisions"]], float), info["true_position"]]
        env.close()
        return np.concatenate([np.ravel(x) for x in out])

    a, b, c = run(3), run(3), run(4)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_reset_observation_and_info_contents():
    env = gym.make("VRLoco-Approach-v0")
    obs, info = env.reset(seed=0)
    names = env.unwrapped.observation_spec.names
    assert obs.shape == (len(names),) and obs.dtype == np.float32
    assert env.observation_space.contains(obs)
    assert info["distance_to_goal"] > 0 and info["shortest_path"] >= info["distance_to_goal"]
    obs, *_, info = env.step(np.zeros(5, np.float32))
    for key in (
        "true_ypr",
        "est_ypr",
        "attitude_error_deg",
        "true_steps",
        "detected_steps",
        "true_hand_ypr",
        "est_hand_ypr",
        "hand_error_deg",
        "collision",
        "collisions",
        "distance_to_goal",
        "is_success",
        "cost",
        "position",
        "true_position",
    ):
        assert key in info, key
    assert info["attitude_error_deg"] < 5.0  # the EKF initialised from the first samples
    assert info["true_steps"] == 0 and info["detected_steps"] == 0  # standing still


def test_walking_into_the_avoid_obstacle_is_blocked_and_counted():
    env = gym.make("VRLoco-Avoid-v0")
    env.reset(seed=5)
    layout = env.unwrapped.layout
    collisions, positions = 0, []
    for _ in range(250):  # walk straight ahead: the obstacle sits on the straight line
        _, _, te, tr, info = env.step(np.array([0.5, 0, 0, 0, 0], np.float32))
        positions.append(info["position"])
        collisions = info["collisions"]
        if te or tr:
            break
    assert collisions > 0
    clearance = signed_distance(layout, np.array(positions))
    assert clearance.min() > layout.avatar_radius  # never inside an obstacle or a wall
    assert not info["is_success"]


@pytest.mark.parametrize("locomotion", ["eq17", "smooth"])
def test_a_goal_seeking_user_reaches_the_approach_goal(locomotion):
    env = gym.make("VRLoco-Approach-v0", locomotion=locomotion)
    successes = 0
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        for _ in range(600):
            obs, _, te, tr, info = env.step(goal_seeker(obs))
            if te or tr:
                break
        successes += info["is_success"]
        if info["is_success"]:
            assert te and info["distance_to_goal"] == 0.0
    assert successes >= 2  # a naive seeker (no avoidance) may meet an obstacle once


def test_steps_move_the_virtual_body_by_about_a_step_length_each():
    env = gym.make("VRLoco-Avoid-v0", estimators=EstimatorConfig(step_length=0.5))
    env.reset(seed=2)
    true_steps = detected = 0
    start = env.unwrapped.core.ep.position[0].copy()
    for _ in range(30):
        _, _, _, _, info = env.step(np.array([0.5, 0, 0, 0, 0], np.float32))
        true_steps += info["true_steps"]
        detected += info["detected_steps"]
    moved = np.linalg.norm(info["position"] - start)
    assert true_steps >= 4 and abs(detected - true_steps) <= 1
    assert moved == pytest.approx(0.5 * detected, rel=0.02)


def test_actions_outside_the_space_are_clipped_and_nan_is_rejected():
    def first_step(action):
        env = gym.make("VRLoco-Approach-v0")
        env.reset(seed=7)
        return env.step(np.asarray(action, np.float32))[0]

    np.testing.assert_array_equal(first_step([5, -3, 2, 0, 0]), first_step([1, -1, 1, 0, 0]))
    env = gym.make("VRLoco-Approach-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action\[1\] \(turn\) is nan"):
        env.step(np.array([0, np.nan, 0, 0, 0], np.float32))
    with pytest.raises(ValueError, match=r"action must have shape \(5,\)"):
        env.step(np.zeros(4, np.float32))


def test_rgb_array_render_and_close_twice():
    env = gym.make("VRLoco-Interact-v0", render_mode="rgb_array")
    env.reset(seed=1)
    for _ in range(5):
        env.step(np.array([0.5, 0.2, 0.3, 0.0, 0.0], np.float32))
    img = env.render()
    assert img.shape == (480, 960, 3) and img.dtype == np.uint8
    assert img[:, :480].std() > 10 and img[:, 480:].std() > 5  # a map and a 3-D view, not blank
    assert env.metadata["render_fps"] == 10
    env.close()
    env.close()


@pytest.mark.skipif(display_available(), reason="a display exists: the GUI would open")
def test_human_render_without_a_display_says_so():
    env = gym.make("VRLoco-Approach-v0", render_mode="human")
    with pytest.raises(RuntimeError, match="needs a display"):
        env.reset(seed=0)
    env.close()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"task": "fly"}, "task='fly': unknown; valid names: approach, avoid, interact"),
        ({"sensor_preset": "iphone"}, "iphone"),
        ({"locomotion": "teleport"}, "locomotion='teleport': unknown; valid names: eq17, smooth"),
        ({"render_mode": "ascii"}, "render_mode='ascii'"),
        (
            {"config": EnvConfig(max_episode_steps=10), "max_episode_steps": 0},
            r"max_episode_steps=0: must be an integer in \[1, 100000\]",
        ),
    ],
)
def test_bad_configuration_is_rejected_clearly(kwargs, match):
    with pytest.raises(ValueError, match=match):
        VRLocoEnv(**kwargs)


def test_sensor_noise_comes_from_the_seed():
    """Standing still, the true motion is the same for every seed: the IMU samples differ only
    through the user's random stream, which the seed must set."""

    def first_imu(seed):
        env = gym.make("VRLoco-Approach-v0")
        env.reset(seed=seed)
        env.step(np.zeros(5, np.float32))
        return env.unwrapped.core.last.imu.acc[0]

    np.testing.assert_array_equal(first_imu(1), first_imu(1))
    assert not np.array_equal(first_imu(1), first_imu(2))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"terminate_on_collision": "yes"}, r"terminate_on_collision='yes': must be True"),
        ({"ray_count": 2.5}, r"EnvConfig.ray_count=2.5: must be an integer in \[1, 360\]"),
        ({"max_episode_steps": "600"}, r"EnvConfig.max_episode_steps='600': must be an integer"),
        ({"max_episode_steps": 1.5}, r"EnvConfig.max_episode_steps=1.5: must be an integer"),
    ],
)
def test_config_types_are_checked(kwargs, match):
    with pytest.raises(ValueError, match=match):
        EnvConfig(**kwargs)
    assert EnvConfig(max_episode_steps=np.int64(50)).max_episode_steps == 50


@pytest.mark.parametrize(
    "bad", ["abc", {"walk": 1.0}, np.full(5, 1j), np.ones(5, bool), np.ones(4)]
)
def test_an_action_that_is_not_five_real_numbers_is_refused_by_name(bad):
    env = gym.make("VRLoco-Approach-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action must (be an array of|have) shape \(5,\)"):
        env.step(bad)


def test_a_collision_forfeits_the_success_bonus_only_when_asked():
    """The same episode (hand steering bumps into the room, then reaches the goal) under both
    objectives: the bonus is withheld at the success step, and nothing else changes."""
    from agents.benchmark.policies import build_policy
    from vrloco_env.config import RewardConfig

    def play(reward):
        env = gym.make("VRLoco-Approach-v0", technique="hand_steering", reward=reward)
        user = build_policy("goal_seeker", env)
        obs, _ = env.reset(seed=3)
        user.reset(np.random.default_rng([3, 1]))
        rewards, info = [], {}
        for _ in range(600):
            obs, r, terminated, truncated, info = env.step(user.act(obs))
            rewards.append(r)
            if terminated or truncated:
                break
        return np.array(rewards), info

    plain, info = play(RewardConfig())
    strict, strict_info = play(RewardConfig(success_without_collision=True))
    assert info["is_success"] and info["collisions"] > 0 and strict_info["is_success"]
    np.testing.assert_array_equal(plain[:-1], strict[:-1])
    assert plain[-1] - strict[-1] == pytest.approx(RewardConfig().success)


def test_hand_progress_pays_the_hand_errors_fall_and_nothing_else():
    """The goal seeker's Interact episode under both objectives: the difference of rewards sums
    to the weight times the fall of the hand's error to its target from the first estimate to
    the last (a difference of potentials), and the error falls as the seeker aligns the hand.
    A task without a hand target pays nothing for it."""
    from agents.benchmark.policies import build_policy
    from vrloco_env.config import RewardConfig
    from vrloco_env.tasks.interact import hand_error

    def play(task, reward):
        env = gym.make(f"VRLoco-{task}-v0", reward=reward)
        user = build_policy("goal_seeker", env)
        obs, _ = env.reset(seed=4)
        user.reset(np.random.default_rng([4, 1]))
        rewards, errors = [], []
        for _ in range(600):
            obs, r, terminated, truncated, info = env.step(user.act(obs))
            rewards.append(r)
            if task == "Interact":
                t = env.unwrapped.core.task
                est = np.asarray(info["est_hand_ypr"], dtype=np.float64)[None]
                errors.append(float(hand_error(np.deg2rad(est), t.hand_target[:1])[0]))
            if terminated or truncated:
                break
        return np.array(rewards), np.array(errors), info

    plain, errors, info = play("Interact", RewardConfig())
    shaped, _, shaped_info = play("Interact", RewardConfig(hand_progress=2.0))
    assert info["is_success"] and shaped_info["is_success"]
    known = errors[np.isfinite(errors)]
    assert known[0] - known[-1] > np.deg2rad(10)  # the seeker brought the hand to its target
    np.testing.assert_allclose((shaped - plain).sum(), 2.0 * (known[0] - known[-1]), atol=1e-9)
    plain, _, _ = play("Approach", RewardConfig())
    shaped, _, _ = play("Approach", RewardConfig(hand_progress=2.0))
    np.testing.assert_array_equal(plain, shaped)
