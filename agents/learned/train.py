"""PPO training of a learned simulated user: stable-baselines3's PPO on the native vector env
(:class:`SB3VecEnv`), one run (:func:`train_ppo`), on one torch thread
(:class:`OneTorchThread`). One run per seed, in worker processes or Ray tasks:
:mod:`agents.learned.seeds`.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

from agents.learned.curves import plot_learning_curve
from agents.learned.evaluate import run_policy_episodes
from agents.learned.imitation import check_imitation, imitate_scripted, scripted_teacher
from agents.learned.mixed_env import mix_cell, mixed_users, training_cells
from agents.learned.models import ModelFields, cell_of, env_settings, observation_layout
from agents.learned.residual import (
    RESIDUAL_LOG_STD,
    VALUE_STEPS,
    ScriptedPlusCorrection,
    check_residual,
    fit_values,
    zero_correction,
)
from agents.learned.threads import _TORCH_SPINS
from vrloco_env.vector import VRLocoVectorEnv

__all__ = ["EVAL_EPISODES", "OneTorchThread", "SB3VecEnv", "make_model", "train_ppo"]

#: Users each training evaluation plays by default (a mix of more cells plays one per cell).
EVAL_EPISODES = 32


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
    eval_episodes: int | None = None,
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
    residual_on: str | None = None,
    **ppo_kwargs: Any,
) -> Path:
    """Train PPO on ``task``; returns the path of the final model (``.zip``).

    Writes TensorBoard logs (``out_dir/tb``), checkpoints (``out_dir/checkpoints``), the best
    model by evaluation success (``out_dir/best_model.zip``) and ``out_dir/learning_curve.json``
    (environment steps, wall time, evaluation success rate and mean return).

    Args:
        eval_episodes: users each evaluation plays, seeded from ``10_000 + seed`` (None:
            :data:`EVAL_EPISODES`, or one per cell of a mix of more cells; a mix needs at least
            one per cell).
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
        residual_on: a scripted user (``goal_seeker``) whose actions the policy learns to
            correct (:mod:`agents.learned.residual`: it sees the scripted action, its own is
            added to it, and a new policy starts with no correction, as the scripted user; the
            value function is first fitted to the scripted user's returns over
            :data:`~agents.learned.residual.VALUE_STEPS` steps, not counted in ``steps``). One
            technique, a feed-forward policy, no ``imitate``. None: the policy acts alone.
        ppo_kwargs: PPO's settings over :func:`defaults_ppo`.

    ``frame_stack``, ``recurrent`` and ``residual_on`` are saved as ``model.vrloco_policy``.

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
        check_imitation(imitate, init, recurrent, cells, env_workers)
    if residual_on is not None:
        check_residual(residual_on, recurrent, env_workers)
        if imitate is not None:
            raise ValueError(
                f"residual_on={residual_on!r} starts as that scripted user; drop imitate"
            )
    if eval_episodes is None:
        eval_episodes = max(EVAL_EPISODES, len(cells))
    technique, population, variability = cells[0]  # a mix's settings: its first cell's
    env_kwargs = env_settings(
        task, sensor_preset, technique, population, condition, **_reward_kwargs(reward)
    )
    policy_kwargs = _policy_settings(frame_stack, recurrent, residual_on)
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
    spec = eval_users.observation_spec
    if residual_on is not None:  # the policy sees, and corrects, the scripted user's action
        users = ScriptedPlusCorrection(
            users, scripted_teacher(residual_on, users.unwrapped, True), residual_on, spec
        )
        evaluated = ScriptedPlusCorrection(
            evaluated, scripted_teacher(residual_on, eval_users, True), residual_on, spec
        )
        spec = users.observation_spec
    layout = observation_layout(spec)
    base = None
    if init is not None:  # the model reads the users' fields it was trained on, by name
        base, columns = _start_from(Path(init), policy_kwargs, spec)
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
        if residual_on is not None:  # explore near the scripted user
            settings["policy_kwargs"] = {
                "log_std_init": RESIDUAL_LOG_STD,
                **settings.get("policy_kwargs", {}),
            }
        model = make_model(
            venv, seed=seed, recurrent=recurrent, tensorboard_log=str(out_dir / "tb"), **settings
        )
        if residual_on is not None:  # the scripted user's returns go to out_dir/values.json
            zero_correction(model)
            warmup = fit_values(model, _wrap(users, frame_stack), VALUE_STEPS, seed + 50_000)
            (out_dir / "values.json").write_text(
                json.dumps({"scripted_user": residual_on, **warmup}, indent=2)
            )
        if imitate is not None:  # the scripted user's rounds go to out_dir/imitation.json
            rounds = imitate_scripted(
                model, _wrap(users, frame_stack), users.unwrapped, imitate, imitate_steps, seed
            )
            (out_dir / "imitation.json").write_text(
                json.dumps({"teacher": imitate, "steps": imitate_steps, "rounds": rounds}, indent=2)
            )
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
    callbacks = [OneTorchThread(), checkpoints, Evaluate()]
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


