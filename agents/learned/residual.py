"""A learned user that corrects a scripted user: the scripted user's action plus the learner's.

Residual policy learning (Silver, Allen, Tenenbaum & Kaelbling 2018, "Residual policy learning";
Johannink et al. 2019, "Residual reinforcement learning for robot control"): the user acts as a
scripted user would (the goal seeker: a map, a route, the walk gate) and the learned policy adds
a correction, ``action = clip(scripted + RESIDUAL_SCALE * clip(correction, -1, 1), -1, 1)``. It
sees what it corrects: the scripted user's action is one more observation field
(:func:`with_scripted_action`, named after the scripted user). Its correction starts at zero
(:func:`zero_correction`), so before training the learned user *is* the scripted user, action
for action; training changes what the scripted user does where that pays, as a person who knows
how to walk to a goal learns a technique's quirks (a stop that lands late, a head that steers).

:class:`ScriptedPlusCorrection` is the training side (a vector env wrapper); the benchmark plays
such a model with :class:`~agents.benchmark.policies.LearnedPolicy`, which runs the same
scripted user beside it (``model.vrloco_policy["residual_on"]``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from vrloco_env.actions import ACTION_NAMES, ACTION_SIZE
from vrloco_env.observation import Field, ObservationSpec

__all__ = [
    "RESIDUAL_LOG_STD",
    "RESIDUAL_SCALE",
    "VALUE_STEPS",
    "ScriptedPlusCorrection",
    "check_residual",
    "combine",
    "fit_values",
    "scripted_field",
    "with_scripted_action",
    "zero_correction",
]

#: How far the learner's correction (in [-1, 1]) moves the scripted user's action: 2, the least
#: with which any action in [-1, 1] can be reached from any scripted action (a standing user's
#: walk of -1 can become a walk of 1, a walking one's a stop).
RESIDUAL_SCALE = 2.0


def scripted_field(name: str) -> Field:
    """The observation field holding the scripted user ``name``'s action: one entry per action
    (``goal_seeker_walk``, ``goal_seeker_turn``, ...), as the env reads an action (in [-1, 1])."""
    return Field(
        f"{name}_action",
        tuple(f"{name}_{a}" for a in ACTION_NAMES),
        1.0,
        "",
        f"the action the scripted user {name} takes now, which the learner corrects",
    )


def with_scripted_action(spec: ObservationSpec, name: str) -> ObservationSpec:
    """``spec`` with the scripted user ``name``'s action appended (:func:`scripted_field`)."""
    return ObservationSpec((*spec.fields, scripted_field(name)))


def combine(scripted: NDArray[np.floating], correction: Any) -> NDArray[np.float32]:
    """The user's action: ``clip(scripted + RESIDUAL_SCALE * clip(correction, -1, 1), -1, 1)``,
    float32, (B, 5)."""
    c = np.minimum(np.maximum(np.asarray(correction, dtype=np.float32), -1.0), 1.0)
    a = np.asarray(scripted, dtype=np.float32) + np.float32(RESIDUAL_SCALE) * c
    return np.minimum(np.maximum(a, -1.0), 1.0)


def check_residual(residual_on: Any, recurrent: bool = False, env_workers: int = 1) -> None:
    """Whether a run can learn a correction of the scripted user ``residual_on``: a registered
    scripted user, a feed-forward policy, stepped in this process (the scripted user is built
    from the env it acts in; a mix of techniques has one per technique's body,
    :class:`~agents.learned.imitation.BodyTeachers`).

    Raises:
        ValueError: naming what stands in the way (an unknown name lists the scripted users).
    """
    from agents.scripted import POLICIES

    if not isinstance(residual_on, str) or residual_on not in POLICIES:
        raise ValueError(
            f"residual_on={residual_on!r}: not a scripted user; choose from "
            f"{', '.join(sorted(POLICIES))}"
        )
    if recurrent:
        raise ValueError(f"residual_on={residual_on!r} trains a feed-forward policy")
    if env_workers > 1:
        raise ValueError(
            f"residual_on={residual_on!r} trains users stepped in this process (env_workers=1)"
        )


def zero_correction(model: Any) -> None:
    """Set ``model``'s (a stable-baselines3 PPO) mean action to 0 for every observation, in
    place: its last actor layer's weights and biases zeroed, so the user starts as the scripted
    user. The hidden layers keep their random start, so gradients reach them."""
    import torch

    with torch.no_grad():
        model.policy.action_net.weight.zero_()
        model.policy.action_net.bias.zero_()


