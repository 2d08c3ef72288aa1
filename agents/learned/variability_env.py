"""A user population's human variability around a learned user in training: the vector env as a
person of that population would act in it.

:class:`HumanVariabilityEnv` wraps a :class:`~vrloco_env.vector.VRLocoVectorEnv` with the
population's :class:`agents.benchmark.variability.HumanVariability`, the same one the benchmark
puts around a user (``ppo+typical``): the learner sees each observation after the user's
reaction delay (:meth:`~agents.benchmark.variability.HumanVariability.perceive`) and its actions
reach the body with the turn overshoot and the cadence's bias and jitter
(:meth:`~agents.benchmark.variability.HumanVariability.respond`). Each user's variability is
drawn per episode from its own generator, seeded from the training seed, the user and the
episode's count. The finished episode's last observation that a vector env reports in its info
(for the value of a truncated episode) is the env's own, not delayed.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from agents.benchmark.variability import HumanVariability, VariabilityParams

__all__ = ["HumanVariabilityEnv"]


class _Learner:
    """The learned user inside the wrapper: it acts outside (through ``step``), so it only
    takes the resets."""

    name = "ppo"

    def reset(self, rng: Any = None, rows: Any = None) -> None:
        """Nothing to reset: the learner keeps its own state."""

    def act(self, obs: Any) -> Any:  # pragma: no cover - never called: the learner acts outside
        raise RuntimeError("the learner acts through HumanVariabilityEnv.step")


class HumanVariabilityEnv(gym.vector.VectorWrapper):
    """``env`` as the users of ``population`` act in it (module docstring).

    Args:
        env: the vector env (same-step autoreset).
        population: a user population with agent-side variability
            (:meth:`agents.benchmark.variability.VariabilityParams.from_population`).
        seed: the training seed the variability's generators start from.
    """

    def __init__(self, env: Any, population: str, seed: int = 0) -> None:
        super().__init__(env)
        self.population = population
        self.human = HumanVariability(
            _Learner(), VariabilityParams.from_population(population), population
        )
        self._seed = int(seed)
        self._episodes = np.zeros(self.num_envs, np.int64)

    def _generators(self, rows: np.ndarray) -> list[np.random.Generator]:
        return [
            np.random.default_rng([self._seed, 31, int(i), int(self._episodes[i])]) for i in rows
        ]

    def reset(self, *, seed: Any = None, options: Any = None) -> tuple[Any, dict]:
        obs, info = self.env.reset(seed=seed, options=options)
        if seed is not None:
            self._seed = int(np.ravel(seed)[0])
        self._episodes[:] = 0
        self.human.reset(self._generators(np.arange(self.num_envs)))
        return self.human.perceive(obs).astype(np.float32), info

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict]:
        body = self.human.respond(actions)
        obs, reward, terminated, truncated, info = self.env.step(body)
        done = np.flatnonzero(np.asarray(terminated) | np.asarray(truncated))
        if done.size:  # same-step autoreset: obs already starts the next episodes
            self._episodes[done] += 1
            self.human.reset(self._generators(done), rows=done)
        return self.human.perceive(obs).astype(np.float32), reward, terminated, truncated, info
