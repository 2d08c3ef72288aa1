"""Learned simulated users with RLlib: PPO on the native vector env, on several env runners.

``vrloco train --backend rllib --env-runners 2`` (:func:`train_rllib`) trains RLlib's PPO (the
new API stack: ``EnvRunner``s, an ``RLModule`` and a ``Learner``) on a task. Each env runner
steps one :class:`~vrloco_env.vector.VRLocoVectorEnv` of ``num_envs_per_env_runner`` users
(RLlib's ``VECTOR_ENTRY_POINT`` mode: the users stay batched, nothing loops over them). The
run writes ``out_dir/learning_curve.json`` and ``.png`` in the schema of the stable-baselines3
trainer (:func:`agents.learned.train.train_ppo`): the deterministic policy's success rate, collision
rate and mean return on separately seeded evaluation episodes, every ``eval_every`` environment
steps; and RLlib checkpoints (``out_dir/checkpoint``, ``out_dir/best_checkpoint``).

With your own RLlib script, :func:`register_rllib_env` registers the env creator
:func:`make_rllib_env` under :data:`ENV_NAME` (``ray.tune.registry.register_env``) and
:func:`ppo_config` gives a ``PPOConfig`` that uses it.

Seeding: RLlib resets env runner ``w``'s env once, with the seed ``config.seed + w`` (plus
1,000,000 on evaluation runners). :class:`RLlibVectorEnv` seeds row (vector index) ``i`` of that
env from ``numpy.random.SeedSequence([base, reset_seed])``'s ``i``-th 64-bit word, where
``base`` is the ``seed`` of the env config (the run's seed): every (run seed, runner, row) gets
its own 64-bit seed, where RLlib's own ``seed + w + i`` would give runner 1's second user the
first user of runner 2. With the same seed, settings and runner count, a run repeats bit for
bit. (A first reset without a seed, RLlib's without ``config.seed``, draws fresh entropy, as
gymnasium's envs do; :func:`ppo_config` always sets one.)

RLlib is an optional extra (``pip install 'vrloco[rllib]'``), imported only here.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorWrapper

from estimators.validation import check_in_range
from vrloco_env.vector import VRLocoVectorEnv

__all__ = [
    "ENV_NAME",
    "RLLIB_HINT",
    "RLlibPolicy",
    "RLlibRun",
    "RLlibVectorEnv",
    "defaults_rllib",
    "make_rllib_env",
    "ppo_config",
    "register_rllib_env",
    "train_rllib",
    "train_rllib_seeds",
]

#: The name :func:`register_rllib_env` registers :func:`make_rllib_env` under.
ENV_NAME = "vrloco"
RLLIB_HINT = (
    "--backend rllib needs RLlib: pip install 'vrloco[rllib]' in this environment "
    "(and on every machine of the cluster)"
)
#: The env config keys :func:`make_rllib_env` reads (RLlib adds ``num_envs``).
_ENV_KEYS = (
    "task",
    "sensor_preset",
    "seed",
    "num_envs",
    "max_episode_steps",
    "technique",
    "population",
    "condition",
)
#: Training iterations in a row without a sampled step after which :func:`train_rllib` stops.
MAX_IDLE_ITERATIONS = 3
#: Seeds are below 2**31 (torch's and RLlib's seeding take them).
MAX_SEED = 2**31 - 1
_SEEDS = f"an integer in [0, {MAX_SEED}]"


@dataclass(frozen=True)
class RLlibRun:
    """The sizes and seed of an RLlib run, checked: ``steps`` to sample, ``num_env_runners``
    (0: sample in the driver), ``num_envs_per_env_runner`` users batched in each runner's env,
    the run's ``seed``, ``eval_every`` steps between evaluations of ``eval_episodes`` users."""

    steps: int = 2_000_000
    num_env_runners: int = 2
    num_envs_per_env_runner: int = 16
    seed: int = 0
    eval_every: int = 100_000
    eval_episodes: int = 32

    def __post_init__(self) -> None:
        check_in_range(self, "steps", 1, 10**12, integer=True)
        check_in_range(self, "num_env_runners", 0, 10_000, integer=True)
        check_in_range(self, "num_envs_per_env_runner", 1, 1_000_000, integer=True)
        check_in_range(self, "seed", 0, MAX_SEED, integer=True, allowed=_SEEDS)
        check_in_range(self, "eval_every", 1, 10**12, integer=True)
        check_in_range(self, "eval_episodes", 1, 100_000, integer=True)


