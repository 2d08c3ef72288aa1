"""The stable-baselines3 adapter and a tiny PPO run (the learning curve itself is a benchmark)."""

import json
import sys

import numpy as np
import pytest

from agents.learned import SB3VecEnv, evaluate_model, train_ppo  # before torch: see its docs
from vrloco_env.config import RewardConfig
from vrloco_env.vector import VRLocoVectorEnv


def test_adapter_reports_terminal_observations_and_time_limits():
    from stable_baselines3.common.vec_env import VecEnv

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


@pytest.mark.slow  # about 10 s: a real PPO run
def test_tiny_ppo_run_writes_a_model_and_a_learning_curve(tmp_path, capsys):
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
        policy_kwargs={"net_arch": [32, 16]},  # not the default 64, 64: the benchmark reads it
    )
    assert path.is_file()
    from agents.benchmark.policies import load_ppo

    actor = load_ppo(path).policy.mlp_extractor.policy_net
    assert [layer.out_features for layer in actor if hasattr(layer, "out_features")] == [32, 16]
    curve = json.loads((tmp_path / "learning_curve.json").read_text())
    assert curve[-1]["steps"] >= 512 and 0.0 <= curve[-1]["success_rate"] <= 1.0
    result = evaluate_model(path, episodes=2)
    assert result["task"] == "avoid"  # the model's own task, not a default
    assert result["sensors"] == "ig500n"
    # The benchmark plays the same model through the same episode loop: the same numbers.
    from agents.benchmark import run_benchmark

    (row,) = run_benchmark(
        tasks=["avoid"],
        policies=[str(path)],
        techniques=["zhang2021"],
        episodes=2,
        workers=1,
        progress=False,
        print_table=False,
    )
    # The same row, steps matched in the benchmark's window (step F1 too).
    for key in (
        "success_rate",
        "spl",
        "attitude_rmse_deg",
        "mean_collisions",
        "step_f1",
        "heading_error_rmse_deg",
        "phantom_steps_per_min",
    ):
        assert row[key] == pytest.approx(result[key], nan_ok=True), key
    # Batched users play the model row by row: the same table as one episode at a time.
    kw = dict(
        tasks=["avoid"],
        policies=[str(path)],
        techniques=["zhang2021"],
        episodes=3,
        workers=1,
        progress=False,
        print_table=False,
    )
    assert run_benchmark(**kw, batch_size=2) == run_benchmark(**kw, batch_size=0)
    with pytest.raises(ValueError, match="trained on task 'avoid'"):
        run_benchmark(
            tasks=["approach"],
            policies=[str(path)],
            episodes=1,
            workers=1,
            progress=False,
            print_table=False,
        )
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
    # vrloco evaluate: a progress bar, the benchmark's table for the row, --json the whole row.
    from agents.cli import main

    capsys.readouterr()
    out_json = tmp_path / "eval.json"
    assert main(["evaluate", str(path), "--episodes", "2", "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "episodes" in out and "2/2" in out  # the progress bar, done
    assert "vrloco benchmark: outcomes (seeds 0..1)" in out and "walking in place" in out
    assert f"ppo:{path.name}" in out and '"success_rate"' not in out  # a table, not raw JSON
    assert f"wrote {out_json}" in out
    (saved,) = json.loads(out_json.read_text())["rows"]
    assert saved["policy"] == f"ppo:{path.name}" and saved["episodes"] == 2
    for key in ("success_rate", "spl", "step_f1", "mean_collisions"):
        assert saved[key] == pytest.approx(result[key]), key


@pytest.mark.slow  # about 10 s: a real PPO run
def test_tiny_runs_over_two_seeds_write_each_seed_and_their_mean(tmp_path):
    import zipfile

    from agents.learned.seeds import train_seeds

    kw = dict(steps=512, num_envs=4, eval_every=256, eval_episodes=2, n_steps=64, batch_size=128)
    paths = train_seeds("avoid", [0, 1], tmp_path / "two", **kw)
    assert paths == [tmp_path / "two" / f"seed_{s}" / "ppo_avoid_final.zip" for s in (0, 1)]
    assert all(p.is_file() for p in paths)
    for s in (0, 1):
        assert (tmp_path / "two" / f"seed_{s}" / "learning_curve.png").is_file()
    data = json.loads((tmp_path / "two" / "learning_curve.json").read_text())
    assert data["task"] == "avoid" and data["seeds"] == [0, 1]
    curves = [data["per_seed"][s] for s in ("0", "1")]
    steps = [c["steps"] for c in curves[0]]
    assert [m["steps"] for m in data["mean"]] == steps == [c["steps"] for c in curves[1]]
    for i, m in enumerate(data["mean"]):
        values = [curves[0][i]["mean_return"], curves[1][i]["mean_return"]]
        assert m["mean_return"] == pytest.approx(np.mean(values))
        assert m["mean_return_std"] == pytest.approx(np.std(values))
        assert 0.0 <= m["success_rate"] <= 1.0 and m["success_rate_std"] >= 0.0
    assert (tmp_path / "two" / "learning_curve.png").is_file()

    def policy(path):
        with zipfile.ZipFile(path) as z:
            return z.read("policy.pth")

    def without_wall_time(curve):
        return [{k: v for k, v in row.items() if k != "wall_s"} for row in curve]

    assert policy(paths[0]) != policy(paths[1])  # the seeds train different users
    # Seed 0 alone (one seed: today's single run, in this process) repeats the worker's run
    # bit for bit: the workers keep torch's thread count (fewer threads changed the last digits).
    (alone,) = train_seeds("avoid", [0], tmp_path / "one", progress=False, **kw)
    assert alone == tmp_path / "one" / "ppo_avoid_final.zip"
    assert not (tmp_path / "one" / "seed_0").exists()
    curve = json.loads((tmp_path / "one" / "learning_curve.json").read_text())
    assert without_wall_time(curve) == without_wall_time(curves[0])
    assert policy(alone) == policy(paths[0])
    with pytest.raises(ValueError, match="given more than once"):
        train_seeds("avoid", [1, 1], tmp_path / "bad", **kw)


NEEDS_RAY = "the Ray backend needs Ray: pip install 'vrloco[ray]'"
TINY = dict(steps=512, num_envs=4, eval_every=256, eval_episodes=2, n_steps=64, batch_size=128)


def _policy(path):
    import zipfile

    with zipfile.ZipFile(path) as z:
        return z.read("policy.pth")


def _without_wall_time(curve):
    return [{k: v for k, v in row.items() if k != "wall_s"} for row in curve]


@pytest.mark.slow
def test_seeds_on_ray_train_as_the_local_backend_and_a_failed_seed_is_named(tmp_path):
    import logging

    ray = pytest.importorskip("ray", reason=NEEDS_RAY)
    from agents.benchmark.backends import BackendError
    from agents.learned.seeds import train_seeds

    out = tmp_path / "ray"
    bad = 2**32  # numpy's seeding refuses it inside the worker, after the run has started
    ray.init(num_cpus=2, include_dashboard=False, logging_level=logging.WARNING)
    try:
        with pytest.raises(BackendError, match=r"1 of 3 seed runs failed on Ray") as err:
            train_seeds("avoid", [0, 1, bad], out, backend="ray", **TINY)
    finally:
        ray.shutdown()
    assert err.value.partial
    assert (
        f"  seed {bad}: ValueError: Seed must be between 0 and 2**32 - 1"
        in str(err.value).splitlines()
    )
    assert not (out / f"seed_{bad}").exists()
    for s in (0, 1):  # the finished seeds' files came back from the workers
        folder = out / f"seed_{s}"
        assert (folder / "ppo_avoid_final.zip").is_file() and (folder / "best_model.zip").is_file()
        assert any((folder / "checkpoints").glob("*.zip")) and any((folder / "tb").rglob("*"))
    data = json.loads((out / "learning_curve.json").read_text())
    assert data["seeds"] == [0, 1] and (out / "learning_curve.png").is_file()
    assert _policy(out / "seed_0" / "ppo_avoid_final.zip") != _policy(
        out / "seed_1" / "ppo_avoid_final.zip"
    )
    # A Ray task trains seed 0 exactly as this process does: torch's thread count is kept.
    (alone,) = train_seeds("avoid", [0], tmp_path / "one", progress=False, **TINY)
    assert _policy(alone) == _policy(out / "seed_0" / "ppo_avoid_final.zip")
    curve = json.loads((tmp_path / "one" / "learning_curve.json").read_text())
    assert _without_wall_time(curve) == _without_wall_time(data["per_seed"]["0"])


def test_seeds_on_an_unreachable_ray_address_are_named_at_once(tmp_path, capsys):
    import time

    pytest.importorskip("ray", reason=NEEDS_RAY)
    from agents.benchmark.backends import BackendError
    from agents.cli import main
    from agents.learned.seeds import train_seeds

    t0 = time.perf_counter()
    with pytest.raises(BackendError, match=r"cannot reach a Ray cluster at 127\.0\.0\.1:1"):
        train_seeds("avoid", [0, 1], tmp_path, backend="ray", address="127.0.0.1:1", **TINY)
    assert time.perf_counter() - t0 < 10.0
    assert not list(tmp_path.glob("seed_*"))
    assert (
        main(
            [
                "train",
                "--seeds",
                "0,1",
                "--backend",
                "ray",
                "--address",
                "127.0.0.1:1",
                "--steps",
                "1024",
                "--num-envs",
                "4",
                "--out",
                str(tmp_path),
            ]
        )
        == 1
    )
    err = capsys.readouterr().err
    assert err.startswith("vrloco train: cannot reach a Ray cluster at 127.0.0.1:1")
    assert "Traceback" not in err
    with pytest.raises(ValueError, match="backend must be 'local' or 'ray', got 'dask'"):
        train_seeds("avoid", [0, 1], tmp_path, backend="dask", **TINY)
    with pytest.raises(ValueError, match="needs backend 'ray'"):
        train_seeds("avoid", [0, 1], tmp_path, address="auto", **TINY)


def _kill_one_seed_task(stop, killed):
    """Kill (SIGKILL) the first Ray worker process found running a seed's training (its title
    is ``ray::_train_seed_task``), once; Linux's /proc."""
    import os
    import signal
    from pathlib import Path

    while not stop.is_set() and not killed:
        for proc in Path("/proc").glob("[0-9]*"):
            try:
                title = (proc / "cmdline").read_bytes()
            except OSError:
                continue
            if title.startswith(b"ray::_train_seed_task"):
                os.kill(int(proc.name), signal.SIGKILL)
                killed.append(int(proc.name))
                return
        stop.wait(0.2)


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="finds the worker in /proc")
def test_a_seed_whose_ray_worker_is_lost_is_trained_again(tmp_path):
    import logging
    import threading

    ray = pytest.importorskip("ray", reason=NEEDS_RAY)
    from agents.learned.seeds import train_seeds

    stop, killed = threading.Event(), []
    killer = threading.Thread(target=_kill_one_seed_task, args=(stop, killed))
    ray.init(num_cpus=2, include_dashboard=False, logging_level=logging.WARNING)
    try:
        killer.start()
        (path,) = train_seeds("avoid", [0], tmp_path / "ray", backend="ray", **TINY)
    finally:
        stop.set()
        killer.join()
        ray.shutdown()
    assert killed  # a worker did die mid-run, and the task ran again to the end
    (alone,) = train_seeds("avoid", [0], tmp_path / "one", progress=False, **TINY)
    assert _policy(path) == _policy(alone)


def test_evaluate_names_a_file_that_is_not_a_model_in_one_line(tmp_path, capsys):
    import zipfile

    from agents.cli import main

    (tmp_path / "junk.zip").write_bytes(b"not a zip file" * 8)
    with zipfile.ZipFile(tmp_path / "notes.zip", "w") as z:
        z.writestr("notes.txt", "not a model")
    with zipfile.ZipFile(tmp_path / "broken.zip", "w") as z:
        z.writestr("data", "{not json")
        z.writestr("policy.pth", b"")
    (tmp_path / "model.zip.zip").write_bytes(b"")
    cases = {
        "junk.zip": "is not a saved model: not a zip file",
        "notes.zip": "is not a saved stable-baselines3 model: the zip holds no data and no "
        "policy.pth",
        "broken.zip": "stable-baselines3 cannot load it as a PPO model (JSONDecodeError",
        "missing.zip": "no such model file",
        "model.zip": "no such model file; did you mean",
    }
    for name, says in cases.items():
        path = tmp_path / name
        assert main(["evaluate", str(path), "--episodes", "1"]) == 2, name
        err = capsys.readouterr().err
        assert err.startswith(f"vrloco evaluate: {str(path)!r}") and says in err, err
        assert err.count("\n") == 1 and "Traceback" not in err
        with pytest.raises(ValueError, match="model"):
            evaluate_model(path, episodes=1, progress=False)


_WRONG_WIDTH = '''
import numpy as np


class Narrow:
    """A batched user whose act() gives 3 numbers per user instead of 5."""

    batched = True

    def __init__(self, env):
        pass

    def reset(self, rng=None, rows=None):
        pass

    def act(self, obs):
        return np.zeros((np.shape(obs)[0], 3), np.float32)


class Short:
    """A single-env user whose act() gives one action too few."""

    def __init__(self, env):
        pass

    def reset(self, rng=None, rows=None):
        pass

    def act(self, obs):
        return np.zeros(4, np.float32)


class OneRow:
    """A batched user that answers a batch with one row."""

    batched = True

    def __init__(self, env):
        pass

    def reset(self, rng=None, rows=None):
        pass

    def act(self, obs):
        return np.zeros((1, 5), np.float32)
'''


def test_a_policy_returning_actions_of_the_wrong_shape_is_named(tmp_path):
    from agents.benchmark.episodes import run_batched, run_cell_episode
    from agents.benchmark.grid import Cell

    plugin = tmp_path / "bad_users.py"
    plugin.write_text(_WRONG_WIDTH)
    narrow = Cell("avoid", f"{plugin}:Narrow")
    with pytest.raises(
        ValueError,
        match=rf"policy '{plugin}:Narrow' returned actions of shape "
        r"\(2, 3\) from act\(\); expected \(2, 5\) \(one row of "
        r"5 per user\): \[walk, turn, ",
    ):
        run_batched([(narrow, 0, False), (narrow, 1, False)], batch_size=2)
    with pytest.raises(
        ValueError,
        match=rf"policy '{plugin}:OneRow' returned actions of shape "
        r"\(1, 5\) from act\(\); expected \(3, 5\)",
    ):
        one = Cell("avoid", f"{plugin}:OneRow")
        run_batched([(one, s, False) for s in range(3)], batch_size=3)
    with pytest.raises(
        ValueError,
        match=rf"policy '{plugin}:Short' returned actions of shape "
        r"\(4,\) from act\(\); expected \(5,\)",
    ):
        run_cell_episode(Cell("avoid", f"{plugin}:Short"), 0)


def test_a_model_predicting_the_wrong_shape_is_named():
    from agents.learned.evaluate import run_policy_episodes

    class Wide:
        def predict(self, obs, deterministic=True):
            return np.zeros((len(obs), 6), np.float32), None

    with pytest.raises(
        ValueError,
        match=r"model Wide returned actions of shape \(2, 6\) from "
        r"predict\(\); expected \(2, 5\)",
    ):
        run_policy_episodes(Wide(), VRLocoVectorEnv(2, task="avoid"), seed=0)


def test_an_evaluation_that_drops_finished_users_scores_as_one_that_plays_them_on(monkeypatch):
    """The training's evaluation drops a user whose episode has ended (from a copy of the env)
    and still gives, to the last bit, what playing every user to the batch's end gives: a PPO
    policy on frame-stacked, field-read users whose episodes end at their first collision, at
    different steps."""
    import torch
    from stable_baselines3 import PPO

    from agents.learned.evaluate import run_policy_episodes
    from agents.learned.models import ModelFields
    from vrloco_env.config import EnvConfig
    from vrloco_env.wrappers import FrameStack

    inner = VRLocoVectorEnv(12, task="avoid", config=EnvConfig(terminate_on_collision=True))
    size = inner.single_observation_space.shape[0]
    env = FrameStack(ModelFields(inner, np.arange(size)), 2)
    model = PPO("MlpPolicy", SB3VecEnv(env), seed=0, n_steps=64)
    with torch.no_grad():
        model.policy.action_net.bias[0] = 1.0  # walk
    dropped = []
    take = VRLocoVectorEnv.take_users
    monkeypatch.setattr(
        VRLocoVectorEnv,
        "take_users",
        lambda self, rows: (dropped.append(len(rows)), take(self, rows)),
    )

    class PlaysOn:  # the same env, saying it cannot drop users
        can_take_users = False

        def __getattr__(self, name):
            return getattr(env, name)

    dropping = run_policy_episodes(model, env, seed=5)
    assert dropped and min(dropped) < 12 and env.num_envs == 12  # dropped from a copy
    assert run_policy_episodes(model, PlaysOn(), seed=5) == dropping
    assert 0.0 < dropping["collision_rate"]


def _stacked(history):
    """Each user's frames side by side, oldest first (the reference stacking)."""
    return np.stack([np.concatenate(frames) for frames in history])


def test_frame_stack_gives_each_user_its_last_k_observations_in_the_batch_layout():
    from vrloco_env.wrappers import FrameStack

    k, n_users = 3, 2
    raw = VRLocoVectorEnv(n_users, task="avoid", max_episode_steps=4)
    env = FrameStack(VRLocoVectorEnv(n_users, task="avoid", max_episode_steps=4), k)
    size = raw.single_observation_space.shape[0]
    assert env.single_observation_space.shape == (k * size,)
    assert env.observation_space.shape == (n_users, k * size)
    first, _ = raw.reset(seed=3)
    obs, _ = env.reset(seed=3)
    history = [[first[i]] * k for i in range(n_users)]  # an episode starts repeated
    np.testing.assert_array_equal(obs, _stacked(history))
    rng = np.random.default_rng(0)
    ended_seen = 0
    for _ in range(10):  # two and a half episodes of 4 steps
        action = rng.uniform(-1, 1, (n_users, 5)).astype(np.float32)
        new, _, term, trunc, info_raw = raw.step(action)
        obs, _, term2, trunc2, info = env.step(action)
        np.testing.assert_array_equal(term | trunc, term2 | trunc2)
        for i in range(n_users):
            if term[i] or trunc[i]:  # the episode's last k frames, then the new one's first
                last = [*history[i][1:], info_raw["final_obs"][i]]
                np.testing.assert_array_equal(info["final_obs"][i], np.concatenate(last))
                history[i] = [new[i]] * k
                ended_seen += 1
            else:
                history[i] = [*history[i][1:], new[i]]
        np.testing.assert_array_equal(obs, _stacked(history))
    assert ended_seen == 2 * n_users


def test_frame_stack_restarts_masked_users_and_drops_users_with_the_env():
    from gymnasium.vector import AutoresetMode

    from vrloco_env.wrappers import FrameStack

    k = 2
    kw = dict(task="avoid", autoreset_mode=AutoresetMode.DISABLED)
    raw = VRLocoVectorEnv(3, **kw)
    env = FrameStack(VRLocoVectorEnv(3, **kw), k)
    first, _ = raw.reset(seed=0)
    env.reset(seed=0)
    history = [[first[i]] * k for i in range(3)]
    zeros = np.zeros((3, 5), np.float32)
    new, *_ = raw.step(zeros)
    obs, *_ = env.step(zeros)
    history = [[*h[1:], new[i]] for i, h in enumerate(history)]
    np.testing.assert_array_equal(obs, _stacked(history))
    mask = np.array([False, True, False])
    seeds = [None, 7, None]
    new, _ = raw.reset(seed=seeds, options={"reset_mask": mask})
    obs, _ = env.reset(seed=seeds, options={"reset_mask": mask})
    history[1] = [new[1]] * k  # only the masked user starts again
    np.testing.assert_array_equal(obs, _stacked(history))
    assert env.can_take_users
    raw.take_users([2, 0])
    env.take_users([2, 0])
    history = [history[2], history[0]]
    new, *_ = raw.step(zeros[:2])
    obs, *_ = env.step(zeros[:2])
    history = [[*h[1:], new[i]] for i, h in enumerate(history)]
    assert env.observation_space.shape == (2, k * raw.single_observation_space.shape[0])
    np.testing.assert_array_equal(obs, _stacked(history))


def test_importing_the_trainer_starts_torch_after_the_passive_thread_policy():
    """torch's OpenMP runtime reads OMP_WAIT_POLICY when torch loads: agents.learned imports
    the kernels (which set it) first, else torch's threads spin on the env's cores."""
    import os
    import subprocess

    code = (
        "import os, sys, agents.learned; assert 'torch' not in sys.modules; "
        "from agents.learned import train_ppo; m = list(sys.modules); "
        "print(m.index('estimators.kernels.batch') < m.index('torch'), "
        "os.environ['OMP_WAIT_POLICY'], agents.learned.threads._TORCH_SPINS)"
    )
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert out.stdout.split() == ["True", "PASSIVE", "False"]
    # torch imported first (without the policy): the trainer knows, and warns.
    code = "import torch, agents.learned; print(agents.learned.threads._TORCH_SPINS)"
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert out.stdout.split() == ["True"]


def test_training_runs_on_one_torch_thread_and_gives_the_count_back():
    """Rollouts and updates run on one torch thread; torch has its own count again after
    training, and after an interrupted run."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback

    from agents.learned.train import OneTorchThread, make_model

    seen = []

    class Count(BaseCallback):
        def _on_step(self) -> bool:
            seen.append(torch.get_num_threads())
            return True

        def _on_rollout_end(self) -> None:
            seen.append(torch.get_num_threads())

    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        venv = SB3VecEnv(VRLocoVectorEnv(2, task="approach"), seed=0)
        model = make_model(venv, seed=0, n_steps=8, batch_size=16, n_epochs=1)
        threads = OneTorchThread()
        model.learn(32, callback=[threads, Count()])
        assert seen and set(seen) == {1}
        assert torch.get_num_threads() == 2
        torch.set_num_threads(1)  # as an interrupted run leaves it
        threads.restore()
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)


def test_an_unknown_technique_population_or_condition_is_one_error_naming_the_valid_ones(
    tmp_path, capsys
):
    from agents.cli import main

    cases = {
        "technique": "technique='nope': unknown; valid names: zhang2021, zhang2021_consumer",
        "population": "population='nope': unknown; valid names: idealised, human, typical",
        "condition": "condition='nope': unknown; valid names: lab, beside_metal",
    }
    for name, says in cases.items():
        out = tmp_path / name
        with pytest.raises(ValueError, match=says.replace("(", r"\(")):
            train_ppo("avoid", steps=512, num_envs=4, out_dir=out, **{name: "nope"})
        assert not out.exists()  # refused before anything was written
        assert (
            main(
                [
                    "train",
                    f"--{name}",
                    "nope",
                    "--steps",
                    "1024",
                    "--num-envs",
                    "4",
                    "--out",
                    str(out),
                ]
            )
            == 2
        )
        err = capsys.readouterr().err
        assert err.startswith(f"vrloco train: {says}") and err.count("\n") == 1, err
        assert not (out / "tb").exists()
    with pytest.raises(ValueError, match=r"frame_stack=0: must be an integer in \[1, 64\]"):
        train_ppo("avoid", steps=512, num_envs=4, out_dir=tmp_path / "fs", frame_stack=0)
    assert main(["train", "--backend", "rllib", "--recurrent", "--out", str(tmp_path)]) == 2
    assert "--frame-stack and --recurrent need --backend local or ray" in capsys.readouterr().err


def test_train_passes_the_cell_and_the_policy_options_on(tmp_path, monkeypatch, capsys):
    import agents.learned.seeds
    from agents.cli import main

    seen = {}

    def fake(task, seeds, out_dir, **kwargs):
        seen.update(kwargs, task=task, seeds=seeds)
        return [out_dir / "ppo_final.zip"]

    monkeypatch.setattr(agents.learned.seeds, "train_seeds", fake)
    assert (
        main(
            [
                "train",
                "--task",
                "reach",
                "--technique",
                "madgwick",
                "--population",
                "nodders",
                "--condition",
                "beside_metal",
                "--frame-stack",
                "4",
                "--recurrent",
                "--reward",
                "collision=10,time=0.02",
                "--rollout-steps",
                "64",
                "--learning-rate",
                "1e-4",
                "--residual-on",
                "goal_seeker",
                "--net-arch",
                "256,128",
                "--out",
                str(tmp_path),
            ]
        )
        == 0
    )
    assert seen["task"] == "reach" and seen["seeds"] == [0] and seen["n_steps"] == 64
    assert seen["policy_kwargs"] == {"net_arch": [256, 128]}
    assert seen["learning_rate"] == 1e-4 and seen["residual_on"] == "goal_seeker"
    assert seen["reward"] == RewardConfig(collision=10.0, time=0.02)  # the rest: defaults
    assert {
        k: seen[k]
        for k in (
            "technique",
            "population",
            "condition",
            "frame_stack",
            "recurrent",
            "sensor_preset",
        )
    } == {
        "technique": "madgwick",
        "population": "nodders",
        "condition": "beside_metal",
        "frame_stack": 4,
        "recurrent": True,
        "sensor_preset": None,
    }


@pytest.mark.slow  # about 10 s: a real PPO run
def test_a_model_trained_on_a_cell_carries_it_and_is_evaluated_on_it(tmp_path, capsys):
    import gymnasium as gym

    from agents.benchmark.conditions import CONDITIONS, get_condition
    from agents.benchmark.episodes import run_episode
    from agents.benchmark.metrics import summarize
    from agents.benchmark.policies import LearnedPolicy, load_ppo
    from agents.cli import main
    from agents.learned.models import env_settings
    from vrloco_env.tasks import env_id
    from vrloco_env.techniques import TECHNIQUES

    cell = {
        "task": "approach",
        "technique": "madgwick",
        "population": "typical",
        "condition": "beside_metal",
    }
    path = train_ppo(
        steps=256,
        num_envs=4,
        out_dir=tmp_path,
        eval_every=256,
        eval_episodes=2,
        progress=False,
        n_steps=64,
        batch_size=128,
        **cell,
    )
    model = load_ppo(path)
    assert model.vrloco_cell == cell
    assert model.vrloco_policy == {"frame_stack": 1, "recurrent": False, "residual_on": None}
    settings = model.vrloco_env
    assert settings["estimators"] == TECHNIQUES["madgwick"].estimators
    metal = CONDITIONS["beside_metal"].magnetic_disturbances
    assert settings["sensors"].magnetic_disturbances == metal
    assert settings["config"].population == "typical"
    # The typical population's head turns on the torso: one observation field more; a
    # population whose head does not turn leaves the observation as it is.
    plain = VRLocoVectorEnv(1).single_observation_space.shape[0]
    assert model.observation_space.shape == (plain + 1,)
    for population, extra in (("idealised", 0), ("human", 0), ("nodders", 1)):
        env = VRLocoVectorEnv(1, **env_settings("approach", population=population))
        assert env.single_observation_space.shape == (plain + extra,), population

    row = evaluate_model(path, episodes=2, progress=False)
    assert {k: row[k] for k in cell} == cell and row["trained_on"] is None
    # The episodes of the cell's own env, as the benchmark builds it.
    env = gym.make(
        env_id("approach"),
        technique="madgwick",
        population="typical",
        sensors=get_condition("beside_metal").sensors(),
    )
    policy = LearnedPolicy(path, env)
    played = [run_episode(env, policy, s)[0] for s in (0, 1)]
    ref = summarize(played)
    for key in ("success_rate", "spl", "attitude_rmse_deg", "heading_error_rmse_deg"):
        assert row[key] == pytest.approx(ref[key], nan_ok=True), key
    # Repeating the model's own cell is no mismatch; another cell is refused, naming it.
    assert evaluate_model(path, episodes=2, progress=False, **cell) == row
    with pytest.raises(
        ValueError,
        match=r"technique='zhang2021' \(trained: 'madgwick'\), "
        r"condition='lab' \(trained: 'beside_metal'\) "
        r"contradicts the model",
    ):
        evaluate_model(path, episodes=1, technique="zhang2021", condition="lab")
    with pytest.raises(ValueError, match="condition='nope': unknown; valid names: lab"):
        evaluate_model(path, episodes=1, condition="nope")
    capsys.readouterr()
    assert main(["evaluate", str(path), "--episodes", "1", "--condition", "lab"]) == 2
    err = capsys.readouterr().err
    assert (
        err.startswith(
            "vrloco evaluate: condition='lab' (trained: 'beside_metal') contradicts the model"
        )
        and "--allow-mismatch" in err
    )
    assert err.count("\n") == 1
    # --allow-mismatch plays the cell asked for: the model's env, the condition replaced.
    assert (
        main(["evaluate", str(path), "--episodes", "2", "--condition", "lab", "--allow-mismatch"])
        == 0
    )
    out = capsys.readouterr().out
    assert (
        "cell: task approach, technique madgwick, population typical, condition lab; the "
        "model was trained on task approach, technique madgwick, population typical, "
        "condition beside_metal, sensors ig500n"
    ) in out
    moved = evaluate_model(path, episodes=2, progress=False, condition="lab", allow_mismatch=True)
    assert moved["condition"] == "lab" and moved["trained_on"]["condition"] == "beside_metal"
    env = gym.make(env_id("approach"), technique="madgwick", population="typical")
    played = [run_episode(env, LearnedPolicy(path, env), s)[0] for s in (0, 1)]
    assert moved["attitude_rmse_deg"] == pytest.approx(summarize(played)["attitude_rmse_deg"])
    assert moved["attitude_rmse_deg"] != pytest.approx(row["attitude_rmse_deg"])


def _trained_actions(model, task, seed, steps, frame_stack):
    """The model's deterministic actions in the vector env it was trained in (one user, seeded
    ``seed``, autoreset), as the training loop feeds it (the wrapper's frames, the LSTM state
    carried and restarted at each episode)."""
    from agents.learned.models import is_recurrent
    from agents.learned.train import _wrap

    env = _wrap(VRLocoVectorEnv(1, task=task, max_episode_steps=6), frame_stack)
    obs, _ = env.reset(seed=seed)
    state, start, actions = None, np.ones(1, bool), []
    for _ in range(steps):
        if is_recurrent(model):
            action, state = model.predict(obs, state=state, episode_start=start, deterministic=True)
        else:
            action, _ = model.predict(obs, deterministic=True)
        actions.append(action[0])
        obs, _, term, trunc, _ = env.step(action)
        start = term | trunc
    return np.array(actions)


def _played_actions(path, task, seed, steps):
    """LearnedPolicy's actions in the single env seeded ``seed`` (reset again, unseeded, after
    each episode, as a vector env's user is)."""
    import gymnasium as gym

    from agents.benchmark.policies import LearnedPolicy
    from vrloco_env.tasks import env_id

    env = gym.make(env_id(task), max_episode_steps=6)
    policy = LearnedPolicy(path, env)
    obs, _ = env.reset(seed=seed)
    policy.reset(np.random.default_rng(0))
    actions = []
    for _ in range(steps):
        action = policy.act(obs)
        actions.append(action)
        obs, _, term, trunc, _ = env.step(action)
        if term or trunc:
            obs, _ = env.reset()
            policy.reset(np.random.default_rng(0))
    return np.array(actions)


