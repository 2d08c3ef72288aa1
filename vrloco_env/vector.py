"""The native vector env: N users stepped together, one batched call per stage.

``gym.make_vec("vrloco_env:VRLoco-Approach-v0", num_envs=N)`` builds it (the ids register it as
their ``vector_entry_point``). The motion model, the sensor models, the estimators and the world
queries all run once per step for the N users (:class:`~vrloco_env.core.LocoCore`); nothing loops
over the sub-envs in Python on the step path.

Autoreset: by default ``SAME_STEP`` — a sub-env whose episode ends in a step is reset within
that step; the returned observation is the new episode's first one, and the last observation of
the finished episode is in ``infos["final_obs"]`` (with ``infos["final_info"]``), as
stable-baselines3's own vector envs do. ``autoreset_mode=AutoresetMode.DISABLED`` leaves finished
sub-envs to the caller, who resets them with ``reset(seed=[...], options={"reset_mask": mask})``
(gymnasium's convention): the benchmark's batched runner gives each finished user the next seed
of its cell that way. A finished sub-env that is not reset keeps being simulated; its numbers
mean nothing until its next reset.

Seeding: ``reset(seed=s)`` seeds sub-env i with ``s + i``, so sub-env i behaves exactly like a
single env reset with ``seed=s + i`` and reset again after each of its episodes; ``seed=[...]``
gives each sub-env its own seed (None: keep its generator).

Copies. ``copy.deepcopy(envs)``, ``pickle`` and ``copy.copy(envs)`` (a deep copy too: a shallow
one would share the users and their random streams) give a vector env that goes on exactly as the
original, bit for bit, mid-episode as well.
"""

from __future__ import annotations

import copy
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from vrloco_env.actions import ACTION_SIZE
from vrloco_env.core import LocoCore
from vrloco_env.env import make_configs, technique_name
from vrloco_env.techniques import get_technique

__all__ = ["VRLocoVectorEnv"]