class RLlibVectorEnv(VectorWrapper):
    """A :class:`~vrloco_env.vector.VRLocoVectorEnv` as RLlib's env runners step it.

    RLlib expects gymnasium's ``NEXT_STEP`` autoreset: the step that ends a user's episode
    returns that episode's last observation, and the user's next step ignores its action and
    returns the new episode's first observation (reward 0, neither terminated nor truncated).
    The wrapped env runs with ``autoreset_mode=DISABLED``; a finished user is reset (with
    ``reset_mask``, continuing its generator) after the batched step that follows its end, so
    that step's simulation of it is discarded. Seeding: see the module docstring.

    Infos: ``is_success`` and ``collision`` per user and step.
    """

    def __init__(self, env: VRLocoVectorEnv, seed: int = 0) -> None:
        if env.autoreset_mode is not AutoresetMode.DISABLED:
            raise ValueError(
                "RLlibVectorEnv needs a VRLocoVectorEnv with autoreset_mode=AutoresetMode.DISABLED"
            )
        super().__init__(env)
        self.base_seed = seed
        check_in_range(self, "base_seed", 0, MAX_SEED, integer=True, allowed=_SEEDS)
        self.metadata = {**env.metadata, "autoreset_mode": AutoresetMode.NEXT_STEP}
        self._pending = np.zeros(env.num_envs, bool)

    def row_seeds(self, seed: int) -> list[int]:
        """Each row's seed for a reset with ``seed``: ``SeedSequence([base, seed])``'s words."""
        words = np.random.SeedSequence([self.base_seed, int(seed)]).generate_state(
            self.num_envs, np.uint64
        )
        return [int(w) for w in words]

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        if isinstance(seed, int | np.integer) and not isinstance(seed, bool):
            if seed < 0:
                raise ValueError(f"seed={seed}: must be an integer >= 0 (or a list, or None)")
            seed = self.row_seeds(int(seed))
        obs, _ = self.env.reset(seed=seed, options=options)
        self._pending[:] = False
        return obs, self._infos(np.zeros(self.num_envs, bool), np.zeros(self.num_envs, bool))

    def step(self, actions: Any):
        obs, reward, terminated, truncated, info = self.env.step(actions)
        pending = self._pending.copy()
        if pending.any():  # last step ended these users' episodes: start their next ones
            first, _ = self.env.reset(options={"reset_mask": pending})
            obs = np.where(pending[:, None], first, obs)
            reward = np.where(pending, 0.0, reward)
            terminated = terminated & ~pending
            truncated = truncated & ~pending
        self._pending = terminated | truncated
        success = np.asarray(info["is_success"], bool) & ~pending
        collision = np.asarray(info["collision"], bool) & ~pending
        return obs, reward, terminated, truncated, self._infos(success, collision)

    def _infos(self, success: np.ndarray, collision: np.ndarray) -> dict[str, np.ndarray]:
        every = np.ones(self.num_envs, bool)
        return {
            "is_success": success,
            "_is_success": every,
            "collision": collision,
            "_collision": every,
        }


def make_rllib_env(env_config: dict[str, Any]) -> RLlibVectorEnv:
    """The env creator RLlib calls (``register_env``): an :class:`RLlibVectorEnv` of
    ``env_config["num_envs"]`` users (RLlib passes ``num_envs_per_env_runner`` there in
    ``VECTOR_ENTRY_POINT`` mode) on ``task`` with the IMU preset ``sensor_preset``, in the cell
    of ``technique``, ``population`` and ``condition`` (:func:`agents.learned.models.env_settings`;
    each optional), seeded from ``seed`` (the run's seed, default 0) and RLlib's reset seed.

    Raises:
        ValueError: an unknown key or a bad value (named), or no ``num_envs`` (the env runners
            are not in ``VECTOR_ENTRY_POINT`` mode).
    """
    config = dict(env_config)
    unknown = sorted(set(config) - set(_ENV_KEYS))
    if unknown:
        raise ValueError(
            f"env_config: unknown keys {', '.join(unknown)}; allowed: {', '.join(_ENV_KEYS)}"
        )
    if "num_envs" not in config:
        raise ValueError(
            "env_config has no num_envs: RLlib passes it to a vector env creator "
            "only with .env_runners(gym_env_vectorize_mode="
            "gymnasium.VectorizeMode.VECTOR_ENTRY_POINT) (ppo_config sets it)"
        )
    num_envs = config["num_envs"]
    if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
        raise ValueError(f"env_config num_envs={num_envs!r}: must be an integer >= 1")
    from agents.learned.models import env_settings

    cell = {k: config.get(k) for k in ("sensor_preset", "technique", "population", "condition")}
    settings = env_settings(
        config.get("task", "approach"), **cell, max_episode_steps=config.get("max_episode_steps")
    )
    env = VRLocoVectorEnv(num_envs, autoreset_mode=AutoresetMode.DISABLED, **settings)
    return RLlibVectorEnv(env, seed=config.get("seed", 0))