class ScriptedPlusCorrection(gym.vector.VectorWrapper):
    """Users who act as ``teacher`` does plus the policy's correction (:func:`combine`).

    The observation is the wrapped env's with the scripted user's action for it appended
    (:func:`with_scripted_action`; ``observation_spec`` says so); the action is the correction.
    The scripted user sees the wrapped env's observation and keeps its own memory, started
    afresh for every user whose episode ends (same-step autoreset). A finished episode's
    ``final_obs`` carries the scripted action its last step took.

    Args:
        env: the users (a vector env with ``observation_spec``, same-step autoreset).
        teacher: a batched scripted user for them
            (:func:`~agents.learned.imitation.scripted_teacher`).
        name: the scripted user's name (the field's).
        spec: the wrapped env's observation spec (its ``observation_spec`` where omitted).
    """

    def __init__(self, env: Any, teacher: Any, name: str, spec: Any = None) -> None:
        super().__init__(env)
        self.teacher = teacher
        self.name = name
        spec = env.observation_spec if spec is None else spec
        self.observation_spec = with_scripted_action(spec, name)
        size = self.observation_spec.size
        self.single_observation_space = gym.spaces.Box(-1.0, 1.0, (size,), np.float32)
        self.observation_space = gym.vector.utils.batch_space(
            self.single_observation_space, self.num_envs
        )
        self._scripted: NDArray[np.float32] | None = None  # (B, 5): the scripted action now

    def _seen(self, obs: Any) -> NDArray[np.float32]:
        self._scripted = np.asarray(self.teacher.act(obs), dtype=np.float32).reshape(
            -1, ACTION_SIZE
        )
        return np.concatenate([np.asarray(obs, np.float32), self._scripted], axis=1)

    def reset(self, *, seed: Any = None, options: Any = None) -> tuple[Any, dict]:
        obs, info = self.env.reset(seed=seed, options=options)
        self.teacher.reset()
        return self._seen(obs), info

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict]:
        if self._scripted is None:
            raise RuntimeError("reset the env before stepping it")
        last = self._scripted
        obs, reward, terminated, truncated, info = self.env.step(combine(last, actions))
        done = np.asarray(terminated | truncated)
        if done.any():
            self.teacher.reset(rows=np.flatnonzero(done))
        if "final_obs" in info:
            final = np.asarray(info["final_obs"], np.float32)
            info = {**info, "final_obs": np.concatenate([final, last], axis=1)}
        return self._seen(obs), reward, terminated, truncated, info

    @property
    def can_take_users(self) -> bool:
        """Whether :meth:`take_users` works (the wrapped env can drop users)."""
        return bool(getattr(self.env, "can_take_users", False))

    def take_users(self, rows: Any) -> None:
        """Keep the users ``rows`` of the wrapped env, the scripted user's memory of them and
        its actions for them."""
        rows = np.asarray(rows, dtype=np.intp)
        self.env.take_users(rows)
        self.teacher.take_users(rows)
        if self._scripted is not None:
            self._scripted = self._scripted[rows]
        self.observation_space = gym.vector.utils.batch_space(
            self.single_observation_space, self.env.num_envs
        )


#: The correction's starting log standard deviation (PPO's exploration): e ** -2 ~ 0.14, so 0.27
#: on the action after :data:`RESIDUAL_SCALE`. A choice: exploration around the scripted user
#: that seldom flips its walk gate (walk 0.5 stands below 0), rather than SB3's default e ** 0.
RESIDUAL_LOG_STD = -2.0

#: Environment steps the scripted user plays before PPO starts, to fit the value function to its
#: returns (:func:`fit_values`), so that the first advantages are not an untrained critic's. A
#: choice.
VALUE_STEPS = 100_000


def fit_values(model: Any, env: Any, steps: int, seed: int) -> dict[str, float]:
    """Fit ``model``'s value function (in place) to the discounted returns of the episodes its
    deterministic policy plays in ``env`` (the wrapped users) over ``steps`` environment steps
    (every user's counted); the policy is not changed. Returns the episodes, their success and
    collision rates."""
    import torch

    from agents.learned.imitation import EpisodeTally, _fit_values

    n = env.num_envs
    per_user = -(-steps // n)
    width = env.single_observation_space.shape[0]
    seen = np.empty((per_user, n, width), np.float32)
    rewards = np.empty((per_user, n))
    ends = np.empty((per_user, n), bool)
    tally = EpisodeTally(n)
    obs, _ = env.reset(seed=seed)
    policy = model.policy
    for t in range(per_user):
        seen[t] = obs
        with torch.no_grad():
            action, _, _ = policy(torch.as_tensor(obs, device=policy.device), deterministic=True)
        obs, reward, terminated, truncated, info = env.step(action.cpu().numpy())
        done = terminated | truncated
        rewards[t], ends[t] = reward, done
        tally.add(done, info)
    optimiser = torch.optim.Adam(policy.parameters(), lr=1e-3)
    rng = np.random.default_rng(seed)
    _fit_values(policy, optimiser, seen, rewards, ends, float(model.gamma), 10, 2048, rng)
    return {"steps": per_user * n, **tally.rates()}
