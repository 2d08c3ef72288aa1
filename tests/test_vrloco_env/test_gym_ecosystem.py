"""Gymnasium's own tools on every id: its sync and async vector envs, and the episode horizon."""

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401
from vrloco_env import ENV_IDS
from vrloco_env.config import EnvConfig
from vrloco_env.env import VRLocoEnv

_ACTIONS = np.random.default_rng(3).uniform(-1, 1, (40, 2, 5)).astype(np.float32)
_ACTIONS[:, :, 0] = np.abs(_ACTIONS[:, :, 0])  # walking: steps are taken and detected


def _run(envs, steps: int):
    """Step ``envs`` through ``steps`` actions; return the observations, the ends and the infos."""
    obs, _ = envs.reset(seed=5)
    out, ends, infos = [obs], [], []
    for k in range(steps):
        obs, _, te, tr, info = envs.step(_ACTIONS[k, : envs.num_envs])
        out.append(obs)
        ends.append(te | tr)
        infos.append(info)
    return np.array(out), np.array(ends), infos


@pytest.mark.parametrize("env_id", sorted(ENV_IDS))
@pytest.mark.parametrize("mode", ["sync", "async", "vector_entry_point"])
def test_every_vectorization_mode_runs_through_autoresets_and_stacks_every_info(env_id, mode):
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode=mode, max_episode_steps=6)
    try:
        obs, ends, infos = _run(envs, 20)
    finally:
        envs.close()
    assert ends.sum(axis=0).min() >= 2  # each sub-env went through autoresets
    assert np.isfinite(obs).all()
    # Heel strikes are reported per control step as inf-padded arrays of one width. (A step
    # on which every sub-env resets, under gymnasium's next-step autoreset, has the reset info.)
    stepped = [i for i in infos if "true_step_times" in i]
    assert len(stepped) >= len(infos) // 2
    times = np.concatenate([i["true_step_times"] for i in stepped], axis=0)
    assert times.ndim == 2 and times.shape[0] == 2 * len(stepped)
    assert np.isfinite(times).any()  # the walking users took steps
    for info in stepped:
        for key in ("true_step_times", "detected_step_times", "est_hand_ypr", "position"):
            assert info[key].shape[0] == 2, key


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_gymnasium_vector_envs_start_with_the_native_vector_envs_episodes(mode):
    """Until the first reset, sub-env i of every mode is the same episode (seed + i)."""
    kw = {"num_envs": 2, "max_episode_steps": 50}
    native = gym.make_vec("VRLoco-Approach-v0", vectorization_mode="vector_entry_point", **kw)
    other = gym.make_vec("VRLoco-Approach-v0", vectorization_mode=mode, **kw)
    try:
        a, _, info_a = _run(native, 12)
        b, _, info_b = _run(other, 12)
    finally:
        native.close()
        other.close()
    np.testing.assert_array_equal(a, b)
    for x, y in zip(info_a, info_b, strict=True):
        np.testing.assert_array_equal(x["true_step_times"], y["true_step_times"])
        np.testing.assert_array_equal(x["position"], y["position"])


def test_single_env_step_times_keep_one_shape_inf_padded():
    env = gym.make("VRLoco-Approach-v0")
    env.reset(seed=0)
    shapes, finite = set(), 0
    for k in range(30):
        *_, info = env.step(_ACTIONS[k, 0])
        shapes.add((info["true_step_times"].shape, info["detected_step_times"].shape))
        finite += np.isfinite(info["true_step_times"]).sum()
    env.close()
    assert len(shapes) == 1
    assert finite > 0


def _episode_length(env) -> int:
    env.reset(seed=0)
    stand = np.array([-1.0, 0, 0, 0, 0], np.float32)  # stands still: only the horizon ends it
    for n in range(1, 5000):
        *_, te, tr, _ = env.step(stand)
        if te or tr:
            assert tr and not te
            return n
    raise AssertionError("no truncation")


def _vector_episode_length(envs) -> int:
    envs.reset(seed=0)
    for length in range(1, 5000):
        *_, tr, _ = envs.step(np.array([[-1.0, 0, 0, 0, 0]], np.float32))
        if tr[0]:
            return length
    raise AssertionError("no truncation")


def test_gym_makes_horizon_is_its_argument_and_the_spec_rebuilds_it():
    env = gym.make("VRLoco-Avoid-v0", max_episode_steps=37)
    assert env.spec.max_episode_steps == 37
    assert env.unwrapped.config.max_episode_steps is None  # the TimeLimit alone ends it
    assert _episode_length(env) == 37
    again = gym.make(env.spec)
    assert _episode_length(again) == 37
    longer = gym.make("VRLoco-Avoid-v0", max_episode_steps=700)  # past the default
    assert _episode_length(longer) == 700
    for mode in ("vector_entry_point", "sync", "async"):
        envs = gym.make_vec("VRLoco-Avoid-v0", 1, vectorization_mode=mode, max_episode_steps=37)
        assert _vector_episode_length(envs) == 37
        envs.close()
    for e in (env, again, longer):
        e.close()


def test_the_classes_horizon_is_the_configs():
    for kwargs in ({"max_episode_steps": 37}, {"config": EnvConfig(max_episode_steps=37)}):
        assert _episode_length(VRLocoEnv("avoid", **kwargs)) == 37


def test_default_horizon_is_600_steps():
    env = gym.make("VRLoco-Approach-v0")
    assert env.spec.max_episode_steps == 600
    assert _episode_length(env) == 600
    assert _episode_length(VRLocoEnv()) == 600


def test_a_horizon_gym_make_would_not_see_or_a_contradiction_is_an_error():
    with pytest.raises(ValueError, match=r"give it as gym.make\(id, max_episode_steps=20\)"):
        gym.make("VRLoco-Approach-v0", config=EnvConfig(max_episode_steps=20))
    with pytest.raises(ValueError, match=r"max_episode_steps=10 contradicts config=EnvConfig"):
        VRLocoEnv(max_episode_steps=10, config=EnvConfig(max_episode_steps=20))
    with pytest.raises(ValueError, match=r"registered max_episode_steps=600"):
        gym.make_vec("VRLoco-Approach-v0", 1, config=EnvConfig(max_episode_steps=20))


def test_importing_and_building_the_simulation_prints_nothing():
    import subprocess
    import sys

    code = (
        "import gymnasium as gym, vrloco_env\n"
        "env = gym.make('VRLoco-Approach-v0', render_mode='rgb_array')\n"
        "env.reset(seed=0); env.render(); env.close()\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "pybullet build time" not in out.stdout + out.stderr
    assert "argv[0]" not in out.stdout + out.stderr
    assert out.stdout == ""


def test_openmp_threads_sleep_when_idle_unless_the_user_chose():
    """Spinning OpenMP threads halve the vector env's speed while another job holds a core
    (python benchmarks/bench_env.py --contention); the package asks for passive waiting."""
    import os
    import subprocess
    import sys

    code = "import os, vrloco_env.core; print(os.environ['OMP_WAIT_POLICY'])"
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.stdout.strip() == "PASSIVE", out.stderr
    env["OMP_WAIT_POLICY"] = "ACTIVE"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.stdout.strip() == "ACTIVE"