def register_rllib_env(name: str = ENV_NAME) -> str:
    """Register :func:`make_rllib_env` with RLlib (``ray.tune.registry.register_env``) under
    ``name``; returns ``name``, for ``PPOConfig().environment(name, env_config={...})``."""
    register_env = _import_rllib("ray.tune.registry").register_env
    register_env(name, make_rllib_env)
    return name


def defaults_rllib() -> dict[str, Any]:
    """PPO's settings for ``vrloco train --backend rllib``: those of the stable-baselines3
    trainer (:func:`agents.learned.train.defaults_ppo` and SB3's PPO defaults: 64-64 tanh networks,
    clip 0.2, no KL penalty, no value clipping, value loss weight 0.5, gradients clipped to a
    global norm of 0.5) in RLlib's terms; ``rollout_fragment_length`` is SB3's ``n_steps``.
    The networks' initialisation is RLlib's (SB3: orthogonal), and the Gaussian's log-std is an
    output of the policy network (SB3: one free parameter per action)."""
    return {
        "rollout_fragment_length": 256,
        "minibatch_size": 2048,
        "num_epochs": 5,
        "gamma": 0.99,
        "lambda_": 0.95,
        "lr": 3e-4,
        "entropy_coeff": 0.0,
        "clip_param": 0.2,
        "use_kl_loss": False,
        "vf_clip_param": float("inf"),
        "vf_loss_coeff": 0.5,
        "grad_clip": 0.5,
        "grad_clip_by": "global_norm",
    }


def ppo_config(
    task: str = "approach",
    num_env_runners: int = 2,
    num_envs_per_env_runner: int = 16,
    seed: int = 0,
    sensor_preset: str | None = None,
    env_name: str = ENV_NAME,
    technique: str | None = None,
    population: str | None = None,
    condition: str | None = None,
    **ppo: Any,
) -> Any:
    """A ``PPOConfig`` on :func:`make_rllib_env` (registered as ``env_name`` by the caller or
    by :func:`train_rllib`): ``num_env_runners`` env runners (0: sample in this process) of
    ``num_envs_per_env_runner`` batched users each, a train batch of one rollout fragment per
    user, seeded with ``seed``, in the cell of ``technique``, ``population`` and ``condition``
    (:func:`agents.learned.models.env_settings`; ``sensor_preset`` None: the technique's);
    ``ppo`` overrides :func:`defaults_rllib`. Every iteration
    waits for every env runner's fragment (no ``sample_timeout_s``): RLlib's timeout would fill a
    batch from whichever runners answered in time, so a loaded machine would change the run.

    Raises:
        ValueError: a bad count or seed (named), an unknown technique, population or condition
            (listing the registered names), an unknown PPO setting, RLlib not installed.
    """
    import gymnasium as gym

    from agents.learned.models import env_settings

    cell = {"technique": technique, "population": population, "condition": condition}
    env_settings(task, sensor_preset, **cell)  # raises with the registered names
    RLlibRun(
        num_env_runners=num_env_runners, num_envs_per_env_runner=num_envs_per_env_runner, seed=seed
    )
    settings = {**defaults_rllib(), **ppo}
    unknown = sorted(set(settings) - set(defaults_rllib()))
    if unknown:
        raise ValueError(
            f"unknown PPO settings {', '.join(unknown)}; allowed: {', '.join(defaults_rllib())}"
        )
    fragment = settings.pop("rollout_fragment_length")
    if isinstance(fragment, bool) or not isinstance(fragment, int) or fragment < 1:
        raise ValueError(f"rollout_fragment_length={fragment!r}: must be an integer >= 1")
    batch = max(num_env_runners, 1) * num_envs_per_env_runner * fragment
    settings["minibatch_size"] = min(settings["minibatch_size"], batch)
    env_config = {
        "task": task,
        "seed": seed,
        **{k: v for k, v in {"sensor_preset": sensor_preset, **cell}.items() if v is not None},
    }
    ppo_mod = _import_rllib("ray.rllib.algorithms.ppo")
    model = _import_rllib("ray.rllib.core.rl_module.default_model_config")
    return (
        ppo_mod.PPOConfig()
        .environment(env_name, env_config=env_config)
        .env_runners(
            num_env_runners=num_env_runners,
            num_envs_per_env_runner=num_envs_per_env_runner,
            gym_env_vectorize_mode=gym.VectorizeMode.VECTOR_ENTRY_POINT,
            rollout_fragment_length=fragment,
            sample_timeout_s=None,  # a slow runner is waited for, not left out of the batch
        )
        .training(train_batch_size_per_learner=batch, **settings)
        .rl_module(
            model_config=model.DefaultModelConfig(
                fcnet_hiddens=[64, 64], fcnet_activation="tanh", vf_share_layers=False
            )
        )
        .debugging(seed=seed, log_level="ERROR")
        .reporting(metrics_num_episodes_for_smoothing=100)
    )


