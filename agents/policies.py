"""Simulated users for the benchmark, by name: scripted, learned, or your own.

A policy spec is one of

* a scripted user of :data:`agents.scripted.POLICIES` (``goal_seeker``, ``avoid_manoeuvre``,
  ``reactive_avoider``);
* ``"package.module:attr"`` or ``"path/to/file.py:attr"`` naming a class or factory called as
  ``factory(env)`` that returns an object with the :class:`~agents.scripted.Policy` protocol
  (``reset(rng=None, rows=None)``, ``act(obs) -> action``);
* the path of a stable-baselines3 PPO model (``.zip``), played with its deterministic policy;

each optionally followed by ``+<population>`` for the agent-side variability of a user population
(:mod:`vrloco_env.user.population`) through :class:`agents.variability.HumanVariability`
(reaction delay, turn overshoot, cadence bias and jitter): ``+human`` as it always was,
``+typical``, ``+gaze_scanners``, ``+nodders``; ``+idealised`` leaves the policy as it is. The
population's head behaviour is the env's (``gym.make(..., population="typical")``); give both
for the whole population.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from agents.scripted import POLICIES, ObservationLayout, make_policy, params_from_env
from agents.variability import HumanVariability, VariabilityParams
from estimators.batching import TakesUsers
from vrloco_env.user.population import POPULATIONS

__all__ = ["HUMAN_SUFFIX", "LearnedPolicy", "build_policy", "check_policy", "env_population"]

HUMAN_SUFFIX = "+human"


def _split(spec: str) -> tuple[str, str | None]:
    """The policy's base spec and its population suffix's name (None without one)."""
    if not isinstance(spec, str) or not spec:
        raise ValueError(f"policy={spec!r}: must be a non-empty string")
    base, sep, suffix = spec.rpartition("+")
    if not sep or not base or not suffix.isidentifier():  # no suffix ("my+model.zip")
        return spec, None
    if suffix not in POPULATIONS:
        raise ValueError(
            f"policy={spec!r}: unknown population {suffix!r} after '+'; must be one of "
            f"{', '.join(POPULATIONS)}"
        )
    return base, suffix


def env_population(spec: str) -> str | None:
    """The env-side population of a policy spec: its ``+<population>`` suffix where that
    population acts on the simulated body (gaze, nods, bob: ``Population.moves_head``), else
    None — the env of a ``+human`` or ``+idealised`` user is the default env, bit for bit."""
    _, population = _split(spec)
    if population is None or not POPULATIONS[population].moves_head:
        return None
    return population


def check_policy(spec: str) -> str:
    """``spec`` if it names a policy (see the module docstring), else a ValueError saying what
    is allowed. Checks what can be checked without an env: a scripted name, an existing model
    file, an importable ``module:attr``."""
    base, _ = _split(spec)
    if base in POLICIES:
        return spec
    if base.endswith(".zip"):
        if not Path(base).is_file():
            raise ValueError(f"policy={spec!r}: no such model file {base!r}")
        return spec
    if ":" in base:
        from estimators.registry import load_attr

        try:
            obj = load_attr(base, "policy")
        except ValueError as err:
            raise ValueError(str(err)) from None
        if not callable(obj):
            raise ValueError(
                f"policy={spec!r} names a {type(obj).__name__}, not a class or factory"
            )
        return spec
    raise ValueError(
        f"policy={spec!r}: must be one of {', '.join(POLICIES)}, a stable-baselines3 model "
        f"(.zip) or 'package.module:attr', optionally with '+<population>' "
        f"({', '.join(POPULATIONS)}; e.g. goal_seeker{HUMAN_SUFFIX})"
    )


class LearnedPolicy(TakesUsers):
    """A saved stable-baselines3 PPO model as a policy (deterministic actions).

    Args:
        path: the model's ``.zip``.
        env: the env it will play; a model that ``vrloco train`` saved carries its task, which
            must be the env's, and its observation size must be the env's.
    """

    batched = True  # act() takes (B, n) rows, one at a time (see act)
    per_user_fields = ()  # a feed-forward model keeps nothing per user: a batch may drop users

    def __init__(self, path: str | Path, env: Any) -> None:
        self.path = Path(path)
        self.name = f"ppo:{self.path.name}"
        self.model = _load_ppo(str(self.path.resolve()))
        settings = getattr(self.model, "vrloco_env", None)
        task = getattr(env.unwrapped, "task_name", None)
        if isinstance(settings, dict) and task is not None and settings.get("task") != task:
            raise ValueError(
                f"policy {str(self.path)!r} was trained on task {settings.get('task')!r}, not "
                f"{task!r}"
            )
        want = env.unwrapped.observation_space.shape[-1:]
        have = self.model.observation_space.shape
        if have != want:
            raise ValueError(
                f"policy {str(self.path)!r} takes observations of shape {have}, the env gives "
                f"{want}"
            )

    def reset(self, rng: Any = None, rows: ArrayLike | None = None) -> None:
        """Stateless (a feed-forward policy): nothing to reset."""

    def act(self, obs: ArrayLike) -> NDArray[np.float32]:
        """Deterministic actions for ``obs``, (obs,) or (B, obs). A batch is evaluated one row
        at a time: torch's matrix kernels round differently for different batch sizes, and an
        episode must not depend on how many users it was batched with."""
        x = np.asarray(obs, dtype=np.float32)
        if x.ndim == 1:
            action, _ = self.model.predict(x, deterministic=True)
            return np.asarray(action, dtype=np.float32)
        rows = [self.model.predict(row, deterministic=True)[0] for row in x]
        return np.asarray(rows, dtype=np.float32).reshape(x.shape[0], -1)


@functools.lru_cache(maxsize=8)
def _load_ppo(path: str) -> Any:
    """A PPO model, loaded once per process (the policy is stateless)."""
    from stable_baselines3 import PPO

    return PPO.load(path)


def build_policy(spec: str, env: Any) -> Any:
    """The policy ``spec`` names, built for ``env`` (see the module docstring)."""
    check_policy(spec)
    base, population = _split(spec)
    policy: Any
    if base in POLICIES:
        policy = make_policy(base, ObservationLayout.from_env(env), params_from_env(env))
    elif base.endswith(".zip"):
        policy = LearnedPolicy(base, env)
    else:
        from estimators.registry import load_attr

        policy = load_attr(base, "policy")(env)
        for method in ("reset", "act"):
            if not callable(getattr(policy, method, None)):
                raise ValueError(
                    f"policy={spec!r} built a {type(policy).__name__} without a {method}() "
                    "method (a policy has reset(rng=None, rows=None) and act(obs))"
                )
    if population is None or not POPULATIONS[population].variability:
        return policy
    params = VariabilityParams.from_population(population)
    return HumanVariability(policy, params, population=population)
