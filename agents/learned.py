"""Learned simulated users: stable-baselines3 PPO on the native vector env.

``vrloco train --task approach --steps 2000000`` trains PPO on
:class:`~vrloco_env.vector.VRLocoVectorEnv` (all users batched in one process), with a progress
bar, TensorBoard logs, periodic checkpoints and an evaluation callback on separately seeded
episodes; ``vrloco evaluate MODEL`` runs a trained policy through the benchmark's metrics.
``vrloco train --seeds 0,1,2`` (:func:`train_seeds`) trains one run per seed in parallel worker
processes (``--backend ray``: as Ray tasks on a Ray cluster) and draws their curves together,
with the mean and the spread over the seeds. RLlib's PPO is in :mod:`agents.rllib`.

A run trains on one benchmark cell: a task, a technique (:mod:`vrloco_env.techniques`), a user
population (:mod:`vrloco_env.user.population`, its head behaviour in the env) and a physical-room
condition (:mod:`agents.benchmark.conditions`); the cell is saved with the model
(``model.vrloco_cell``) beside the env's settings (``model.vrloco_env``), and so is how the policy
sees the env (``model.vrloco_policy``: ``frame_stack``, the last k observations side by side through
:class:`~vrloco_env.wrappers.FrameStack`, and ``recurrent``, sb3-contrib's ``RecurrentPPO`` with
an LSTM policy), so that :func:`evaluate_model` and the benchmark
(:class:`agents.benchmark.policies.LearnedPolicy`) play it on its own cell, the way it was trained.

Speed. The env's compiled kernels and torch both run OpenMP thread pools on the same cores.
This module imports :mod:`estimators.kernels` before torch, so that torch's OpenMP runtime
starts with the passive wait policy that module sets (``OMP_WAIT_POLICY=PASSIVE``: idle threads
sleep instead of spinning on the cores the other pool needs), and PPO collects its rollouts
with one torch thread (:class:`RolloutThreads`: the forward pass of one step's users is too
small to share out), its update with torch's own count. Neither changes a number PPO computes:
``benchmarks/bench_training.py`` times the loop against the default settings and checks that
both train the same weights. A process that imported torch before this module (without
``OMP_WAIT_POLICY`` set) keeps torch's spinning threads; :func:`train_ppo` warns.

:class:`SB3VecEnv` adapts the Gymnasium vector env to stable-baselines3's ``VecEnv`` interface.
Both autoreset in the same step, so the adapter only reshapes: the finished episode's last
observation goes to ``infos[i]["terminal_observation"]`` and a time-limit end sets
``infos[i]["TimeLimit.truncated"]``, which PPO uses to bootstrap the value of truncated episodes.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

#: torch's OpenMP runtime started before ``OMP_WAIT_POLICY`` was set (see the module docstring).
_TORCH_SPINS = "torch" in sys.modules and "OMP_WAIT_POLICY" not in os.environ

import estimators.kernels  # noqa: E402, F401  (sets OMP_WAIT_POLICY before torch starts)

# isort: split
from stable_baselines3.common.callbacks import BaseCallback  # noqa: E402
from stable_baselines3.common.vec_env.base_vec_env import VecEnv  # noqa: E402

from vrloco_env.vector import VRLocoVectorEnv  # noqa: E402

__all__ = ["CELL_KEYS", "RolloutThreads", "SB3VecEnv", "env_settings", "evaluate_model",
           "make_model", "model_cell", "model_env_settings", "model_policy", "train_ppo",
           "train_seeds"]  # fmt: skip

#: The names of a training cell, as :attr:`model.vrloco_cell <train_ppo>` stores them.
CELL_KEYS = ("task", "technique", "population", "condition")

#: Reported per-step keys kept in the SB3 infos (episode metrics for the callbacks).
_INFO_KEYS = ("is_success", "collisions", "distance_to_goal")


class SB3VecEnv(VecEnv):
    """stable-baselines3 view of a :class:`~vrloco_env.vector.VRLocoVectorEnv`."""

    def __init__(self, env: VRLocoVectorEnv, seed: int | None = None) -> None:
        self.env = env
        super().__init__(env.num_envs, env.single_observation_space, env.single_action_space)
        self._seed = seed
        self._actions: np.ndarray | None = None
        self._returns = np.zeros(env.num_envs)
        self._lengths = np.zeros(env.num_envs, dtype=np.int64)

    def reset(self) -> np.ndarray:
        seed = self._seed
        self._seed = None  # seed only the first reset; later resets continue the streams
        obs, _ = self.env.reset(seed=seed)
        self._returns[:] = 0.0
        self._lengths[:] = 0
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, dtype=np.float32)

    def step_wait(self):
        assert self._actions is not None, "step_async must come before step_wait"
        obs, reward, terminated, truncated, info = self.env.step(self._actions)
        done = terminated | truncated
        self._returns += reward
        self._lengths += 1
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for i in np.flatnonzero(done):  # only the finished episodes carry an info dict
            infos[i] = {
                "terminal_observation": info["final_obs"][i],
                "TimeLimit.truncated": bool(truncated[i] and not terminated[i]),
                "episode": {"r": float(self._returns[i]), "l": int(self._lengths[i])},
                **{k: info[k][i].item() for k in _INFO_KEYS},
            }
            self._returns[i] = 0.0
            self._lengths[i] = 0
        return obs, reward.astype(np.float32), done, infos

    def close(self) -> None:
        self.env.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(self.env, attr_name)] * len(self._get_indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self.env, attr_name, value)

    def env_method(self, method_name: str, *args, indices=None, **kwargs) -> list[Any]:
        return [getattr(self.env, method_name)(*args, **kwargs)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(self._get_indices(indices))

    def seed(self, seed: int | None = None):
        self._seed = seed
        return [seed]

    def get_images(self):
        raise NotImplementedError("render a single env (gym.make) for pictures")


def defaults_ppo() -> dict[str, Any]:
    """PPO's settings for vrloco train (stable-baselines3 keywords)."""
    return {
        "n_steps": 256,
        "batch_size": 2048,
        "n_epochs": 5,
        "gamma": 0.99,
        "gae_lambda": 0.95,
        "learning_rate": 3e-4,
        "ent_coef": 0.0,
    }