class RLlibPolicy:
    """An RLlib ``RLModule`` behind stable-baselines3's ``predict``, for
    :func:`agents.learned.evaluate.run_policy_episodes`: the deterministic action is the Gaussian's
    mean, clipped to the action space."""

    def __init__(self, module: Any) -> None:
        self.module = module
        self._dist = module.get_inference_action_dist_cls()

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        import torch

        with torch.no_grad():
            out = self.module.forward_inference({"obs": torch.as_tensor(obs)})
            dist = self._dist.from_logits(out["action_dist_inputs"])
            action = (dist.to_deterministic() if deterministic else dist).sample()
        return np.clip(action.numpy(), -1.0, 1.0), None


def train_rllib(
    task: str = "approach",
    steps: int = 2_000_000,
    num_env_runners: int = 2,
    num_envs_per_env_runner: int = 16,
    seed: int = 0,
    out_dir: Path = Path("runs/rllib"),
    sensor_preset: str | None = None,
    eval_every: int = 100_000,
    eval_episodes: int = 32,
    address: str | None = None,
    progress: bool = True,
    technique: str | None = None,
    population: str | None = None,
    condition: str | None = None,
    **ppo: Any,
) -> Path:
    """Train RLlib's PPO on ``task`` until ``steps`` environment steps are sampled (whole
    training iterations of ``num_env_runners x num_envs_per_env_runner x
    rollout_fragment_length`` steps), in the cell of ``technique``, ``population`` and
    ``condition`` (:func:`ppo_config`); returns the final checkpoint's folder.

    Ray runs where :func:`agents.benchmark.backends.run_jobs_ray` would (``address``: ``"auto"``,
    ``"HOST:PORT"``, or None: a running cluster, else a local instance, shut down at the end),
    with its errors for an unreachable address. After the first iteration and then every
    ``eval_every`` steps, the deterministic policy plays ``eval_episodes`` users seeded
    ``10_000 + seed`` (as :func:`agents.learned.train.train_ppo` evaluates) and the point goes to
    ``out_dir/learning_curve.json`` (steps, wall time, success and collision rate, mean
    return); the best one's algorithm to ``out_dir/best_checkpoint``; the end's to
    ``out_dir/checkpoint``, with ``learning_curve.png``. An env runner lost mid-run is
    restarted by RLlib (``restart_failed_env_runners``); a lost cluster is a BackendError
    naming the steps done, and so are :data:`MAX_IDLE_ITERATIONS` iterations in a row in which
    no env runner sampled (RLlib returns such iterations when every runner is down). Ctrl-C
    saves the checkpoint and the curve so far and re-raises.

    Raises:
        ValueError: a bad setting (named), RLlib not installed (:data:`RLLIB_HINT`).
        agents.benchmark.backends.BackendError: no Ray cluster at ``address``; the cluster or every
        env
            runner lost.
    """
    from agents.benchmark.backends import BackendError, _connect, _first_line
    from agents.learned.curves import plot_learning_curve
    from agents.learned.evaluate import run_policy_episodes
    from agents.learned.models import env_settings

    RLlibRun(steps, num_env_runners, num_envs_per_env_runner, seed, eval_every, eval_episodes)
    cell = {"technique": technique, "population": population, "condition": condition}
    config = ppo_config(
        task, num_env_runners, num_envs_per_env_runner, seed, sensor_preset, **cell, **ppo
    )
    ray = _import_rllib("ray")
    out_dir = Path(out_dir).resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    eval_env = VRLocoVectorEnv(eval_episodes, **env_settings(task, sensor_preset, **cell))
    try:
        started = _connect(ray, address)
    except BaseException:
        eval_env.close()
        raise
    curve: list[dict[str, float]] = []
    t_start = time.perf_counter()
    done, next_eval, best = 0, 0, -1.0
    algo = None

    def evaluate() -> None:
        nonlocal best
        policy = RLlibPolicy(algo.get_module())
        result = run_policy_episodes(policy, eval_env, seed=10_000 + seed)
        result.update(steps=done, wall_s=time.perf_counter() - t_start)
        curve.append(result)
        if result["success_rate"] > best:
            best = result["success_rate"]
            algo.save_to_path(str(out_dir / "best_checkpoint"))
        (out_dir / "learning_curve.json").write_text(json.dumps(curve, indent=2))
        if progress:
            print(
                f"{done:>12,} steps  {result['wall_s']:7.1f} s  success "
                f"{result['success_rate']:.0%}  return {result['mean_return']:.2f}"
            )

    try:
        register_rllib_env()
        algo = config.build_algo()
        idle = 0
        while done < steps:
            result = algo.train()
            before = done
            done = int(result.get("env_runners", {}).get("num_env_steps_sampled_lifetime", done))
            idle = idle + 1 if done == before else 0
            if idle >= MAX_IDLE_ITERATIONS:
                raise BackendError(
                    f"the env runners sampled nothing in {idle} training "
                    f"iterations in a row (lost, and not restarted?), after "
                    f"{done:,} of {steps:,} steps; the learning curve so far is "
                    f"in {out_dir / 'learning_curve.json'}",
                    partial=True,
                )
            if done >= next_eval or done >= steps:
                next_eval = done + eval_every
                evaluate()
        final = out_dir / "checkpoint"
        algo.save_to_path(str(final))
        plot_learning_curve(curve, out_dir / "learning_curve.png", title=f"RLlib PPO on {task}")
        return final
    except KeyboardInterrupt:
        if algo is not None:
            algo.save_to_path(str(out_dir / "checkpoint"))
        (out_dir / "learning_curve.json").write_text(json.dumps(curve, indent=2))
        print(
            f"interrupted after {done:,} steps: saved the checkpoint and the learning curve "
            f"so far in {out_dir}"
        )
        raise
    except ray.exceptions.RayError as err:
        cause = getattr(err, "cause", None)
        what = (
            f"an env runner raised {type(cause).__name__}: {_first_line(cause)}"
            if isinstance(cause, BaseException)
            else f"lost the Ray cluster ({_first_line(err)})"
        )
        raise BackendError(
            f"{what}, after {done:,} of {steps:,} steps; the learning curve so "
            f"far is in {out_dir / 'learning_curve.json'}",
            partial=True,
        ) from err
    finally:
        eval_env.close()
        if algo is not None:
            algo.stop()
        if started:
            ray.shutdown()


