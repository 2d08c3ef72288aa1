"""The native vector env: batched spaces, same-step autoreset, and sub-env i == single env."""

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401
from vrloco_env.vector import VRLocoVectorEnv


def test_make_vec_uses_the_native_vector_env():
    envs = gym.make_vec("VRLoco-Approach-v0", num_envs=4)
    assert isinstance(envs.unwrapped, VRLocoVectorEnv)
    obs, info = envs.reset(seed=0)
    assert obs.shape == (4, *envs.single_observation_space.shape)
    assert envs.observation_space.contains(obs)
    assert envs.metadata["autoreset_mode"] == gym.vector.AutoresetMode.SAME_STEP
    obs, reward, te, tr, info = envs.step(envs.action_space.sample())
    assert reward.shape == te.shape == tr.shape == (4,)
    assert info["collisions"].shape == (4,)
    envs.close()


@pytest.mark.parametrize("env_id", ["VRLoco-Approach-v0", "VRLoco-Interact-v0"])
def test_sub_env_i_behaves_exactly_like_a_single_env_seeded_seed_plus_i(env_id):
    n, seed, steps = 3, 11, 70
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (steps, n, 5)).astype(np.float32)
    actions[:, :, 0] = np.abs(actions[:, :, 0])  # mostly walking: steps, collisions, goals
    # Short episodes of different lengths, so sub-envs autoreset at different times.
    envs = gym.make_vec(env_id, num_envs=n, max_episode_steps=23)
    vec_obs, _ = envs.reset(seed=seed)
    vec = [[vec_obs[i]] for i in range(n)]
    resets = np.zeros(n, int)
    for k in range(steps):
        obs, reward, te, tr, _ = envs.step(actions[k])
        resets += te | tr
        for i in range(n):
            vec[i] += [obs[i], np.array([reward[i], te[i], tr[i]])]
    assert resets.sum() >= n  # every sub-env went through at least one autoreset

    for i in range(n):
        env = gym.make(env_id, max_episode_steps=23)
        obs, _ = env.reset(seed=seed + i)
        single = [obs]
        for k in range(steps):
            obs, reward, te, tr, _ = env.step(actions[k, i])
            if te or tr:
                obs, _ = env.reset()
            single += [obs, np.array([reward, te, tr])]
        for a, b in zip(vec[i], single, strict=True):
            np.testing.assert_array_equal(a, b)


def test_final_observation_is_reported_on_autoreset():
    envs = gym.make_vec("VRLoco-Avoid-v0", num_envs=2, max_episode_steps=5)
    envs.reset(seed=1)
    for _ in range(4):
        _, _, te, tr, info = envs.step(np.zeros((2, 5), np.float32))
        assert not np.any(te | tr) and "final_obs" not in info
    obs, _, te, tr, info = envs.step(np.zeros((2, 5), np.float32))
    assert np.all(tr) and info["_final_obs"].all()
    assert info["final_obs"].shape == obs.shape
    assert np.all(info["final_info"]["elapsed_time"] == pytest.approx(0.5))


def test_vector_env_rejects_rendering_and_bad_seeds():
    with pytest.raises(ValueError, match="does not render"):
        VRLocoVectorEnv(2, render_mode="rgb_array")
    envs = VRLocoVectorEnv(2)
    with pytest.raises(ValueError, match="list of 2 seeds"):
        envs.reset(seed=[1, 2, 3])


def test_disabled_autoreset_leaves_resets_to_the_caller_with_a_mask():
    from gymnasium.vector import AutoresetMode

    from vrloco_env.vector import VRLocoVectorEnv

    envs = VRLocoVectorEnv(
        3, task="avoid", max_episode_steps=4, autoreset_mode=AutoresetMode.DISABLED
    )
    assert envs.metadata["autoreset_mode"] is AutoresetMode.DISABLED
    envs.reset(seed=[7, 8, 9])
    for _ in range(4):
        obs, _, _, truncated, info = envs.step(np.zeros((3, 5), np.float32))
    assert np.all(truncated) and "final_obs" not in info  # ended, not reset
    mask = np.array([False, True, False])
    obs, info = envs.reset(seed=[None, 21, None], options={"reset_mask": mask})
    single = gym.make("VRLoco-Avoid-v0", max_episode_steps=4)
    first, single_info = single.reset(seed=21)
    np.testing.assert_array_equal(obs[1], first)  # the masked user starts seed 21's episode
    np.testing.assert_array_equal(info["position"][1], single_info["position"])
    info = envs.step(np.zeros((3, 5), np.float32))[-1]
    assert info["elapsed_time"][1] == pytest.approx(0.1) and info["elapsed_time"][0] > 0.4
    with pytest.raises(ValueError, match="reset_mask"):
        envs.reset(options={"reset_mask": np.array([True, False])})
    with pytest.raises(ValueError, match="selects no sub-env"):
        envs.reset(options={"reset_mask": np.zeros(3, bool)})
    with pytest.raises(ValueError, match="autoreset_mode"):
        VRLocoVectorEnv(2, autoreset_mode="next-step")


def test_reset_options_of_a_wrong_type_or_key_are_one_clear_error():
    envs = VRLocoVectorEnv(2, task="avoid")
    envs.reset(seed=0)
    for bad in ([True, False], "reset_mask", 3):
        with pytest.raises(
            ValueError,
            match=r"options=.*: must be None or a dict \(key "
            r"'reset_mask': a boolean array of shape \(2,\)\)",
        ):
            envs.reset(options=bad)
    with pytest.raises(
        ValueError,
        match=r"options: unknown key\(s\) 'mask'; the one option is "
        r"'reset_mask'",
    ):
        envs.reset(options={"mask": np.ones(2, bool)})
    obs, _ = envs.reset(seed=5, options={})  # an empty dict is no option
    np.testing.assert_array_equal(obs, VRLocoVectorEnv(2, task="avoid").reset(seed=5)[0])
