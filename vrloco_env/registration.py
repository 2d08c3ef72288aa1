"""Gymnasium ids of the vrloco tasks; ``import vrloco_env`` registers them.

The episode horizon has one source of truth, :attr:`vrloco_env.config.EnvConfig.max_episode_steps`:
the env truncates its own episodes, so the ids register no ``TimeLimit`` of their own. Both
spellings set it::

    gym.make(env_id, max_episode_steps=1000)                    # gymnasium's own argument
    gym.make(env_id, config=EnvConfig(max_episode_steps=1000))  # the env's configuration

``gym.make`` consumes its ``max_episode_steps`` argument itself (it wraps the env in a
``TimeLimit`` and never passes the value on), so the ids' entry point, :func:`make_env`, reads it
from the ``gym.make`` call that is building the env and makes it the env's horizon: the env and
gymnasium's wrapper then end the episode on the same step. A ``config`` whose horizon contradicts
that argument is an error. ``gym.make_vec`` passes ``max_episode_steps`` to the env as a keyword
in every vectorization mode, with the same effect.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from typing import Any

import gymnasium as gym

#: id -> task name, one per registered task (:func:`vrloco_env.tasks.register_task`).
ENV_IDS: dict[str, str] = {}


def _gym_make_horizon(frame: Any) -> int | None:
    """The ``TimeLimit`` horizon that the ``gym.make`` call in ``frame`` applies (None if the
    frame is not ``gym.make``'s or it applies none)."""
    from gymnasium.envs import registration as gym_registration

    if frame is None or frame.f_code is not gym_registration.make.__code__:
        return None
    local = frame.f_locals
    limit = local.get("max_episode_steps")
    if limit == -1:  # gymnasium's "no TimeLimit"
        return None
    if limit is None:
        spec = local.get("env_spec")
        limit = getattr(spec, "max_episode_steps", None)
    return limit


def make_env(**kwargs: Any) -> gym.Env:
    """Entry point of the ids: a :class:`~vrloco_env.env.VRLocoEnv` whose horizon is the
    ``max_episode_steps`` of the ``gym.make`` call building it, if that call gives one."""
    from vrloco_env.config import EnvConfig
    from vrloco_env.env import VRLocoEnv

    limit = _gym_make_horizon(sys._getframe(1))
    if limit is not None:
        if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
            raise ValueError(f"max_episode_steps={limit!r}: must be an integer >= 1 (or -1)")
        config = kwargs.get("config")
        if kwargs.get("max_episode_steps") not in (None, limit):
            raise ValueError(
                f"max_episode_steps={limit} contradicts max_episode_steps="
                f"{kwargs['max_episode_steps']} among the env's keywords; give one"
            )
        if isinstance(config, EnvConfig):
            default = EnvConfig.__dataclass_fields__["max_episode_steps"].default
            if config.max_episode_steps not in (default, limit):
                raise ValueError(
                    f"gym.make(..., max_episode_steps={limit}) contradicts "
                    f"config=EnvConfig(max_episode_steps={config.max_episode_steps}); give one"
                )
            kwargs["config"] = replace(config, max_episode_steps=limit)
        else:
            kwargs["max_episode_steps"] = limit
    return VRLocoEnv(**kwargs)


def register_id(env_id: str, task: str) -> None:
    """Register the Gymnasium id ``env_id`` for task ``task`` (replacing an earlier one)."""
    ENV_IDS[env_id] = task
    if env_id in gym.registry:
        del gym.registry[env_id]
    gym.register(
        id=env_id,
        entry_point="vrloco_env.registration:make_env",
        vector_entry_point="vrloco_env.vector:VRLocoVectorEnv",
        kwargs={"task": task},
    )


def register_envs() -> None:
    """Register the ids of every registered task (idempotent: importing
    :mod:`vrloco_env.tasks` registers them)."""
    import vrloco_env.tasks  # noqa: F401
