"""RLlib: the env creator's autoreset and seeding against the native vector env, its errors, and
(with the ``rllib`` extra) a few PPO iterations on two env runners that repeat bit for bit."""

import json
import logging
import sys
import time

import numpy as np
import pytest

from agents.cli import main
from agents.learned.rllib import RLlibRun, make_rllib_env, ppo_config
from vrloco_env.vector import VRLocoVectorEnv

NEEDS_RLLIB = "RLlib needs its extra: pip install 'vrloco[rllib]'"


def _step_both(wrapped, native, actions):
    return wrapped.step(actions), native.step(actions)


def test_the_creator_gives_rllib_next_step_autoreset_of_the_native_episodes():
    env = make_rllib_env({"num_envs": 2, "task": "avoid", "max_episode_steps": 4, "seed": 5})
    assert env.num_envs == 2 and env.metadata["autoreset_mode"].name == "NEXT_STEP"
    native = VRLocoVectorEnv(2, task="avoid", max_episode_steps=4)  # SAME_STEP autoreset
    obs, info = env.reset(seed=7)
    first, _ = native.reset(seed=env.row_seeds(7))
    np.testing.assert_array_equal(obs, first)
    assert set(info) == {"is_success", "_is_success", "collision", "_collision"}
    actions = np.tile(np.array([0.8, 0.3, 0.0, 0.0, 0.0], np.float32), (2, 1))
    for t in range(4):  # the same episode as the native env, to its last observation
        (obs, reward, term, trunc, info), (n_obs, n_reward, n_term, n_trunc, n_info) = _step_both(
            env, native, actions
        )
        np.testing.assert_array_equal(reward, n_reward)
        np.testing.assert_array_equal(term, n_term)
        np.testing.assert_array_equal(trunc, n_trunc)
        np.testing.assert_array_equal(info["collision"], n_info["collision"])
        if t < 3:
            assert not (term | trunc).any()
            np.testing.assert_array_equal(obs, n_obs)
    assert trunc.all()
    np.testing.assert_array_equal(obs, n_info["final_obs"])  # not the next episode's first
    # The next step ignores the actions: the new episodes' first observations, reward 0 ...
    obs, reward, term, trunc, info = env.step(actions)
    assert not (term | trunc).any() and (reward == 0.0).all()
    assert not info["is_success"].any() and not info["collision"].any()
    assert not np.array_equal(obs, n_info["final_obs"])
    # ... and the new episodes run their whole 4 steps from there.
    for t in range(4):
        obs, reward, term, trunc, info = env.step(actions)
        assert (term | trunc).all() == (t == 3)


def test_every_env_runner_and_row_gets_its_own_users_and_a_seed_repeats_them():
    def first_obs(base, reset_seed):
        env = make_rllib_env({"num_envs": 3, "task": "approach", "seed": base})
        return env.reset(seed=reset_seed)[0]

    # RLlib resets env runner w with config.seed + w: runners 1 and 2 of the run seeded 0.
    run_0 = [first_obs(0, 1), first_obs(0, 2)]
    users = np.concatenate([*run_0, first_obs(1, 1 + 1)])  # and runner 1 of the run seeded 1
    assert len({row.tobytes() for row in users}) == 9  # 9 users, 9 different starts
    np.testing.assert_array_equal(first_obs(0, 2), first_obs(0, 2))
    # The env's own seeding (seed + row) would give runner 1's second user runner 2's first.
    native = VRLocoVectorEnv(3, task="approach")
    one, two = native.reset(seed=1)[0], native.reset(seed=2)[0]
    np.testing.assert_array_equal(one[1], two[0])


def test_bad_settings_are_named():
    with pytest.raises(ValueError, match="unknown keys colour; allowed: task"):
        make_rllib_env({"num_envs": 2, "colour": "red"})
    with pytest.raises(ValueError, match="VECTOR_ENTRY_POINT"):
        make_rllib_env({"task": "approach"})
    with pytest.raises(ValueError, match=r"num_envs=0: must be an integer >= 1"):
        make_rllib_env({"num_envs": 0})
    with pytest.raises(ValueError, match=r"base_seed=-1: must be an integer in \[0, 2147483647\]"):
        make_rllib_env({"num_envs": 1, "seed": -1})
    with pytest.raises(ValueError, match=r"num_env_runners=-1: must be an integer in \[0, 10000\]"):
        RLlibRun(num_env_runners=-1)
    with pytest.raises(ValueError, match=r"RLlibRun.seed=2.5: must be an integer in \[0, 214"):
        RLlibRun(seed=2.5)
    with pytest.raises(ValueError, match="task='nope'"):
        ppo_config("nope")
    with pytest.raises(ValueError, match=r"RLlibRun.num_envs_per_env_runner=0"):
        ppo_config(num_envs_per_env_runner=0)
    with pytest.raises(ValueError, match="unknown PPO settings n_steps"):
        ppo_config(n_steps=64)


