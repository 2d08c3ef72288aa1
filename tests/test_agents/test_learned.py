"""The stable-baselines3 adapter and a tiny PPO run (the learning curve itself is a benchmark)."""

import json
import sys

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
    # The same row, steps matched in the benchmark's window (step F1 too).
    for key in ("success_rate", "spl", "attitude_rmse_deg", "mean_collisions", "step_f1",
                "heading_error_rmse_deg", "phantom_steps_per_min"):  # fmt: skip
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

    from agents.learned import train_seeds

    kw = dict(steps=512, num_envs=4, eval_every=256, eval_episodes=2, n_steps=64,
              batch_size=128)  # fmt: skip
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
    from agents.backends import BackendError
    from agents.learned import train_seeds

    out = tmp_path / "ray"
    bad = 2**32  # numpy's seeding refuses it inside the worker, after the run has started
    ray.init(num_cpus=2, include_dashboard=False, logging_level=logging.WARNING)
    try:
        with pytest.raises(BackendError, match=r"1 of 3 seed runs failed on Ray") as err:
            train_seeds("avoid", [0, 1, bad], out, backend="ray", **TINY)
    finally:
        ray.shutdown()
    assert err.value.partial
    assert (f"  seed {bad}: ValueError: Seed must be between 0 and 2**32 - 1"
            in str(err.value).splitlines())  # fmt: skip
    assert not (out / f"seed_{bad}").exists()
    for s in (0, 1):  # the finished seeds' files came back from the workers
        folder = out / f"seed_{s}"
        assert (folder / "ppo_avoid_final.zip").is_file() and (folder / "best_model.zip").is_file()
        assert any((folder / "checkpoints").glob("*.zip")) and any((folder / "tb").rglob("*"))
    data = json.loads((out / "learning_curve.json").read_text())
    assert data["seeds"] == [0, 1] and (out / "learning_curve.png").is_file()
    assert _policy(out / "seed_0" / "ppo_avoid_final.zip") != _policy(
        out / "seed_1" / "ppo_avoid_final.zip")
    # A Ray task trains seed 0 exactly as this process does: torch's thread count is kept.
    (alone,) = train_seeds("avoid", [0], tmp_path / "one", progress=False, **TINY)
    assert _policy(alone) == _policy(out / "seed_0" / "ppo_avoid_final.zip")
    curve = json.loads((tmp_path / "one" / "learning_curve.json").read_text())
    assert _without_wall_time(curve) == _without_wall_time(data["per_seed"]["0"])


def test_seeds_on_an_unreachable_ray_address_are_named_at_once(tmp_path, capsys):
    import time

    pytest.importorskip("ray", reason=NEEDS_RAY)
    from agents.backends import BackendError
    from agents.cli import main
    from agents.learned import train_seeds

    t0 = time.perf_counter()
    with pytest.raises(BackendError, match=r"cannot reach a Ray cluster at 127\.0\.0\.1:1"):
        train_seeds("avoid", [0, 1], tmp_path, backend="ray", address="127.0.0.1:1", **TINY)
    assert time.perf_counter() - t0 < 10.0
    assert not list(tmp_path.glob("seed_*"))
    assert main(["train", "--seeds", "0,1", "--backend", "ray", "--address", "127.0.0.1:1",
                 "--steps", "1024", "--num-envs", "4", "--out", str(tmp_path)]) == 1  # fmt: skip
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
    from agents.learned import train_seeds

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
    from agents.episodes import run_batched, run_cell_episode
    from agents.grid import Cell

    plugin = tmp_path / "bad_users.py"
    plugin.write_text(_WRONG_WIDTH)
    narrow = Cell("avoid", f"{plugin}:Narrow")
    with pytest.raises(ValueError, match=rf"policy '{plugin}:Narrow' returned actions of shape "
                                         r"\(2, 3\) from act\(\); expected \(2, 5\) \(one row of "
                                         r"5 per user\): \[walk, turn, "):  # fmt: skip
        run_batched([(narrow, 0, False), (narrow, 1, False)], batch_size=2)
    with pytest.raises(ValueError, match=rf"policy '{plugin}:OneRow' returned actions of shape "
                                         r"\(1, 5\) from act\(\); expected \(3, 5\)"):  # fmt: skip
        one = Cell("avoid", f"{plugin}:OneRow")
        run_batched([(one, s, False) for s in range(3)], batch_size=3)
    with pytest.raises(ValueError, match=rf"policy '{plugin}:Short' returned actions of shape "
                                         r"\(4,\) from act\(\); expected \(5,\)"):  # fmt: skip
        run_cell_episode(Cell("avoid", f"{plugin}:Short"), 0)


def test_a_model_predicting_the_wrong_shape_is_named():
    from agents.learned import run_policy_episodes

    class Wide:
        def predict(self, obs, deterministic=True):
            return np.zeros((len(obs), 6), np.float32), None

    with pytest.raises(ValueError, match=r"model Wide returned actions of shape \(2, 6\) from "
                                         r"predict\(\); expected \(2, 5\)"):  # fmt: skip
        run_policy_episodes(Wide(), VRLocoVectorEnv(2, task="avoid"), seed=0)
