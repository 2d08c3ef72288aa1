"""A learned model's cell and settings: the env settings of a training cell (task, technique,
population, condition; :func:`env_settings`), stored with the model (``model.vrloco_cell``,
``model.vrloco_env``, ``model.vrloco_policy``) and read back (:func:`model_cell`,
:func:`model_env_settings`, :func:`model_policy`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "CELL_KEYS",
    "ZERO_WHEN_ABSENT",
    "ModelFields",
    "env_settings",
    "model_cell",
    "model_env_settings",
    "model_policy",
    "observation_columns",
    "observation_layout",
    "read_fields",
]


#: The names of a training cell, as :attr:`model.vrloco_cell <train_ppo>` stores them.
CELL_KEYS = ("task", "technique", "population", "condition")


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
                raise ValueError(
                    f"condition={condition!r} sets the sensors' magnetic "
                    "disturbances; give the condition or sensors=, not both"
                )
            configs["sensors"] = room_sensors
    config, sensors, estimators, room, reward = make_configs(
        sensor_preset=sensor_preset, technique=technique, population=population, **configs
    )
    return {
        "task": task,
        "config": config,
        "sensors": sensors,
        "estimators": estimators,
        "room": room,
        "reward": reward,
    }


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
    condition = next(
        (c.name for c in CONDITIONS.values() if tuple(c.magnetic_disturbances) == disturbances),
        "custom",
    )
    population = config.population
    return {
        "task": settings["task"],
        "technique": tech,
        "population": getattr(population, "name", population),
        "condition": condition,
    }


def model_env_settings(model: Any, path: Path) -> dict[str, Any]:
    """The env settings stored with a model by :func:`~agents.learned.train.train_ppo` (a clear
    error without them)."""
    settings = getattr(model, "vrloco_env", None)
    if not isinstance(settings, dict) or "task" not in settings:
        raise ValueError(
            f"{path}: the model carries no vrloco env settings (it was not saved by vrloco "
            "train); pass task= (--task) and the sensors explicitly"
        )
    return settings


def model_cell(model: Any, settings: dict[str, Any]) -> dict[str, Any]:
    """The cell a model was trained on: ``model.vrloco_cell`` as
    :func:`~agents.learned.train.train_ppo` saved it, or for a model saved without one, the cell its
    env ``settings`` make up (:func:`cell_of`)."""
    cell = getattr(model, "vrloco_cell", None)
    if isinstance(cell, dict) and all(k in cell for k in CELL_KEYS):
        return {k: cell[k] for k in CELL_KEYS}
    return cell_of(settings)


def model_policy(model: Any) -> dict[str, Any]:
    """How a model sees the env (``model.vrloco_policy``): ``frame_stack`` (frames side by side,
    1 for a model saved without it), ``recurrent`` (read from the model's policy) and
    ``residual_on`` (the scripted user whose actions it corrects,
    :mod:`agents.learned.residual`; None for a model that acts alone)."""
    saved = getattr(model, "vrloco_policy", None)
    saved = saved if isinstance(saved, dict) else {}
    return {
        "frame_stack": int(saved.get("frame_stack", 1)),
        "recurrent": is_recurrent(model),
        "residual_on": saved.get("residual_on"),
    }


def observation_layout(spec: Any) -> list[dict[str, Any]]:
    """The observation's fields as a model stores them (``model.vrloco_observation``): for each
    field of the env's :class:`~vrloco_env.observation.ObservationSpec`, in order, its ``name``,
    ``entries``, ``scale`` and ``unit``."""
    return [
        {"name": f.name, "entries": list(f.entries), "scale": float(f.scale), "unit": f.unit}
        for f in spec.fields
    ]


#: Observation fields whose absence means 0: ``head_on_torso`` (no population turns the head,
#: so it is straight on the torso).
ZERO_WHEN_ABSENT = frozenset({"head_on_torso"})


def observation_columns(saved: Any, spec: Any) -> NDArray[np.intp] | None:
    """The entries of the env's observation (``spec``) a model trained on the layout ``saved``
    (:func:`observation_layout`) reads, in the model's order: each of its fields, found by name
    wherever the env puts it. A field the env has and the model does not know (a population's
    ``head_on_torso`` for a model trained without one) is left unread; a field the model knows
    that the env lacks by definition (:data:`ZERO_WHEN_ABSENT`: ``head_on_torso`` without a
    population that turns the head, whose head is straight on the torso) reads 0, marked -1.
    None where the model stored no layout (it reads the whole observation).

    Raises:
        ValueError: one phrase naming the first field of the model that the env lacks or has
            changed (its entries, scale or unit): a stale model.
    """
    if not isinstance(saved, list):
        return None
    now = {f["name"]: f for f in observation_layout(spec)}
    columns: list[int] = []
    for old in saved:
        name = old.get("name")
        new = now.get(name)
        if new is None and name in ZERO_WHEN_ABSENT:
            columns += [-1] * len(old.get("entries", ()))
            continue
        if new is None:
            raise ValueError(
                f"the model was trained on an observation field {name!r} the env does not have"
            )
        if list(old.get("entries", ())) != new["entries"]:
            raise ValueError(
                f"observation field {name!r} has {len(new['entries'])} entries, the model was "
                f"trained on {len(old.get('entries', ()))} ({', '.join(old.get('entries', ()))})"
            )
        if old.get("scale") != new["scale"] or old.get("unit") != new["unit"]:
            raise ValueError(
                f"observation field {name!r} reads {new['scale']:g} {new['unit']} as 1, the "
                f"model was trained on {old.get('scale')!r} {old.get('unit')}"
            )
        start = spec.offset(name)
        columns += range(start, start + len(new["entries"]))
    return np.asarray(columns, dtype=np.intp)


def read_fields(obs: Any, columns: NDArray[np.intp] | None) -> NDArray[np.float32]:
    """The (B, n) observations ``obs`` as a model reads them: the entries ``columns``
    (:func:`observation_columns`; -1 reads 0), or all of them where ``columns`` is None."""
    rows = np.asarray(obs, dtype=np.float32)
    if columns is None:
        return rows
    padded = np.concatenate([rows, np.zeros((rows.shape[0], 1), np.float32)], axis=1)
    return padded[:, columns]


class ModelFields(gym.vector.VectorWrapper):
    """A vector env's observations as a model reads them: its fields by name, a field absent by
    definition as 0 (:func:`agents.learned.models.observation_columns`)."""

    def __init__(self, env: Any, columns: Any) -> None:
        super().__init__(env)
        self._columns = np.asarray(columns, dtype=np.intp)
        size = self._columns.size
        self.single_observation_space = gym.spaces.Box(-1.0, 1.0, (size,), np.float32)
        self.observation_space = gym.vector.utils.batch_space(
            self.single_observation_space, self.num_envs
        )

    def _read(self, obs: Any) -> Any:
        return read_fields(obs, self._columns)

    def reset(self, *, seed: Any = None, options: Any = None) -> tuple[Any, dict]:
        obs, info = self.env.reset(seed=seed, options=options)
        return self._read(obs), info

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict]:
        obs, reward, terminated, truncated, info = self.env.step(actions)
        if "final_obs" in info:
            info = {**info, "final_obs": self._read(info["final_obs"])}
        return self._read(obs), reward, terminated, truncated, info

    @property
    def can_take_users(self) -> bool:
        """Whether :meth:`take_users` works (the wrapped env can drop users)."""
        return bool(getattr(self.env, "can_take_users", False))

    def take_users(self, rows: Any) -> None:
        """Keep the users ``rows`` of the wrapped env (:meth:`VRLocoVectorEnv.take_users
        <vrloco_env.vector.VRLocoVectorEnv.take_users>`)."""
        self.env.take_users(rows)
        self.observation_space = gym.vector.utils.batch_space(
            self.single_observation_space, self.env.num_envs
        )