def test_train_options_that_need_a_backend(capsys):
    assert main(["train", "--env-runners", "2"]) == 2
    assert "--env-runners needs --backend rllib" in capsys.readouterr().err
    assert main(["train", "--address", "auto"]) == 2
    assert "--address needs --backend ray or rllib" in capsys.readouterr().err
    assert main(["train", "--backend", "rllib", "--rollout-steps", "64"]) == 2
    assert "--rollout-steps needs --backend local or ray" in capsys.readouterr().err
    assert main(["train", "--init", "model.zip", "--rollout-steps", "64"]) == 2
    assert "--init keeps the model's own rollout steps" in capsys.readouterr().err
    assert main(["train", "--backend", "rllib", "--learning-rate", "1e-4"]) == 2
    assert "--learning-rate needs --backend local or ray" in capsys.readouterr().err
    assert main(["train", "--init", "model.zip", "--learning-rate", "1e-4"]) == 2
    assert "--init keeps the model's own learning rate" in capsys.readouterr().err
    assert main(["train", "--backend", "rllib", "--net-arch", "256,256"]) == 2
    assert "--net-arch needs --backend local or ray" in capsys.readouterr().err
    assert main(["train", "--init", "model.zip", "--net-arch", "256,256"]) == 2
    assert "--init keeps the model's own network" in capsys.readouterr().err
    for bad, why in (("256,x", "'x' is not an integer"), ("0,64", "must be in [1, 4096]")):
        with pytest.raises(SystemExit):
            main(["train", "--net-arch", bad])
        assert why in capsys.readouterr().err
    assert main(["train", "--backend", "rllib", "--residual-on", "goal_seeker"]) == 2
    assert "--residual-on needs --backend local or ray" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["train", "--learning-rate", "0"])
    assert "0.0 must be a finite number > 0" in capsys.readouterr().err


def test_without_rllib_the_error_says_how_to_install_it(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray.rllib.algorithms.ppo", None)  # its import now fails
    with pytest.raises(ValueError, match=r"pip install 'vrloco\[rllib\]'"):
        ppo_config()
    assert main(["train", "--backend", "rllib", "--steps", "64"]) == 2
    assert "pip install 'vrloco[rllib]'" in capsys.readouterr().err


def test_an_unreachable_address_is_named_at_once(tmp_path, capsys):
    pytest.importorskip("ray.rllib", reason=NEEDS_RLLIB)
    from agents.benchmark.backends import BackendError
    from agents.learned.rllib import train_rllib

    t0 = time.perf_counter()
    with pytest.raises(BackendError, match=r"cannot reach a Ray cluster at 127\.0\.0\.1:1"):
        train_rllib(steps=64, out_dir=tmp_path, address="127.0.0.1:1")
    assert time.perf_counter() - t0 < 10.0
    assert (
        main(["train", "--backend", "rllib", "--address", "127.0.0.1:1", "--out", str(tmp_path)])
        == 1
    )
    err = capsys.readouterr().err
    assert err.startswith("vrloco train: cannot reach a Ray cluster at 127.0.0.1:1")
    assert "Traceback" not in err


@pytest.mark.slow
def test_ppo_on_two_env_runners_trains_and_repeats_bit_for_bit(tmp_path):
    pytest.importorskip("ray.rllib", reason=NEEDS_RLLIB)
    import ray

    from agents.learned.rllib import train_rllib

    kw = dict(
        steps=1024,
        num_env_runners=2,
        num_envs_per_env_runner=4,
        eval_every=512,
        eval_episodes=2,
        rollout_fragment_length=64,
        minibatch_size=128,
        progress=False,
    )
    ray.init(num_cpus=2, include_dashboard=False, logging_level=logging.WARNING)
    try:
        final = train_rllib("approach", seed=3, out_dir=tmp_path / "a", **kw)
        train_rllib("approach", seed=3, out_dir=tmp_path / "b", **kw)
    finally:
        ray.shutdown()
    assert final == (tmp_path / "a" / "checkpoint").resolve() and final.is_dir()
    assert (tmp_path / "a" / "best_checkpoint").is_dir()
    assert (tmp_path / "a" / "learning_curve.png").is_file()
    curves = [json.loads((tmp_path / d / "learning_curve.json").read_text()) for d in "ab"]
    # one iteration = 2 runners x 4 users x 64 steps; evaluated after each
    assert [c["steps"] for c in curves[0]] == [512, 1024]
    for c in curves[0]:
        assert 0.0 <= c["success_rate"] <= 1.0 and np.isfinite(c["mean_return"])

    def without_wall_time(curve):
        return [{k: v for k, v in row.items() if k != "wall_s"} for row in curve]

    # the same seed: the same deterministic policy's returns, to the last digit
    assert without_wall_time(curves[0]) == without_wall_time(curves[1])