@pytest.mark.slow  # about 30 s: two real PPO runs
def test_frame_stacked_and_recurrent_models_play_as_they_were_trained(tmp_path):
    import gymnasium as gym

    from agents.benchmark import run_benchmark
    from agents.benchmark.policies import LearnedPolicy, load_ppo
    from vrloco_env.tasks import env_id

    tiny = dict(
        steps=256,
        num_envs=4,
        eval_every=256,
        eval_episodes=2,
        progress=False,
        n_steps=64,
        batch_size=128,
    )
    stacked = train_ppo("avoid", out_dir=tmp_path / "stack", frame_stack=3, **tiny)
    recurrent = train_ppo("avoid", out_dir=tmp_path / "lstm", recurrent=True, **tiny)
    for path, frames, lstm in ((stacked, 3, False), (recurrent, 1, True)):
        model = load_ppo(path)
        policy = {"frame_stack": frames, "recurrent": lstm, "residual_on": None}
        assert model.vrloco_policy == policy
        assert type(model).__name__ == ("RecurrentPPO" if lstm else "PPO")
        # The benchmark's policy acts as the model did in training: 20 steps, 3 episodes.
        want = _trained_actions(model, "avoid", 11, 20, frames)
        np.testing.assert_array_equal(_played_actions(path, "avoid", 11, 20), want)
        # Batched users keep their own frames and LSTM states: the same table as one at a time.
        kw = dict(
            tasks=["avoid"],
            policies=[str(path)],
            techniques=["zhang2021"],
            episodes=3,
            workers=1,
            progress=False,
            print_table=False,
        )
        assert run_benchmark(**kw, batch_size=2) == run_benchmark(**kw, batch_size=0)
        row = evaluate_model(path, episodes=1, progress=False)
        assert row["task"] == "avoid" and 0.0 <= row["success_rate"] <= 1.0
    # A stacked model in an env with a field it was not trained on (a population's
    # head_on_torso) stacks the fields it knows: it acts as on the observation without it.
    env = gym.make(env_id("avoid"), population="typical")
    spec = env.unwrapped.observation_spec
    obs, _ = env.reset(seed=5)
    head = spec.offset("head_on_torso")
    policy = LearnedPolicy(stacked, env)
    policy.reset()
    bare = LearnedPolicy(stacked, gym.make(env_id("avoid")))
    bare.reset()
    np.testing.assert_array_equal(policy.act(obs), bare.act(np.delete(obs, head)))