class VRLocoVectorEnv(VectorEnv):
    """N simulated users, batched. Arguments as :class:`~vrloco_env.env.VRLocoEnv` plus
    ``num_envs``; rendering is not supported (render a single env instead)."""

    metadata: ClassVar[dict[str, Any]] = {
        "autoreset_mode": AutoresetMode.SAME_STEP,
        "render_modes": [],
    }
    _AUTORESET_MODES = (AutoresetMode.SAME_STEP, AutoresetMode.DISABLED)

    def __init__(
        self,
        num_envs: int = 1,
        task: str = "approach",
        render_mode: str | None = None,
        task_config: Any = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.SAME_STEP,
        **config: Any,
    ) -> None:
        """``config``: the configuration keywords of :func:`~vrloco_env.env.make_configs`
        (``config``, ``sensors``, ``estimators``, ``room``, ``reward``, ``sensor_preset``,
        ``locomotion``, ``max_episode_steps``, ``pose_source``, ``technique``,
        ``population``), as for the single env. ``autoreset_mode``: ``SAME_STEP`` or
        ``DISABLED`` (see the module docstring)."""
        if render_mode is not None:
            raise ValueError("VRLocoVectorEnv does not render; use gym.make(...) for pictures")
        modes = {m.value: m for m in self._AUTORESET_MODES}
        mode = modes.get(getattr(autoreset_mode, "value", autoreset_mode))
        if mode is None:
            raise ValueError(
                f"autoreset_mode={autoreset_mode!r}: must be one of "
                f"{', '.join(f'AutoresetMode.{m.name}' for m in self._AUTORESET_MODES)}"
            )
        self.autoreset_mode = mode
        self.metadata = {**self.metadata, "autoreset_mode": mode}
        cfgs = make_configs(**config)
        self.config, self.sensors, self.estimators, self.room, self.reward = cfgs
        #: the technique's name (``"custom"`` for an unregistered combination)
        self.technique = (
            technique_name(self.sensors, self.estimators)
            if config.get("technique") is None
            else get_technique(config["technique"]).name
        )
        self.num_envs = int(num_envs)
        self.core = LocoCore(task, self.num_envs, *cfgs, task_config=task_config)
        self.observation_spec = self.core.spec
        self.task_name = task
        self.single_action_space = spaces.Box(-1.0, 1.0, (ACTION_SIZE,), np.float32)
        self.single_observation_space = spaces.Box(-1.0, 1.0, (self.core.obs_size,), np.float32)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._started = False

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict]:
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, int | np.integer):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(f"seed must be an int or a list of {n} seeds, got {len(seeds)}")
        if options is not None and not isinstance(options, dict):
            raise ValueError(
                f"options={options!r}: must be None or a dict (key 'reset_mask': a boolean "
                f"array of shape ({n},))"
            )
        unknown = sorted(map(repr, set(options or {}) - {"reset_mask"}))
        if unknown:
            raise ValueError(
                f"options: unknown key(s) {', '.join(unknown)}; the one option is 'reset_mask' "
                f"(a boolean array of shape ({n},))"
            )
        mask = (options or {}).get("reset_mask")
        rows = None
        if mask is not None:
            mask = np.asarray(mask)
            if mask.dtype != np.bool_ or mask.shape != (n,):
                raise ValueError(
                    f"options['reset_mask'] must be a boolean array of shape ({n},), got "
                    f"{mask.dtype} {mask.shape}"
                )
            if not self._started and not mask.all():
                raise ValueError("the first reset() must reset every sub-env (no reset_mask)")
            rows = np.flatnonzero(mask)
            if rows.size == 0:
                raise ValueError("options['reset_mask'] selects no sub-env to reset")
        if seed is not None and rows is None:
            self._np_random, self._np_random_seed = seeding.np_random(seeds[0])
        for i, s in enumerate(seeds):
            if (s is not None or not self._started) and (rows is None or mask[i]):
                self.core.generators[i] = seeding.np_random(s)[0]
        obs = self.core.reset(rows)
        self._started = True
        ep = self.core.ep
        return obs, {
            "distance_to_goal": ep.distance.copy(),
            "shortest_path": ep.shortest.copy(),
            "position": ep.position.copy(),
            "step_report_delay_s": np.full(n, self.core.step_report_delay_s),
        }

    def step(
        self, actions: Any
    ) -> tuple[
        NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict
    ]:
        if not self._started:
            raise RuntimeError("reset() must be called before step()")
        obs, reward, terminated, truncated, infos = self.core.step(actions)
        done = terminated | truncated
        if self.autoreset_mode is AutoresetMode.SAME_STEP and np.any(done):
            rows = np.flatnonzero(done)
            infos["final_obs"] = np.where(done[:, None], obs, 0.0).astype(np.float32)
            infos["final_info"] = {k: v for k, v in infos.items() if k != "final_obs"}
            infos["_final_obs"] = done.copy()
            infos["_final_info"] = done.copy()
            obs = self.core.reset(rows)
        return obs, reward, terminated, truncated, infos

    @property
    def can_take_users(self) -> bool:
        """Whether :meth:`take_users` works (every part of the users' pipeline can drop users)."""
        return self.core.can_take_users

    def take_users(self, rows: Any) -> None:
        """Keep the sub-envs ``rows`` (distinct indices, in their new order) and drop the others
        (:meth:`~vrloco_env.core.LocoCore.take_users`): ``num_envs`` becomes ``len(rows)``, and
        each kept sub-env goes on exactly as it would have. Meant for a runner with autoreset
        disabled whose remaining users are fewer than the batch."""
        self.core.take_users(rows)
        self.num_envs = self.core.batch_size
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)

    def close_extras(self, **kwargs: Any) -> None:
        pass

    def __copy__(self) -> VRLocoVectorEnv:
        """A deep copy (:func:`copy.deepcopy`): a shallow one would share the users and their
        random streams with this env, so that stepping either moved both."""
        return copy.deepcopy(self)
