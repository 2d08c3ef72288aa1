"""The stable-baselines3 adapter and a tiny PPO run (the learning curve itself is a benchmark)."""

import json

import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecEnv

from agents.learned import SB3VecEnv, evaluate_model, train_ppo
from vrloco_env.vector import VRLocoVectorEnv


def test_adapter_reports_terminal_observations_and_time_limits():
    venv = SB3VecEnv(VRLocoVectorEnv(2, task="avoid", max_episode_steps=4), seed=3)
    assert isinstance(venv, VecEnv)
    obs = venv.reset()
    assert obs.shape == (2, *venv.observation_space.shape)
    for _ in range(3):
        venv.step_async(np.zeros((2, 5), np.float32))
        obs, reward, done, infos = venv.step_wait()
        assert not done.any() and infos == [{}, {}]
    venv.step_async(np.zeros((2, 5), np.float32))
    obs, reward, done, infos = venv.step_wait()
    assert done.all() and reward.dtype == np.float32
    for info in infos:
        assert info["TimeLimit.truncated"] and info["episode"]["l"] == 4
        assert info["terminal_observation"].shape == obs.shape[1:]
    # The same seed gives the same first observation.
    again = SB3VecEnv(VRLocoVectorEnv(2, task="avoid", max_episode_steps=4), seed=3)
    np.testing.assert_array_equal(
        again.reset(),
        SB3VecEnv(VRLocoVectorEnv(2, task="avoid", max_episode_steps=4), seed=3).reset(),
    )


def test_tiny_ppo_run_writes_a_model_and_a_learning_curve(tmp_path):
    from vrloco_env.config import EnvConfig

    path = train_ppo(
        "avoid",
        steps=512,
        num_envs=4,
        out_dir=tmp_path,
        eval_every=256,
        eval_episodes=2,
        progress=False,
        n_steps=64,
        batch_size=128,
    )
    assert path.is_file()
    curve = json.loads((tmp_path / "learning_curve.json").read_text())
    assert curve[-1]["steps"] >= 512 and 0.0 <= curve[-1]["success_rate"] <= 1.0
    result = evaluate_model(path, episodes=2)
    assert result["task"] == "avoid"  # the model's own task, not a default
    assert result["sensors"] == "ig500n"
    # The benchmark plays the same model through the same episode loop: the same numbers.
    from agents.benchmark import run_benchmark

    (row,) = run_benchmark(tasks=["avoid"], policies=[str(path)], techniques=["seed000"],
                           episodes=2, workers=1, progress=False, print_table=False)  # fmt: skip
    for key in ("success_rate", "spl", "attitude_rmse_deg", "mean_collisions"):
        assert row[key] == pytest.approx(result[key], nan_ok=True), key
    # Batched users play the model row by row: the same table as one episode at a time.
    kw = dict(tasks=["avoid"], policies=[str(path)], techniques=["seed000"], episodes=3,
              workers=1, progress=False, print_table=False)  # fmt: skip
    assert run_benchmark(**kw, batch_size=2) == run_benchmark(**kw, batch_size=0)
    with pytest.raises(ValueError, match="trained on task 'avoid'"):
        run_benchmark(tasks=["approach"], policies=[str(path)], episodes=1, workers=1,
                      progress=False, print_table=False)  # fmt: skip
    with pytest.raises(ValueError, match="contradicts the model"):
        evaluate_model(path, task="approach", episodes=1)
    with pytest.raises(ValueError, match="contradicts the model"):
        evaluate_model(path, sensor_preset="consumer_mems", episodes=1)
    # Every saved model (checkpoints too) carries the env it was trained on.
    from stable_baselines3 import PPO

    for saved in [path, *sorted((tmp_path / "checkpoints").glob("*.zip"))]:
        settings = PPO.load(saved).vrloco_env
        assert settings["task"] == "avoid"
        assert settings["config"] == EnvConfig()
    for key in (
        "success_rate",
        "collision_rate",
        "collision_free_success_rate",
        "spl",
        "step_f1",
        "attitude_rmse_deg",
    ):  # the benchmark's metrics
        assert key in result, key
    assert result["episodes"] == 2