def rollout_steps(steps: int, n_steps: int, num_envs: int) -> int:
    """``steps`` rounded up to whole PPO rollouts of ``n_steps x num_envs`` (what PPO trains
    anyway); fewer steps than one rollout is an error, not a silent rollout."""
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ValueError(f"steps={steps!r}: must be an integer >= 1")
    if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
        raise ValueError(f"num_envs={num_envs!r}: must be an integer >= 1")
    rollout = n_steps * num_envs
    if steps < rollout:
        raise ValueError(
            f"steps={steps:,}: PPO trains in rollouts of n_steps x num_envs = {n_steps} x "
            f"{num_envs} = {rollout:,} steps; ask for at least that many (or fewer --num-envs)"
        )
    whole = -(-steps // rollout) * rollout
    if whole != steps:
        print(f"training {whole:,} steps: {steps:,} rounded up to whole rollouts of {rollout:,}")
    return whole


def train_ppo(
    task: str = "approach",
    steps: int = 2_000_000,
    num_envs: int = 32,
    seed: int = 0,
    out_dir: Path = Path("runs"),
    sensor_preset: str | None = None,
    eval_every: int = 100_000,
    eval_episodes: int = 32,
    progress: bool = True,
    technique: Any = None,
    population: Any = None,
    condition: str | None = None,
    frame_stack: int = 1,
    recurrent: bool = False,
    **ppo_kwargs: Any,
) -> Path:
    """Train PPO on ``task``; returns the path of the final model (``.zip``).

    Writes TensorBoard logs (``out_dir/tb``), checkpoints (``out_dir/checkpoints``), the best
    model by evaluation success (``out_dir/best_model.zip``) and ``out_dir/learning_curve.json``
    (environment steps, wall time, evaluation success rate and mean return).

    Args:
        technique, population, condition: the cell trained on (:func:`env_settings`; None: the
            env's default technique, no population, the ``lab``); saved with every model as
            ``model.vrloco_cell`` (with ``task``), the env's settings as ``model.vrloco_env``.
        sensor_preset: the IMU preset (None: the technique's, ``"ig500n"`` without one).
        frame_stack: the policy sees each user's last ``frame_stack`` observations side by side
            (:class:`~vrloco_env.wrappers.FrameStack`; 1: the observation alone).
        recurrent: train sb3-contrib's ``RecurrentPPO`` with its LSTM policy
            (``MlpLstmPolicy``) instead of PPO's feed-forward one.
        ppo_kwargs: PPO's settings over :func:`defaults_ppo`.

    Both ``frame_stack`` and ``recurrent`` are saved as ``model.vrloco_policy``.

    Raises:
        ValueError: an unknown task, technique, population or condition (listing the
            registered names), a bad ``frame_stack``, too few ``steps`` for one rollout, or
            ``recurrent`` without sb3-contrib installed.
    """
    from stable_baselines3.common.callbacks import CheckpointCallback
    from stable_baselines3.common.vec_env import VecMonitor

    if _TORCH_SPINS:
        import warnings

        warnings.warn("torch was imported before agents.learned set OMP_WAIT_POLICY=PASSIVE: "
                      "its OpenMP threads spin on the cores the env's kernels need, and training "
                      "runs slower (several times, on a machine whose cores are busy); import "
                      "agents.learned first or set OMP_WAIT_POLICY=PASSIVE before starting "
                      "Python", stacklevel=2)  # fmt: skip
    settings = {**defaults_ppo(), **ppo_kwargs}
    env_kwargs = env_settings(task, sensor_preset, technique, population, condition)
    policy_kwargs = _policy_settings(frame_stack, recurrent)
    steps = rollout_steps(steps, settings["n_steps"], num_envs)
    out_dir.mkdir(parents=True, exist_ok=True)
    venv = VecMonitor(
        SB3VecEnv(_wrap(VRLocoVectorEnv(num_envs, **env_kwargs), frame_stack), seed=seed),
        info_keywords=("is_success",),
    )
    eval_env = _wrap(VRLocoVectorEnv(eval_episodes, **env_kwargs), frame_stack)
    curve: list[dict[str, float]] = []
    t_start = time.perf_counter()

    class Evaluate(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.next_eval = 0
            self.best = -1.0

        def _on_step(self) -> bool:
            if self.num_timesteps < self.next_eval:
                return True
            self.next_eval = self.num_timesteps + eval_every
            result = run_policy_episodes(self.model, eval_env, seed=10_000 + seed)
            result.update(steps=self.num_timesteps, wall_s=time.perf_counter() - t_start)
            curve.append(result)
            self.logger.record("eval/success_rate", result["success_rate"])
            self.logger.record("eval/collision_rate", result["collision_rate"])
            self.logger.record("eval/mean_return", result["mean_return"])
            if result["success_rate"] > self.best:
                self.best = result["success_rate"]
                self.model.save(out_dir / "best_model")
            (out_dir / "learning_curve.json").write_text(json.dumps(curve, indent=2))
            return True

    model = make_model(venv, seed=seed, recurrent=recurrent,
                       tensorboard_log=str(out_dir / "tb"), **settings)  # fmt: skip
    # Saved with every checkpoint, the best and the final model: what the policy was trained on.
    model.vrloco_env = env_kwargs
    model.vrloco_cell = cell_of(env_kwargs, technique)
    model.vrloco_policy = policy_kwargs
    checkpoints = CheckpointCallback(
        max(eval_every // num_envs, 1), str(out_dir / "checkpoints"), name_prefix=f"ppo_{task}"
    )
    final = out_dir / f"ppo_{task}_final"
    callbacks = [RolloutThreads(), checkpoints, Evaluate()]
    try:
        model.learn(steps, callback=callbacks, progress_bar=progress)
    except KeyboardInterrupt:  # Ctrl-C: keep the model and the curve so far
        model.save(final)
        (out_dir / "learning_curve.json").write_text(json.dumps(curve, indent=2))
        if curve:
            plot_learning_curve(curve, out_dir / "learning_curve.png", title=f"PPO on {task}")
        venv.close()
        print(f"interrupted after {model.num_timesteps:,} steps: saved {final}.zip and the "
              f"learning curve so far in {out_dir}")  # fmt: skip
        raise
    finally:
        callbacks[0].restore()
    model.save(final)
    result = run_policy_episodes(model, eval_env, seed=10_000 + seed)
    result.update(steps=model.num_timesteps, wall_s=time.perf_counter() - t_start)
    curve.append(result)
    (out_dir / "learning_curve.json").write_text(json.dumps(curve, indent=2))
    plot_learning_curve(curve, out_dir / "learning_curve.png", title=f"PPO on {task}")
    venv.close()
    return final.with_suffix(".zip")


class RolloutThreads(BaseCallback):
    """A callback that runs PPO's rollouts with one torch thread and its updates with the
    thread count torch had when the callback was made.

    A rollout step's forward pass (one row per user) is too small to share between threads:
    splitting it costs more than it saves, and the second thread takes a core from the env's
    kernels. The update's minibatches keep the threads. Neither changes the numbers:
    ``benchmarks/bench_training.py`` checks that the trained weights are the same.
    """

    def __init__(self) -> None:
        import torch

        super().__init__()
        self.threads = torch.get_num_threads()

    def _on_rollout_start(self) -> None:
        import torch

        torch.set_num_threads(1)

    def _on_rollout_end(self) -> None:
        self.restore()

    def _on_step(self) -> bool:
        return True

    def restore(self) -> None:
        """Give torch its thread count back (after an interrupted rollout too)."""
        import torch

        torch.set_num_threads(self.threads)


def make_model(
    venv: Any, seed: int = 0, recurrent: bool = False, tensorboard_log: str | None = None,
    **settings: Any,
) -> Any:  # fmt: skip
    """The untrained model :func:`train_ppo` trains on ``venv``: stable-baselines3's PPO with
    its feed-forward ``MlpPolicy``, or with ``recurrent`` sb3-contrib's ``RecurrentPPO`` with
    ``MlpLstmPolicy``; ``settings`` are PPO's keywords (:func:`defaults_ppo`)."""
    if recurrent:
        algorithm, policy = _recurrent_ppo(), "MlpLstmPolicy"
    else:
        from stable_baselines3 import PPO

        algorithm, policy = PPO, "MlpPolicy"
    return algorithm(policy, venv, seed=seed, verbose=0, tensorboard_log=tensorboard_log,
                     **settings)  # fmt: skip


def _recurrent_ppo() -> Any:
    """sb3-contrib's ``RecurrentPPO``, or a ValueError saying how to install it."""
    try:
        from sb3_contrib import RecurrentPPO
    except ImportError as err:
        raise ValueError(f"recurrent=True (--recurrent) needs sb3-contrib: pip install "
                         f"sb3-contrib ({err})") from None  # fmt: skip
    return RecurrentPPO


def _policy_settings(frame_stack: Any, recurrent: Any) -> dict[str, Any]:
    """``model.vrloco_policy``: how the policy sees the env, checked."""
    from vrloco_env.wrappers import check_frame_stack

    if not isinstance(recurrent, bool | np.bool_):
        raise ValueError(f"recurrent={recurrent!r}: must be True or False")
    return {"frame_stack": check_frame_stack(frame_stack), "recurrent": bool(recurrent)}


def _wrap(env: VRLocoVectorEnv, frame_stack: int) -> Any:
    """``env`` with each user's last ``frame_stack`` observations side by side (1: as it is)."""
    if frame_stack == 1:
        return env
    from vrloco_env.wrappers import FrameStack

    return FrameStack(env, frame_stack)


#: The evaluation metrics averaged over the seeds by :func:`train_seeds`.
_CURVE_KEYS = ("success_rate", "collision_rate", "mean_return")


def train_seeds(
    task: str,
    seeds: list[int],
    out_dir: Path,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    **train_kwargs: Any,
) -> list[Path]:
    """:func:`train_ppo` once per seed; returns the final models' paths, in the order of ``seeds``.

    One seed is exactly ``train_ppo(task, seed=seed, out_dir=out_dir, ...)``: the same files in
    ``out_dir``. Several seeds train in a :class:`~concurrent.futures.ProcessPoolExecutor` of
    ``workers`` processes (default: one per seed, at most one per core; spawned, so a script
    that calls this needs the ``if __name__ == "__main__":`` guard; no progress bars), each in
    ``out_dir/seed_<s>/`` with the files of a single run, seeded by its seed. The workers keep
    torch's default thread count, so each seed's curve and model are bit-identical to training
    that seed alone (fewer torch threads changed the last digits). Then
    ``out_dir/learning_curve.json`` holds ``{"task", "seeds", "per_seed": {seed: curve},
    "mean": [...]}``, where ``mean`` has, for each evaluation step that every seed reached, the
    mean and the standard deviation over the seeds (``ddof=0``, keys ``<metric>_std``) of the
    success rate, collision rate and mean return, and ``out_dir/learning_curve.png`` draws each
    seed's success rate thin, the mean bold and a mean +- std band against environment steps.

    Ctrl-C stops the workers at once and re-raises ``KeyboardInterrupt``; what each seed saved
    stays (its checkpoints, best model and learning curve up to its last evaluation; not a final
    model), the combined curve is written from those, and one line says so.

    ``backend="ray"`` trains every seed (one too) as a Ray task of one CPU on the cluster at
    ``address`` (as ``vrloco benchmark --backend ray`` connects: ``"auto"``, ``"HOST:PORT"``,
    or None: a running cluster, else a local instance; ``workers`` is not used):
    :func:`_train_seeds_ray`.
    """
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    seeds = list(seeds)
    if not seeds:
        raise ValueError("seeds: give at least one seed")
    for s in seeds:
        if isinstance(s, bool) or not isinstance(s, int) or s < 0:
            raise ValueError(f"seeds: {s!r} is not an integer >= 0")
    repeated = sorted({s for s in seeds if seeds.count(s) > 1})
    if repeated:
        raise ValueError(f"seeds: {', '.join(map(str, repeated))} given more than once")
    out_dir = Path(out_dir)
    if backend not in ("local", "ray"):
        raise ValueError(f"backend must be 'local' or 'ray', got {backend!r}")
    if address is not None and backend != "ray":
        raise ValueError(f"address={address!r} needs backend 'ray'")
    _check_run(task, train_kwargs)  # a bad cell is named here, before any worker starts
    if backend == "ray":
        return _train_seeds_ray(task, seeds, out_dir, address, train_kwargs)
    if len(seeds) == 1:
        return [train_ppo(task, seed=seeds[0], out_dir=out_dir, **train_kwargs)]
    from estimators.kernels import usable_cores

    workers = min(len(seeds), usable_cores()) if workers is None else workers
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers={workers!r}: must be an integer >= 1")
    kwargs = _worker_kwargs(train_kwargs)
    out_dir.mkdir(parents=True, exist_ok=True)
    folders = {s: out_dir / f"seed_{s}" for s in seeds}
    pool = ProcessPoolExecutor(
        max_workers=workers,
        mp_context=get_context("spawn"),  # torch in a forked child can hang
        initializer=_ignore_sigint,
    )
    try:
        futures = [pool.submit(train_ppo, task, seed=s, out_dir=folders[s], **kwargs)
                   for s in seeds]  # fmt: skip
        paths = [f.result() for f in futures]
    except BaseException as err:  # Ctrl-C (or a failed seed): stop the workers now
        for process in list(getattr(pool, "_processes", {}).values()):
            process.terminate()
        pool.shutdown(wait=False, cancel_futures=True)
        curves = _read_curves(folders)
        if curves:
            write_seed_curves(task, curves, out_dir)
        why = "interrupted" if isinstance(err, KeyboardInterrupt) else "a seed run failed"
        print(f"{why}: stopped {len(seeds)} seed runs; kept what each saved (checkpoints, best "
              f"model, learning curve so far) in {out_dir}/seed_*")  # fmt: skip
        raise
    pool.shutdown()
    write_seed_curves(task, _read_curves(folders), out_dir)
    return paths


def _check_run(task: str, train_kwargs: dict[str, Any]) -> None:
    """The cell and the policy settings of :func:`train_ppo`'s keywords, checked (its errors)."""
    env_settings(task, *(train_kwargs.get(k) for k in
                         ("sensor_preset", "technique", "population", "condition")))  # fmt: skip
    _policy_settings(train_kwargs.get("frame_stack", 1), train_kwargs.get("recurrent", False))


def _worker_kwargs(train_kwargs: dict[str, Any]) -> dict[str, Any]:
    """:func:`train_ppo`'s keywords for a worker: no progress bar, and the steps rounded (and
    checked) once here rather than in every worker."""
    n_steps = train_kwargs.get("n_steps", defaults_ppo()["n_steps"])
    kwargs = dict(train_kwargs, progress=False)
    kwargs["steps"] = rollout_steps(kwargs.get("steps", 2_000_000), n_steps,
                                    kwargs.get("num_envs", 32))  # fmt: skip
    return kwargs


def _train_seeds_ray(
    task: str, seeds: list[int], out_dir: Path, address: str | None, train_kwargs: dict
) -> list[Path]:
    """:func:`train_seeds` on the Ray backend: one Ray task of one CPU per seed
    (:func:`_train_seed_task`), which trains in a temporary folder on its node and returns the
    folder's files; each seed's files are written here, in ``out_dir/seed_<s>/`` (one seed:
    in ``out_dir``), as its task finishes, so the cluster's nodes need no shared disk. The
    tasks set torch's thread count to this machine's default (at most their node's cores), so
    that on one machine a seed's curve and model are bit-identical to the local backend's.

    Failures (:mod:`agents.benchmark.backends`): a worker or node lost mid-run is retried up to
    :data:`~agents.benchmark.backends.MAX_RETRIES` times; a seed whose own code raised is not (it
    would raise again). After every other seed has finished and been written, a
    :class:`~agents.benchmark.backends.BackendError` names each failed seed and why; the combined
    curve holds the finished seeds. Ctrl-C cancels the tasks: the finished seeds' files stay (an
    unfinished seed's were on its node and are lost), the combined curve is written from them.
    """
    import torch

    from agents.benchmark.backends import (
        MAX_RETRIES,
        BackendError,
        _cause,
        _connect,
        _first_line,
        import_ray,
    )

    ray = import_ray()
    kwargs = _worker_kwargs(train_kwargs)
    out_dir.mkdir(parents=True, exist_ok=True)
    folders = {s: out_dir if len(seeds) == 1 else out_dir / f"seed_{s}" for s in seeds}
    started = _connect(ray, address)
    remote = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(_train_seed_task)
    threads = torch.get_num_threads()
    pending = {remote.remote(task, s, kwargs, threads): s for s in seeds}
    paths: dict[int, Path] = {}
    failed: list[tuple[int, BaseException]] = []
    try:
        while pending:
            try:
                ready, _ = ray.wait(list(pending), num_returns=1)
            except ray.exceptions.RaySystemError as err:
                raise BackendError(f"lost the Ray cluster mid-run ({_first_line(err)}); seeds "
                                   f"{', '.join(map(str, sorted(pending.values())))} "
                                   "unfinished", partial=True) from err  # fmt: skip
            for ref in ready:
                s = pending.pop(ref)
                try:
                    name, files = ray.get(ref)
                except ray.exceptions.RayError as err:  # retries spent, or the code raised
                    failed.append((s, err))
                    continue
                for rel, data in files.items():
                    (folders[s] / rel).parent.mkdir(parents=True, exist_ok=True)
                    (folders[s] / rel).write_bytes(data)
                paths[s] = folders[s] / name
                print(f"seed {s}: trained ({len(paths)} of {len(seeds)}), in {folders[s]}")
    except BaseException as err:
        for ref in pending:
            try:
                ray.cancel(ref, force=True)
            except Exception:  # the cluster may be gone already
                pass
        if isinstance(err, KeyboardInterrupt):
            print(f"interrupted: cancelled {len(pending)} seed runs on Ray; kept the "
                  f"{len(paths)} finished seeds' files in {out_dir}")  # fmt: skip
        raise
    finally:
        if len(seeds) > 1 and paths:
            write_seed_curves(task, _read_curves({s: folders[s] for s in paths}), out_dir)
        if started:
            ray.shutdown()
    if failed:
        lines = [f"  seed {s}: {_cause(err)}" for s, err in sorted(failed, key=lambda f: f[0])]
        raise BackendError(f"{len(failed)} of {len(seeds)} seed runs failed on Ray (the other "
                           f"{len(seeds) - len(failed)} finished, in {out_dir}):\n"
                           + "\n".join(lines), partial=True)  # fmt: skip
    return [paths[s] for s in seeds]


def _train_seed_task(
    task: str, seed: int, kwargs: dict[str, Any], threads: int
) -> tuple[str, dict[str, bytes]]:
    """One seed's :func:`train_ppo` in a temporary folder, with ``threads`` torch threads (at
    most this node's cores); returns the final model's file name and every file written
    (relative path: bytes)."""
    import tempfile

    import torch

    torch.set_num_threads(max(1, min(threads, os.cpu_count() or 1)))
    with tempfile.TemporaryDirectory(prefix=f"vrloco_seed{seed}_") as tmp:
        root = Path(tmp)
        path = train_ppo(task, seed=seed, out_dir=root, **kwargs)
        files = {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
                 if p.is_file()}  # fmt: skip
    return path.name, files


def _ignore_sigint() -> None:
    """:func:`train_seeds`' workers leave Ctrl-C to the main process, which stops them."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _read_curves(folders: dict[int, Path]) -> dict[int, list[dict[str, float]]]:
    """Each seed's ``learning_curve.json`` that exists (and is whole)."""
    curves = {}
    for s, folder in folders.items():
        try:
            curves[s] = json.loads((folder / "learning_curve.json").read_text())
        except (OSError, ValueError):
            continue
    return curves


def seed_curves_summary(curves: dict[int, list[dict[str, float]]]) -> list[dict[str, float]]:
    """The mean and standard deviation (``ddof=0``) over the seeds of each metric in
    :data:`_CURVE_KEYS`, at every evaluation step that all the seeds' curves have."""
    if not curves:
        return []
    by_seed = [{c["steps"]: c for c in curve} for curve in curves.values()]
    common = sorted(set.intersection(*(set(b) for b in by_seed)))
    rows = []
    for step in common:
        row: dict[str, float] = {"steps": step}
        for key in _CURVE_KEYS:
            values = np.array([b[step][key] for b in by_seed], dtype=float)
            row[key] = float(values.mean())
            row[f"{key}_std"] = float(values.std())
        rows.append(row)
    return rows


def write_seed_curves(
    task: str, curves: dict[int, list[dict[str, float]]], out_dir: Path
) -> dict[str, Any]:
    """``out_dir/learning_curve.json`` and ``.png`` of a :func:`train_seeds` run; returns the
    JSON's content (the png only where the seeds share an evaluation step)."""
    mean = seed_curves_summary(curves)
    data = {"task": task, "seeds": sorted(curves), "per_seed": {str(s): c for s, c in
            sorted(curves.items())}, "mean": mean}  # fmt: skip
    (out_dir / "learning_curve.json").write_text(json.dumps(data, indent=2))
    if mean:
        plot_seed_curves(curves, mean, out_dir / "learning_curve.png", title=f"PPO on {task}")
    return data


def plot_seed_curves(
    curves: dict[int, list[dict[str, float]]],
    mean: list[dict[str, float]],
    path: Path,
    title: str = "",
) -> None:
    """Evaluation success rate against environment steps: one thin line per seed, the mean over
    the seeds bold and a shaded mean +- std band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    for s, curve in sorted(curves.items()):
        ax.plot([c["steps"] for c in curve], [c["success_rate"] for c in curve], lw=0.8,
                alpha=0.6, label=f"seed {s}")  # fmt: skip
    steps = np.array([m["steps"] for m in mean])
    mu = np.array([m["success_rate"] for m in mean])
    sd = np.array([m["success_rate_std"] for m in mean])
    ax.fill_between(steps, mu - sd, mu + sd, color="C0", alpha=0.2, lw=0, label="mean ± std")
    ax.plot(steps, mu, color="k", lw=2.5, label=f"mean of {len(curves)} seeds")
    ax.axhline(0.9, color="0.6", lw=0.8, ls=":")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("evaluation success rate")
    ax.set_ylim(-0.02, 1.02)
    ax.legend(loc="lower right", fontsize="small")
    ax.set_title(
        f"{title}: {mu[-1]:.0%} ± {sd[-1]:.0%} success after {steps[-1]:,} steps "
        f"({len(curves)} seeds)"
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_learning_curve(curve: list[dict[str, float]], path: Path, title: str = "") -> None:
    """Evaluation success and collision rates against environment steps (wall time on top)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = np.array([c["steps"] for c in curve])
    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    ax.plot(steps, [c["success_rate"] for c in curve], "o-", label="success rate")
    ax.plot(steps, [c["collision_rate"] for c in curve], "s--", label="collision rate")
    ax.axhline(0.9, color="0.6", lw=0.8, ls=":")
    ax.set_xlabel("environment steps")
    ax.set_ylim(-0.02, 1.02)
    ax.legend(loc="center right")
    wall = curve[-1]["wall_s"]
    ax.set_title(
        f"{title}: {curve[-1]['success_rate']:.0%} success after {steps[-1]:,} steps, "
        f"{wall / 60:.1f} min"
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run_policy_episodes(model: Any, env: VRLocoVectorEnv, seed: int) -> dict[str, float]:
    """One episode per sub-env with the deterministic policy; success, collision rate, return.
    A recurrent model (sb3-contrib's ``RecurrentPPO``) carries its LSTM state from step to step,
    each user's started afresh with its episode."""
    obs, _ = env.reset(seed=seed)
    n = env.num_envs
    done = np.zeros(n, bool)
    success = np.zeros(n, bool)
    collided = np.zeros(n, bool)
    returns = np.zeros(n)
    want = (n, *env.single_action_space.shape)
    recurrent = is_recurrent(model)
    state, starts = None, np.ones(n, bool)
    while not done.all():
        if recurrent:
            action, state = model.predict(obs, state=state, episode_start=starts,
                                          deterministic=True)  # fmt: skip
        else:
            action, _ = model.predict(obs, deterministic=True)
        if np.shape(action) != want:
            raise ValueError(
                f"model {type(model).__name__} returned actions of shape {np.shape(action)} "
                f"from predict(); expected {want} (one row of {want[1]} per user)"
            )
        obs, reward, terminated, truncated, info = env.step(action)
        starts = terminated | truncated
        live = ~done
        returns += np.where(live, reward, 0.0)
        collided |= live & info["collision"]
        ended = live & (terminated | truncated)
        success |= ended & info["is_success"]
        done |= ended
    return {
        "success_rate": float(success.mean()),
        "collision_rate": float(collided.mean()),
        "mean_return": float(returns.mean()),
    }


def is_recurrent(model: Any) -> bool:
    """Whether ``model``'s policy keeps a state between steps (an LSTM policy of sb3-contrib's
    ``RecurrentPPO``), so that ``predict`` takes ``state`` and ``episode_start``."""
    return hasattr(getattr(model, "policy", None), "lstm_actor")


def env_settings(
    task: str,
    sensor_preset: str | None = None,
    technique: Any = None,
    population: Any = None,
    condition: str | None = None,
    **configs: Any,
) -> dict[str, Any]:
    """The env a policy is trained on, as the keywords of :class:`~vrloco_env.env.VRLocoEnv`:
    the task and every configuration dataclass filled in (stored with the model).

    Args:
        task: a registered task.
        sensor_preset: the IMU preset (None: the technique's, ``"ig500n"`` without one).
        technique: a registered technique, ``"module:attr"`` or a
            :class:`~vrloco_env.techniques.Technique` (None: the env's default chain).
        population: a user population (:mod:`vrloco_env.user.population`) whose head behaviour
            the env simulates (None: none; one whose head turns on the torso adds the
            observation field ``head_on_torso``).
        condition: a physical-room condition (:mod:`agents.benchmark.conditions`; None: ``lab``).
        configs: further keywords of :func:`~vrloco_env.env.make_configs`.

    Raises:
        ValueError: an unknown task, technique, population or condition (the registry's error,
            listing the registered names), or settings that contradict each other.
    """
    from agents.benchmark.conditions import get_condition
    from vrloco_env.env import make_configs
    from vrloco_env.tasks import get_task
    from vrloco_env.techniques import get_technique
    from vrloco_env.user.population import get_population

    get_task(task)  # raises with the registered names
    if technique is not None:
        get_technique(technique)
    if population is not None:
        get_population(population)
    if condition is not None:
        room_sensors = get_condition(condition).sensors()
        if room_sensors is not None:
            if configs.get("sensors") is not None:
                raise ValueError(f"condition={condition!r} sets the sensors' magnetic "
                                 "disturbances; give the condition or sensors=, not both")
            configs["sensors"] = room_sensors
    config, sensors, estimators, room, reward = make_configs(
        sensor_preset=sensor_preset, technique=technique, population=population, **configs
    )
    return {
        "task": task, "config": config, "sensors": sensors, "estimators": estimators,
        "room": room, "reward": reward,
    }  # fmt: skip


def cell_of(settings: dict[str, Any], technique: Any = None) -> dict[str, Any]:
    """The cell of the env ``settings`` (:func:`env_settings`): its ``task``, ``technique``
    (``technique``'s name where one was given, else the registered technique its sensors and
    estimators make up, or ``"custom"``), ``population`` (the name, None without one) and
    ``condition`` (the registered condition whose magnetic disturbances its sensors have, else
    ``"custom"``)."""
    from agents.benchmark.conditions import CONDITIONS
    from vrloco_env.env import technique_name
    from vrloco_env.techniques import get_technique

    sensors, config = settings["sensors"], settings["config"]
    if technique is not None:
        tech = get_technique(technique).name
    else:
        tech = technique_name(sensors, settings["estimators"])
    disturbances = tuple(getattr(sensors, "magnetic_disturbances", ()) or ())
    condition = next((c.name for c in CONDITIONS.values()
                      if tuple(c.magnetic_disturbances) == disturbances), "custom")  # fmt: skip
    population = config.population
    return {
        "task": settings["task"],
        "technique": tech,
        "population": getattr(population, "name", population),
        "condition": condition,
    }


def model_env_settings(model: Any, path: Path) -> dict[str, Any]:
    """The env settings stored with a model by :func:`train_ppo` (a clear error without them)."""
    settings = getattr(model, "vrloco_env", None)
    if not isinstance(settings, dict) or "task" not in settings:
        raise ValueError(
            f"{path}: the model carries no vrloco env settings (it was not saved by vrloco "
            "train); pass task= (--task) and the sensors explicitly"
        )
    return settings


def model_cell(model: Any, settings: dict[str, Any]) -> dict[str, Any]:
    """The cell a model was trained on: ``model.vrloco_cell`` as :func:`train_ppo` saved it, or
    for a model saved without one, the cell its env ``settings`` make up (:func:`cell_of`)."""
    cell = getattr(model, "vrloco_cell", None)
    if isinstance(cell, dict) and all(k in cell for k in CELL_KEYS):
        return {k: cell[k] for k in CELL_KEYS}
    return cell_of(settings)


def model_policy(model: Any) -> dict[str, Any]:
    """How a model sees the env (``model.vrloco_policy``): ``frame_stack`` (frames side by side,
    1 for a model saved without it) and ``recurrent`` (read from the model's policy)."""
    saved = getattr(model, "vrloco_policy", None)
    frames = saved.get("frame_stack", 1) if isinstance(saved, dict) else 1
    return {"frame_stack": int(frames), "recurrent": is_recurrent(model)}


def _cell_text(cell: dict[str, Any], sensors: str) -> str:
    """A cell in words, for messages."""
    return (f"task {cell['task']!r}, technique {cell['technique']!r}, population "
            f"{cell['population']!r}, condition {cell['condition']!r}, sensors "
            f"{sensors!r}")  # fmt: skip


def _asked_cell(
    cell: dict[str, Any], sensors: str, task: str | None, technique: Any, population: Any,
    condition: str | None, sensor_preset: str | None,
) -> dict[str, tuple[Any, Any]]:  # fmt: skip
    """The parts of the cell asked for that differ from the model's: ``{name: (trained,
    asked)}``; unknown names raise the registries' errors."""
    from agents.benchmark.conditions import get_condition
    from vrloco_env.tasks import get_task
    from vrloco_env.techniques import get_technique
    from vrloco_env.user.population import get_population

    asked: dict[str, Any] = {}
    if task is not None:
        get_task(task)
        asked["task"] = task
    if technique is not None:
        asked["technique"] = get_technique(technique).name
    if population is not None:
        asked["population"] = get_population(population).name
    if condition is not None:
        asked["condition"] = get_condition(condition).name
    if sensor_preset is not None:
        asked["sensors"] = sensor_preset
    trained = {**cell, "sensors": sensors}
    none_is = {"population": "idealised"}  # no population: the idealised user's head
    return {k: (trained[k], v) for k, v in asked.items()
            if (trained[k] or none_is.get(k)) != v}  # fmt: skip


def _settings_for(
    settings: dict[str, Any], task: str | None, technique: Any, population: Any,
    condition: str | None, sensor_preset: str | None,
) -> dict[str, Any]:  # fmt: skip
    """The model's env ``settings`` with the parts of the cell asked for replaced, the rest
    (room, reward, rates, ...) as trained."""
    from dataclasses import replace

    from agents.benchmark.conditions import get_condition
    from vrloco_env.techniques import get_technique

    out = dict(settings)
    sensors = out["sensors"]
    if technique is not None:
        tech = get_technique(technique)
        if sensor_preset is not None and sensor_preset != tech.sensor_preset:
            raise ValueError(f"sensors={sensor_preset!r} contradicts technique={tech.name!r} "
                             f"(sensor preset {tech.sensor_preset!r}); give one")  # fmt: skip
        out["estimators"] = tech.estimators
        sensors = replace(sensors, imu=tech.sensor_preset)
    if sensor_preset is not None:
        sensors = replace(sensors, imu=sensor_preset)
    if condition is not None:
        sensors = replace(sensors,
                          magnetic_disturbances=get_condition(condition).magnetic_disturbances)
    out["sensors"] = sensors
    if population is not None:
        out["config"] = replace(out["config"], population=population)
    if task is not None:
        out["task"] = task
    return out


def evaluate_model(
    path: Path,
    task: str | None = None,
    episodes: int = 100,
    seed: int = 0,
    sensor_preset: str | None = None,
    progress: bool = True,
    technique: Any = None,
    population: Any = None,
    condition: str | None = None,
    allow_mismatch: bool = False,
) -> dict[str, Any]:
    """The benchmark's row (:func:`agents.benchmark.metrics.summarize`) for a saved PPO model.

    The model is evaluated on the cell it was trained on (task, technique, population and
    condition, and every configuration, stored with it by :func:`train_ppo`), seeing the env as
    it was trained to (its frame stack, its recurrent state:
    :class:`agents.benchmark.policies.LearnedPolicy`). ``task``, ``technique``, ``population``,
    ``condition`` and ``sensor_preset`` may repeat what the model carries; one that
    contradicts it is an error naming every difference, unless ``allow_mismatch``: then the
    model plays the cell asked for (the model's env with those parts replaced). A model saved
    elsewhere, without vrloco's settings, needs ``task``. Episode i is a single env reset with
    ``seed + i`` and run with the deterministic policy, as ``vrloco benchmark`` runs a scripted
    user, and steps are matched in the benchmark's window
    (:func:`agents.benchmark.step_matching.step_window`), so the row compares directly with the
    benchmark's (:func:`agents.benchmark.outputs.show_table` prints it). ``progress`` shows a
    progress bar over the episodes (rich, as the benchmark's).

    Returns:
        The row: ``task``, ``policy`` (``ppo:<file name>``), ``technique``, ``population``
        (None: no population), ``condition`` (the registered physical-room condition whose
        magnetic disturbances the env's sensors have, else ``"custom"``), ``sensors`` (the IMU
        preset), ``trained_on`` (the model's own cell where it was played on another, else
        None), the metrics of :func:`~agents.benchmark.metrics.summarize` and ``vs_baseline`` (None:
        no baseline here).

    Raises:
        ValueError: one line naming the file or the argument: no such file, not a PPO model
            (:func:`agents.benchmark.policies.load_ppo`), an unknown technique, population or
            condition (listing the registered names), a cell contradicting the model's without
            ``allow_mismatch``, a model without vrloco's settings and no ``task``, or
            ``episodes`` below 1.
    """
    import gymnasium as gym
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    from agents.benchmark.episodes import run_episode
    from agents.benchmark.metrics import summarize
    from agents.benchmark.policies import LearnedPolicy, _load_ppo
    from agents.benchmark.step_matching import step_window
    from vrloco_env.tasks import env_id

    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes={episodes!r}: must be an integer >= 1")
    path = Path(path)
    model = _load_ppo(path)
    trained_on = None
    try:
        settings = dict(model_env_settings(model, path))
    except ValueError:
        if task is None:
            raise
        settings = env_settings(task, sensor_preset, technique, population, condition)
        here = cell_of(settings, technique)
    else:
        here = model_cell(model, settings)
        preset = settings["sensors"].preset_name
        differs = _asked_cell(here, preset, task, technique, population, condition,
                              sensor_preset)  # fmt: skip
        if differs and not allow_mismatch:
            what = ", ".join(f"{k}={v!r} (trained: {t!r})" for k, (t, v) in differs.items())
            them = "it" if len(differs) == 1 else "them"
            raise ValueError(
                f"{what} contradicts the model, which was trained on {_cell_text(here, preset)} "
                f"({path}); leave {them} out to evaluate on the model's own cell, or allow the "
                "mismatch (--allow-mismatch) to evaluate it on the one asked for"
            )
        if differs:
            trained_on = {**here, "sensors": preset}
            settings = _settings_for(settings, task, technique, population, condition,
                                     sensor_preset)  # fmt: skip
            played = cell_of(settings, technique)
            replaced = set(differs) | ({"technique"} if "sensors" in differs else set())
            here = {k: played[k] if k in replaced else here[k] for k in CELL_KEYS}
    played_preset = settings["sensors"].preset_name
    task = settings.pop("task")
    env = gym.make(env_id(task), **settings)
    try:
        policy = LearnedPolicy(path, env, allow_mismatch=trained_on is not None)
        columns = ("[progress.description]{task.description}", BarColumn(),
                   MofNCompleteColumn(), TimeElapsedColumn())  # fmt: skip
        played = []
        with Progress(*columns, disable=not progress, transient=False) as bar:
            job = bar.add_task("episodes", total=episodes)
            for i in range(episodes):
                played.append(run_episode(env, policy, seed + i, name=policy.name))
                bar.advance(job)
    finally:
        env.close()
    stats = [st for st, _ in played]
    first, info = played[0]
    window = step_window(info, first.elapsed_s / max(first.steps, 1))
    return {
        "task": task,
        "policy": policy.name,
        "technique": here["technique"],
        "population": here["population"],
        "condition": here["condition"],
        "sensors": played_preset,
        "trained_on": trained_on,
        **summarize(stats, *window),
        "vs_baseline": None,
    }
