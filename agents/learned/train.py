"""PPO training of a learned simulated user: stable-baselines3's PPO on the native vector env
(:class:`SB3VecEnv`), one run (:func:`train_ppo`) or one per seed in worker processes or Ray
tasks (:func:`train_seeds`), with rollouts on one torch thread (:class:`RolloutThreads`).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

from agents.learned.curves import _read_curves, plot_learning_curve, write_seed_curves
from agents.learned.evaluate import run_policy_episodes
from agents.learned.mixed_env import mix_cell, mixed_users, training_cells
from agents.learned.models import ModelFields, cell_of, env_settings, observation_layout
from agents.learned.threads import _TORCH_SPINS
from vrloco_env.vector import VRLocoVectorEnv

__all__ = ["RolloutThreads", "SB3VecEnv", "make_model", "train_ppo", "train_seeds"]


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
    reward: Any = None,
    variability: str | None = None,
    env_workers: int = 1,
    init: Path | str | None = None,
    imitate: str | None = None,
    imitate_steps: int = 200_000,
    **ppo_kwargs: Any,
) -> Path:
    """Train PPO on ``task``; returns the path of the final model (``.zip``).

    Writes TensorBoard logs (``out_dir/tb``), checkpoints (``out_dir/checkpoints``), the best
    model by evaluation success (``out_dir/best_model.zip``) and ``out_dir/learning_curve.json``
    (environment steps, wall time, evaluation success rate and mean return).

    Args:
        technique, population, condition: the cell trained on
            (:func:`~agents.learned.models.env_settings`; None: the env's default technique, no
            population, the ``lab``); saved with every model as ``model.vrloco_cell`` (with
            ``task``), the env's settings as ``model.vrloco_env``.
        sensor_preset: the IMU preset (None: the technique's, ``"ig500n"`` without one).
        frame_stack: the policy sees each user's last ``frame_stack`` observations side by side
            (:class:`~vrloco_env.wrappers.FrameStack`; 1: the observation alone).
        recurrent: train sb3-contrib's ``RecurrentPPO`` with its LSTM policy
            (``MlpLstmPolicy``) instead of PPO's feed-forward one.
        reward: the training objective, a :class:`~vrloco_env.config.RewardConfig` (None: the
            env's default terms). It shapes what the user learns, not the task: success,
            collisions and time are measured the same under any reward.
        variability: a user population whose human variability (reaction delay, turn
            overshoot, cadence; :class:`~agents.learned.variability_env.HumanVariabilityEnv`) the
            learner trains and is evaluated with (None: none); saved as
            ``model.vrloco_variability``.
        env_workers: processes the training users are stepped in, a share of the batch each
            (:func:`~agents.learned.parallel_env.parallel_users`; 1: in this process). The
            users' episodes, and so the trained weights, are the same for any number.
        init: a model (``.zip``) trained by ``vrloco train`` to start from instead of a new
            policy: its weights and PPO settings go on learning on this run's cell and
            objective (``ppo_kwargs`` are not taken). It must see the env as this run does
            (the same frame stack and recurrence) and reads the users' observation fields it
            knows, by name (:class:`~agents.learned.models.ModelFields`: a population's
            ``head_on_torso`` it was not trained on is left unread); it keeps its layout.
        imitate: a scripted user (``goal_seeker``, ...) the new policy imitates before PPO
            starts (:func:`~agents.learned.imitation.imitate`, DAgger on the training users
            with the run's seed; None: PPO from a random policy). One cell, a feed-forward
            policy, no ``init``.
        imitate_steps: the imitation's environment steps (not counted in ``steps``).
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

        warnings.warn(
            "torch was imported before agents.learned set OMP_WAIT_POLICY=PASSIVE: "
            "its OpenMP threads spin on the cores the env's kernels need, and training "
            "runs slower (several times, on a machine whose cores are busy); import "
            "agents.learned first or set OMP_WAIT_POLICY=PASSIVE before starting "
            "Python",
            stacklevel=2,
        )
    settings = {**defaults_ppo(), **ppo_kwargs}
    if init is not None:  # its own PPO settings: its rollouts
        from agents.benchmark.policies import load_ppo

        if ppo_kwargs:
            raise ValueError(
                f"init={str(init)!r} keeps its own PPO settings; drop "
                + ", ".join(sorted(ppo_kwargs))
            )
        settings["n_steps"] = load_ppo(Path(init)).n_steps
    cells = training_cells(technique, population, variability)
    if imitate is not None:
        _check_imitation(imitate, init, recurrent, len(cells), env_workers)
    technique, population, variability = cells[0]  # a mix's settings: its first cell's
    env_kwargs = env_settings(
        task, sensor_preset, technique, population, condition, **_reward_kwargs(reward)
    )
    policy_kwargs = _policy_settings(frame_stack, recurrent)
    steps = rollout_steps(steps, settings["n_steps"], num_envs)
    out_dir.mkdir(parents=True, exist_ok=True)
    if isinstance(env_workers, bool) or not isinstance(env_workers, int) or env_workers < 1:
        raise ValueError(f"env_workers={env_workers!r}: must be an integer >= 1")
    if env_workers > 1 and len(cells) > 1:
        raise ValueError("env_workers > 1 (--env-workers) steps one cell's users; not a mix")
    if len(cells) == 1:
        if env_workers > 1:
            from agents.learned.parallel_env import parallel_users

            users = _human(parallel_users(num_envs, env_workers, env_kwargs), variability, seed)
        else:
            users = _human(VRLocoVectorEnv(num_envs, **env_kwargs), variability, seed)
        eval_users = VRLocoVectorEnv(eval_episodes, **env_kwargs)
        evaluated = _human(eval_users, variability, 10_000 + seed)
    else:
        mix = (task, sensor_preset, cells, condition, reward)
        users = mixed_users(num_envs, *mix, seed=seed)
        eval_users = mixed_users(eval_episodes, *mix, seed=10_000 + seed, field="eval_episodes")
        evaluated = eval_users
    layout = observation_layout(eval_users.observation_spec)
    base = None
    if init is not None:  # the model reads the users' fields it was trained on, by name
        base, columns = _start_from(Path(init), policy_kwargs, eval_users)
        layout = base.vrloco_observation
        users, evaluated = ModelFields(users, columns), ModelFields(evaluated, columns)
    eval_env = _wrap(evaluated, frame_stack)
    venv = VecMonitor(
        SB3VecEnv(_wrap(users, frame_stack), seed=seed), info_keywords=("is_success",)
    )
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

    if init is None:
        model = make_model(
            venv, seed=seed, recurrent=recurrent, tensorboard_log=str(out_dir / "tb"), **settings
        )
        if imitate is not None:
            _imitate(model, users, frame_stack, imitate, imitate_steps, seed, out_dir)
    else:
        model = type(base).load(init, env=venv)
        model.tensorboard_log = str(out_dir / "tb")
        model.set_random_seed(seed)
    # Saved with every checkpoint, the best and the final model: what the policy was trained on.
    model.vrloco_env = env_kwargs
    model.vrloco_cell = cell_of(env_kwargs, technique)
    model.vrloco_policy = policy_kwargs
    model.vrloco_observation = layout
    model.vrloco_variability = variability
    if len(cells) > 1:  # the cell's technique and population: every one of the mix
        model.vrloco_cell.update({k: v for k, v in mix_cell(cells).items() if isinstance(v, list)})
        model.vrloco_variability = [c[2] for c in cells]
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
        print(
            f"interrupted after {model.num_timesteps:,} steps: saved {final}.zip and the "
            f"learning curve so far in {out_dir}"
        )
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


def _check_imitation(
    imitate: str, init: Any, recurrent: bool, n_cells: int, env_workers: int
) -> None:
    from agents.scripted import POLICIES

    if imitate not in POLICIES:
        raise ValueError(
            f"imitate={imitate!r}: not a scripted user; choose from {', '.join(sorted(POLICIES))}"
        )
    for bad, why in (
        (init is not None, "a new policy, not init's"),
        (recurrent, "a feed-forward policy, not a recurrent one"),
        (n_cells > 1, "one cell's users, not a mix"),
        (env_workers > 1, "users stepped in this process (env_workers=1)"),
    ):
        if bad:
            raise ValueError(f"imitate={imitate!r} trains {why}")


def _imitate(
    model: Any, users: Any, frame_stack: int, imitate: str, steps: int, seed: int, out_dir: Path
) -> None:
    """The new policy imitates the scripted user ``imitate`` on the training users
    (:func:`~agents.learned.imitation.imitate`); its rounds go to ``out_dir/imitation.json``."""
    from agents.learned.imitation import imitate as dagger
    from agents.scripted import ObservationLayout, make_policy, params_from_env

    base = users.unwrapped
    teacher = make_policy(imitate, ObservationLayout.from_env(base), params_from_env(base))
    rounds = dagger(model, _wrap(users, frame_stack), teacher, steps, seed=seed + 50_000)
    (out_dir / "imitation.json").write_text(
        json.dumps({"teacher": imitate, "steps": steps, "rounds": rounds}, indent=2)
    )


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
    venv: Any,
    seed: int = 0,
    recurrent: bool = False,
    tensorboard_log: str | None = None,
    **settings: Any,
) -> Any:
    """The untrained model :func:`train_ppo` trains on ``venv``: stable-baselines3's PPO with
    its feed-forward ``MlpPolicy``, or with ``recurrent`` sb3-contrib's ``RecurrentPPO`` with
    ``MlpLstmPolicy``; ``settings`` are PPO's keywords (:func:`defaults_ppo`)."""
    if recurrent:
        algorithm, policy = _recurrent_ppo(), "MlpLstmPolicy"
    else:
        from stable_baselines3 import PPO

        algorithm, policy = PPO, "MlpPolicy"
    return algorithm(
        policy, venv, seed=seed, verbose=0, tensorboard_log=tensorboard_log, **settings
    )


def _recurrent_ppo() -> Any:
    """sb3-contrib's ``RecurrentPPO``, or a ValueError saying how to install it."""
    try:
        from sb3_contrib import RecurrentPPO
    except ImportError as err:
        raise ValueError(
            f"recurrent=True (--recurrent) needs sb3-contrib: pip install sb3-contrib ({err})"
        ) from None
    return RecurrentPPO


def _policy_settings(frame_stack: Any, recurrent: Any) -> dict[str, Any]:
    """``model.vrloco_policy``: how the policy sees the env, checked."""
    from vrloco_env.wrappers import check_frame_stack

    if not isinstance(recurrent, bool | np.bool_):
        raise ValueError(f"recurrent={recurrent!r}: must be True or False")
    return {"frame_stack": check_frame_stack(frame_stack), "recurrent": bool(recurrent)}


def _start_from(path: Path, policy_kwargs: dict[str, Any], users: Any) -> tuple[Any, Any]:
    """The model at ``path`` (:func:`train_ppo`'s ``init``) and the columns of ``users``'
    observation it reads (:func:`~agents.learned.models.observation_columns`: its fields by
    name; a field the users have and it does not know is left unread).

    Raises:
        ValueError: a model that sees the env otherwise than this run (its frame stack or
            recurrence, or a field the users lack), naming what differs.
    """
    from agents.benchmark.policies import load_ppo
    from agents.learned.models import model_policy, observation_columns

    base = load_ppo(path)
    seen = model_policy(base)
    for key in ("frame_stack", "recurrent"):
        if seen[key] != policy_kwargs[key]:
            raise ValueError(
                f"init={str(path)!r} was trained with {key}={seen[key]!r}, this run has "
                f"{policy_kwargs[key]!r}"
            )
    saved = getattr(base, "vrloco_observation", None)
    if not isinstance(saved, list):
        raise ValueError(
            f"init={str(path)!r} carries no observation layout (not from vrloco train)"
        )
    try:
        columns = observation_columns(saved, users.observation_spec)
    except ValueError as err:
        raise ValueError(f"init={str(path)!r} cannot read this run's users: {err}") from None
    return base, columns


def _human(env: Any, population: str | None, seed: int) -> Any:
    """``env`` with the human variability of ``population`` around the learner (None: as it
    is)."""
    if population is None:
        return env
    from agents.learned.variability_env import HumanVariabilityEnv

    return HumanVariabilityEnv(env, population, seed)


def _wrap(env: VRLocoVectorEnv, frame_stack: int) -> Any:
    """``env`` with each user's last ``frame_stack`` observations side by side (1: as it is)."""
    if frame_stack == 1:
        return env
    from vrloco_env.wrappers import FrameStack

    return FrameStack(env, frame_stack)


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
        futures = [
            pool.submit(train_ppo, task, seed=s, out_dir=folders[s], **kwargs) for s in seeds
        ]
        paths = [f.result() for f in futures]
    except BaseException as err:  # Ctrl-C (or a failed seed): stop the workers now
        for process in list(getattr(pool, "_processes", {}).values()):
            process.terminate()
        pool.shutdown(wait=False, cancel_futures=True)
        curves = _read_curves(folders)
        if curves:
            write_seed_curves(task, curves, out_dir)
        why = "interrupted" if isinstance(err, KeyboardInterrupt) else "a seed run failed"
        print(
            f"{why}: stopped {len(seeds)} seed runs; kept what each saved (checkpoints, best "
            f"model, learning curve so far) in {out_dir}/seed_*"
        )
        raise
    pool.shutdown()
    write_seed_curves(task, _read_curves(folders), out_dir)
    return paths


def _reward_kwargs(reward: Any) -> dict[str, Any]:
    """``reward`` as :func:`env_settings`' keyword (none for None), checked."""
    from vrloco_env.config import RewardConfig

    if reward is None:
        return {}
    if not isinstance(reward, RewardConfig):
        raise ValueError(f"reward={reward!r}: must be a RewardConfig or None")
    return {"reward": reward}


def _check_run(task: str, train_kwargs: dict[str, Any]) -> None:
    """The cell and the policy settings of :func:`train_ppo`'s keywords, checked (its errors)."""
    cells = training_cells(
        *(train_kwargs.get(k) for k in ("technique", "population", "variability"))
    )
    for technique, population, _ in cells:
        env_settings(
            task,
            train_kwargs.get("sensor_preset"),
            technique,
            population,
            train_kwargs.get("condition"),
            **_reward_kwargs(train_kwargs.get("reward")),
        )
    _policy_settings(train_kwargs.get("frame_stack", 1), train_kwargs.get("recurrent", False))
    if train_kwargs.get("imitate") is not None:
        _check_imitation(
            train_kwargs["imitate"],
            train_kwargs.get("init"),
            train_kwargs.get("recurrent", False),
            len(cells),
            train_kwargs.get("env_workers", 1),
        )


def _worker_kwargs(train_kwargs: dict[str, Any]) -> dict[str, Any]:
    """:func:`train_ppo`'s keywords for a worker: no progress bar, and the steps rounded (and
    checked) once here rather than in every worker."""
    n_steps = train_kwargs.get("n_steps", defaults_ppo()["n_steps"])
    kwargs = dict(train_kwargs, progress=False)
    kwargs["steps"] = rollout_steps(
        kwargs.get("steps", 2_000_000), n_steps, kwargs.get("num_envs", 32)
    )
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
                raise BackendError(
                    f"lost the Ray cluster mid-run ({_first_line(err)}); seeds "
                    f"{', '.join(map(str, sorted(pending.values())))} "
                    "unfinished",
                    partial=True,
                ) from err
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
            print(
                f"interrupted: cancelled {len(pending)} seed runs on Ray; kept the "
                f"{len(paths)} finished seeds' files in {out_dir}"
            )
        raise
    finally:
        if len(seeds) > 1 and paths:
            write_seed_curves(task, _read_curves({s: folders[s] for s in paths}), out_dir)
        if started:
            ray.shutdown()
    if failed:
        lines = [f"  seed {s}: {_cause(err)}" for s, err in sorted(failed, key=lambda f: f[0])]
        raise BackendError(
            f"{len(failed)} of {len(seeds)} seed runs failed on Ray (the other "
            f"{len(seeds) - len(failed)} finished, in {out_dir}):\n" + "\n".join(lines),
            partial=True,
        )
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
        files = {
            str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
        }
    return path.name, files


def _ignore_sigint() -> None:
    """:func:`train_seeds`' workers leave Ctrl-C to the main process, which stops them."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
