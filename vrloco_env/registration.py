"""Gymnasium ids of the vrloco tasks; ``import vrloco_env`` registers them.

The horizon has one source on each road into the env:

- through gymnasium's factories, gymnasium's own argument: ``gym.make(env_id,
  max_episode_steps=1000)`` and ``gym.make_vec(env_id, n, max_episode_steps=1000)`` (default:
  the ids register ``max_episode_steps=600``). ``gym.make`` ends the episode with its
  ``TimeLimit`` wrapper, so the ids' entry point, :func:`make_env`, builds an env with no horizon
  of its own; ``gym.make_vec`` hands the value to :class:`~vrloco_env.vector.VRLocoVectorEnv`.
  A ``config`` that sets another horizon is an error naming the argument to use.
- through the classes, :attr:`vrloco_env.config.EnvConfig.max_episode_steps` (or the
  ``max_episode_steps`` keyword): ``VRLocoEnv(config=EnvConfig(max_episode_steps=1000))``.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import gymnasium as gym

#: id -> task name, one per registered task (:func:`vrloco_env.tasks.register_task`).
ENV_IDS: dict[str, str] = {}


def make_env(**kwargs: Any) -> gym.Env:
    """Entry point of the ids: a :class:`~vrloco_env.env.VRLocoEnv` without a horizon of its
    own, ended by the ``TimeLimit`` that ``gym.make`` wraps around it.

    Raises:
        ValueError: the keywords set a horizon (``max_episode_steps``, or a ``config`` whose
            horizon is not the default): ``gym.make`` would never see it.
    """
    from vrloco_env.config import EnvConfig
    from vrloco_env.env import VRLocoEnv

    config = kwargs.get("config")
    given = kwargs.pop("max_episode_steps", None)
    if given is None and isinstance(config, EnvConfig):
        given = config.max_episode_steps
    if given not in (None, EnvConfig.max_episode_steps):
        raise ValueError(
            f"a horizon of {given} steps among the env's keywords: gym.make holds the horizon in "
            f"its own TimeLimit; give it as gym.make(id, max_episode_steps={given})"
        )
    if config is None or isinstance(config, EnvConfig):  # anything else: VRLocoEnv names it
        kwargs["config"] = replace(config or EnvConfig(), max_episode_steps=None)
    return VRLocoEnv(**kwargs)


def register_id(env_id: str, task: str) -> None:
    """Register the Gymnasium id ``env_id`` for task ``task`` (replacing an earlier one)."""
    from vrloco_env.config import EnvConfig

    ENV_IDS[env_id] = task
    if env_id in gym.registry:
        del gym.registry[env_id]
    gym.register(
        id=env_id,
        entry_point="vrloco_env.registration:make_env",
        vector_entry_point="vrloco_env.vector:VRLocoVectorEnv",
        max_episode_steps=EnvConfig.max_episode_steps,
        kwargs={"task": task},
    )


def register_envs() -> None:
    """Register the ids of every registered task (idempotent: importing
    :mod:`vrloco_env.tasks` registers them)."""
    import vrloco_env.tasks  # noqa: F401