def train_rllib_seeds(
    task: str, seeds: list[int], out_dir: Path, address: str | None = None, **kwargs: Any
) -> list[Path]:
    """:func:`train_rllib` once per seed, one after the other (each run spreads over its own
    env runners), each in ``out_dir/seed_<s>/`` (one seed: in ``out_dir``); returns the final
    checkpoints. Several seeds' curves go together into ``out_dir/learning_curve.json`` and
    ``.png`` with the mean and std over the seeds, as :func:`agents.learned.seeds.train_seeds`
    writes them (after a failure or Ctrl-C too, from the seeds done so far)."""
    from agents.learned.curves import _read_curves, write_seed_curves

    seeds = list(seeds)
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds={seeds!r}: give at least one seed, each once")
    out_dir = Path(out_dir)
    folders = {s: out_dir if len(seeds) == 1 else out_dir / f"seed_{s}" for s in seeds}
    for s in seeds:  # every seed checked before the first run starts
        RLlibRun(seed=s)
    paths = []
    try:
        for s in seeds:
            paths.append(train_rllib(task, seed=s, out_dir=folders[s], address=address, **kwargs))
    finally:
        if len(seeds) > 1:
            curves = _read_curves(folders)
            if curves:
                write_seed_curves(task, curves, out_dir)
    return paths


def _import_rllib(module: str) -> Any:
    """``module`` (a part of Ray/RLlib), or a ValueError with :data:`RLLIB_HINT`."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as err:
        raise ValueError(f"{RLLIB_HINT} ({err})") from err