def test_every_technique_gives_the_same_observation_and_action_spaces():
    """A user trained under one technique can play (or be fine-tuned on) any other: the
    technique changes what the sensors and estimators do, never the spaces."""
    from agents.learned.models import env_settings
    from vrloco_env.techniques import TECHNIQUES

    first = None
    for name in TECHNIQUES:
        env = VRLocoVectorEnv(2, **env_settings("approach", technique=name))
        spaces = (env.single_observation_space, env.single_action_space)
        env.close()
        first = first or spaces
        assert spaces == first, name


@pytest.mark.slow  # about 10 s: real PPO runs
@pytest.mark.parametrize("technique", ["head_tilt", "look_down_to_move", "hand_steering"])
def test_a_learned_user_trains_on_each_hands_free_technique(tmp_path, technique):
    path = train_ppo(
        "approach",
        steps=256,
        num_envs=4,
        out_dir=tmp_path,
        eval_every=256,
        eval_episodes=2,
        progress=False,
        n_steps=64,
        batch_size=128,
        technique=technique,
    )
    row = evaluate_model(path, episodes=1, progress=False)
    assert row["technique"] == technique and row["trained_on"] is None


def test_runs_compare_at_a_step_and_over_their_last_evaluations(capsys, tmp_path):
    from agents.learned.curves import compare_runs, main

    def curve(successes):
        return [
            {"steps": 100 * i + 32, "success_rate": s, "collision_rate": 1 - s}
            for i, s in enumerate(successes)
        ]

    runs = {
        "fast": {"command": "vrloco train ...", "curve": curve([0, 0.5, 1, 1, 1, 1, 1, 1])},
        "slow": {"command": "vrloco train ...", "curve": curve([0, 0, 0, 0.5, 1])},
    }
    fast, slow = compare_runs(runs, at=230, last=2)
    # the evaluation nearest 230 steps is the one at 232; the two up to it: 132 and 232
    assert fast["at"]["steps"] == 232 and fast["success_up_to_at"] == pytest.approx(0.75)
    assert slow["at"]["steps"] == 232 and slow["success_up_to_at"] == 0.0
    assert fast["success_last"] == 1.0 and slow["success_last"] == pytest.approx(0.75)
    assert slow["collision_last"] == pytest.approx(0.25) and slow["steps"] == 432
    assert compare_runs(runs, at=640)[1]["at"] is None  # "slow" ended at 432 steps
    assert compare_runs(runs, at=640)[0]["at"]["steps"] == 632
    with pytest.raises(ValueError, match="'empty' has no learning curve"):
        compare_runs({"empty": {"command": "", "curve": []}}, at=100)
    path = tmp_path / "runs.json"
    path.write_text(json.dumps({"runs": runs}))
    main([str(path), "--at", "230"])
    out = capsys.readouterr().out
    assert "fast" in out and "slow" in out and "development" in out