class OneTorchThread(BaseCallback):
    """A callback that runs PPO's rollouts and updates on one torch thread, and gives torch its
    thread count back when training ends (or is interrupted: :meth:`restore`).

    A rollout step's forward pass (one row per user) is too small to share between threads, and
    the second thread takes a core from the env's kernels. The update's minibatches (2048 rows
    through two small MLPs) run faster on one thread than on two whose idle waits sleep
    (``OMP_WAIT_POLICY=PASSIVE``, which the env's kernels need beside other work): each of the
    update's many small parallel regions would wake a sleeping thread.
    ``benchmarks/bench_training.py`` times the loop against the default settings and checks that
    it trains the weights the default loop trains on one thread (on more, the update sums in
    another order and the last bits differ).
    """

    def __init__(self) -> None:
        import torch

        super().__init__()
        self.threads = torch.get_num_threads()

    def _on_training_start(self) -> None:
        import torch

        torch.set_num_threads(1)

    def _on_training_end(self) -> None:
        self.restore()

    def _on_step(self) -> bool:
        return True

    def restore(self) -> None:
        """Give torch its thread count back (after an interrupted run too)."""
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


def _policy_settings(frame_stack: Any, recurrent: Any, residual_on: Any = None) -> dict[str, Any]:
    """``model.vrloco_policy``: how the policy sees the env, checked."""
    from vrloco_env.wrappers import check_frame_stack

    if not isinstance(recurrent, bool | np.bool_):
        raise ValueError(f"recurrent={recurrent!r}: must be True or False")
    return {
        "frame_stack": check_frame_stack(frame_stack),
        "recurrent": bool(recurrent),
        "residual_on": residual_on,
    }


def _start_from(path: Path, policy_kwargs: dict[str, Any], spec: Any) -> tuple[Any, Any]:
    """The model at ``path`` (:func:`train_ppo`'s ``init``) and the columns of the users'
    observation (``spec``) it reads (:func:`~agents.learned.models.observation_columns`: its
    fields by name; a field the users have and it does not know is left unread).

    Raises:
        ValueError: a model that sees the env otherwise than this run (its frame stack,
            recurrence or scripted user, or a field the users lack), naming what differs.
    """
    from agents.benchmark.policies import load_ppo
    from agents.learned.models import model_policy, observation_columns

    base = load_ppo(path)
    seen = model_policy(base)
    for key in ("frame_stack", "recurrent", "residual_on"):
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
        columns = observation_columns(saved, spec)
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


def _reward_kwargs(reward: Any) -> dict[str, Any]:
    """``reward`` as :func:`env_settings`' keyword (none for None), checked."""
    from vrloco_env.config import RewardConfig

    if reward is None:
        return {}
    if not isinstance(reward, RewardConfig):
        raise ValueError(f"reward={reward!r}: must be a RewardConfig or None")
    return {"reward": reward}
