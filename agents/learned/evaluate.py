"""A trained policy through the benchmark's metrics (``vrloco evaluate MODEL``,
:func:`evaluate_model`), and its deterministic success rate, collision rate and return on
separately seeded episodes (:func:`run_policy_episodes`, the training's evaluation).
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np

from agents.learned.models import (
    CELL_KEYS,
    cell_of,
    env_settings,
    is_recurrent,
    model_cell,
    model_env_settings,
)
from vrloco_env.vector import VRLocoVectorEnv

__all__ = ["evaluate_model"]


def run_policy_episodes(model: Any, env: VRLocoVectorEnv, seed: int) -> dict[str, float]:
    """One episode per sub-env with the deterministic policy; success, collision rate, return.
    A recurrent model (sb3-contrib's ``RecurrentPPO``) carries its LSTM state from step to step,
    each user's started afresh with its episode.

    Where ``env`` can drop users (``can_take_users``: the native vector env, frame-stacked or
    field-read or not; not with a population's variability or a mix of cells) and the model is
    feed-forward, a user whose episode has ended leaves a copy of ``env``
    (``env`` itself keeps its users), so that the rest are not slowed by finished users playing
    on; the model still acts on the whole batch, each finished user's row holding its last
    observation, so that it sees batches of the same size as without the drop and acts the same
    to the last bit. Each user's episode goes on exactly as it would have (:meth:`take_users
    <vrloco_env.vector.VRLocoVectorEnv.take_users>`): the result is the same either way."""
    recurrent = is_recurrent(model)
    drops = bool(getattr(env, "can_take_users", False)) and not recurrent
    if drops:
        env = copy.deepcopy(env)
    obs, _ = env.reset(seed=seed)
    n = env.num_envs
    seen = np.array(obs, copy=True)  # every user's row of the batch the model acts on
    rows = np.arange(n)  # the env's users, as rows of the batch
    done = np.zeros(n, bool)
    success = np.zeros(n, bool)
    collided = np.zeros(n, bool)
    returns = np.zeros(n)
    want = (n, *env.single_action_space.shape)
    state, starts = None, np.ones(n, bool)
    while not done.all():
        if recurrent:
            action, state = model.predict(
                seen, state=state, episode_start=starts, deterministic=True
            )
        else:
            action, _ = model.predict(seen, deterministic=True)
        if np.shape(action) != want:
            raise ValueError(
                f"model {type(model).__name__} returned actions of shape {np.shape(action)} "
                f"from predict(); expected {want} (one row of {want[1]} per user)"
            )
        obs, reward, terminated, truncated, info = env.step(np.asarray(action)[rows])
        ended_here = np.asarray(terminated | truncated)
        starts = np.zeros(n, bool)
        starts[rows] = ended_here
        live = ~done[rows]
        returns[rows] += np.where(live, reward, 0.0)
        collided[rows] |= live & info["collision"]
        ended = live & ended_here
        success[rows] |= ended & info["is_success"]
        done[rows] |= ended
        seen[rows] = obs
        if drops and ended.any() and not done.all():
            keep = np.flatnonzero(~done[rows])
            env.take_users(keep)
            rows = rows[keep]
    return {
        "success_rate": float(success.mean()),
        "collision_rate": float(collided.mean()),
        "mean_return": float(returns.mean()),
    }


def _cell_text(cell: dict[str, Any], sensors: str) -> str:
    """A cell in words, for messages."""
    return (
        f"task {cell['task']!r}, technique {cell['technique']!r}, population "
        f"{cell['population']!r}, condition {cell['condition']!r}, sensors "
        f"{sensors!r}"
    )


def _asked_cell(
    cell: dict[str, Any],
    sensors: str,
    task: str | None,
    technique: Any,
    population: Any,
    condition: str | None,
    sensor_preset: str | None,
) -> dict[str, tuple[Any, Any]]:
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

    def knows(k: str, v: Any) -> bool:  # a mix's model knows each of its cells
        was = trained[k] if isinstance(trained[k], list) else [trained[k]]
        return v in [w or none_is.get(k) for w in was]

    return {k: (trained[k], v) for k, v in asked.items() if not knows(k, v)}


def _settings_for(
    settings: dict[str, Any],
    task: str | None,
    technique: Any,
    population: Any,
    condition: str | None,
    sensor_preset: str | None,
) -> dict[str, Any]:
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
            raise ValueError(
                f"sensors={sensor_preset!r} contradicts technique={tech.name!r} "
                f"(sensor preset {tech.sensor_preset!r}); give one"
            )
        out["estimators"] = tech.estimators
        sensors = replace(sensors, imu=tech.sensor_preset)
    if sensor_preset is not None:
        sensors = replace(sensors, imu=sensor_preset)
    if condition is not None:
        sensors = replace(
            sensors, magnetic_disturbances=get_condition(condition).magnetic_disturbances
        )
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
    condition, and every configuration, stored with it by :func:`~agents.learned.train.train_ppo`),
    seeing the env as it was trained to (its frame stack, its recurrent state:
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
        differs = _asked_cell(here, preset, task, technique, population, condition, sensor_preset)
        if differs and not allow_mismatch:
            what = ", ".join(f"{k}={v!r} (trained: {t!r})" for k, (t, v) in differs.items())
            them = "it" if len(differs) == 1 else "them"
            raise ValueError(
                f"{what} contradicts the model, which was trained on {_cell_text(here, preset)} "
                f"({path}); leave {them} out to evaluate on the model's own cell, or allow the "
                "mismatch (--allow-mismatch) to evaluate it on the one asked for"
            )
        # a mix's model plays the cell of the mix asked for (without one: its first cell)
        mix = {k for k in ("technique", "population") if isinstance(here[k], list)}
        if differs or mix:
            if differs:
                trained_on = {**here, "sensors": preset}
            settings = _settings_for(
                settings, task, technique, population, condition, sensor_preset
            )
            played = cell_of(settings, technique)
            replaced = set(differs) | mix | ({"technique"} if "sensors" in differs else set())
            here = {k: played[k] if k in replaced else here[k] for k in CELL_KEYS}
    played_preset = settings["sensors"].preset_name
    task = settings.pop("task")
    env = gym.make(env_id(task), **settings)
    try:
        policy = LearnedPolicy(path, env, allow_mismatch=trained_on is not None)
        columns = (
            "[progress.description]{task.description}",
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
        )
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
