"""Users of several cells side by side in one vector env: a learned user trained on a mix of
techniques (domain randomisation over the registry) or of populations (idealised users beside
typical ones) sees every part of the mix in each rollout.

:class:`MixedUsersEnv` stacks vector envs (:class:`~vrloco_env.vector.VRLocoVectorEnv`, each
optionally inside :class:`~agents.learned.variability_env.HumanVariabilityEnv`) along the batch:
its users are the first part's, then the second's, and so on. Each part steps its own batch (a
loop over the parts, never over the users; parts in worker processes,
:class:`~agents.learned.parallel_env.RemoteUsers`, all take their actions before any is waited
for). The parts' observation fields are read by name into
one layout, the richest part's: a field a part lacks by definition (``head_on_torso`` of users
whose head stays straight on the torso, :data:`agents.learned.models.ZERO_WHEN_ABSENT`) reads 0,
any other difference is an error naming the field. Per-user info entries are stacked the same
way; an entry whose per-user width differs between parts (the step-time lists) is padded with
NaN (floats) or 0.

:func:`training_cells` reads a run's mix from its arguments (``--technique a,b`` or ``all``,
``--population idealised,typical --variability none,typical``), :func:`mixed_users` builds its
users and :func:`mix_cell` names the cell a model trained on it carries.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from agents.learned.models import observation_columns, observation_layout, read_fields

__all__ = ["MixedUsersEnv", "mix_cell", "mixed_users", "split_users", "training_cells"]


def split_users(num_envs: int, parts: int, field: str = "num_envs") -> list[int]:
    """``num_envs`` users shared as evenly as ``parts`` parts allow (the first parts take one
    more where it does not divide).

    Raises:
        ValueError: fewer users than parts (naming ``field``).
    """
    if num_envs < parts:
        raise ValueError(
            f"{field}={num_envs}: a mix of {parts} cells needs at least one user per cell "
            f"({field} >= {parts})"
        )
    base, extra = divmod(num_envs, parts)
    return [base + (i < extra) for i in range(parts)]


class MixedUsersEnv(gym.vector.VectorEnv):
    """The users of ``parts`` (vector envs with same-step autoreset and the same task and action
    space) as one vector env (module docstring).

    Args:
        parts: the vector envs, in batch order.
        names: one label per part (its cell in words), for messages and ``cells``.

    Raises:
        ValueError: no parts, a part without same-step autoreset, parts of different tasks or
            action spaces, or observation fields that cannot be read into one layout (naming
            the part and the field).
    """

    metadata: ClassVar[dict[str, Any]] = {
        "autoreset_mode": AutoresetMode.SAME_STEP,
        "render_modes": [],
    }

    def __init__(self, parts: Sequence[Any], names: Sequence[str]) -> None:
        parts = list(parts)
        if not parts or len(names) != len(parts):
            raise ValueError("MixedUsersEnv needs one or more parts and one name per part")
        self.parts = parts
        self.cells = list(names)
        cores = [p.unwrapped for p in parts]
        for name, part in zip(names, parts, strict=True):
            if part.metadata.get("autoreset_mode") != AutoresetMode.SAME_STEP:
                raise ValueError(f"part {name!r}: MixedUsersEnv needs same-step autoreset")
        tasks = {c.task_name for c in cores}
        if len(tasks) != 1:
            raise ValueError(f"a mix of cells trains one task, got {sorted(tasks)}")
        self.task_name = tasks.pop()
        #: the part whose observation fields every part's are read into
        self.richest = max(range(len(cores)), key=lambda i: len(cores[i].observation_spec.fields))
        self.observation_spec = cores[self.richest].observation_spec
        layout = observation_layout(self.observation_spec)
        self._columns = []
        for name, core in zip(names, cores, strict=True):
            try:
                self._columns.append(observation_columns(layout, core.observation_spec))
            except ValueError as err:
                raise ValueError(f"part {name!r} cannot join the mix: {err}") from None
        self.single_action_space = parts[0].single_action_space
        for name, part in zip(names, parts, strict=True):
            if part.single_action_space != self.single_action_space:
                raise ValueError(f"part {name!r} takes other actions than {names[0]!r}")
        size = int(self._columns[0].size)
        self.single_observation_space = gym.spaces.Box(-1.0, 1.0, (size,), np.float32)
        self.sizes = [p.num_envs for p in parts]
        self.num_envs = int(sum(self.sizes))
        self._bounds = np.cumsum([0, *self.sizes])
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.autoreset_mode = AutoresetMode.SAME_STEP

    def _obs(self, i: int, obs: Any) -> np.ndarray:
        return read_fields(obs, self._columns[i])

    def _info(self, infos: list[dict[str, Any]]) -> dict[str, Any]:
        """The parts' per-user info entries stacked along the batch (nested dicts, such as
        ``final_info``, entry by entry); ``final_obs`` read into the mix's layout. A part
        without an entry (no finished episode, no ``final_obs``) fills its users' rows with NaN
        (floats), False or 0; an entry that is not one row per user is left out."""
        rows = list(infos)
        if "final_obs" in {k for info in infos for k in info}:
            rows = [
                {**info, "final_obs": self._obs(i, info["final_obs"])}
                if "final_obs" in info
                else info
                for i, info in enumerate(infos)
            ]
        return self._stack(rows)

    def _stack(self, values: list[Any]) -> Any:
        """``values`` (one per part, None where a part has none) stacked along the batch; None
        where they are not one row per user."""
        present = [v for v in values if v is not None]
        if all(isinstance(v, dict) for v in present):
            out = {}
            for key in dict.fromkeys(k for v in present for k in v):
                stacked = self._stack([None if v is None else v.get(key) for v in values])
                if stacked is not None:
                    out[key] = stacked
            return out
        arrays = [None if v is None else np.asarray(v) for v in values]
        have = [a for a in arrays if a is not None]
        if any(isinstance(v, dict) for v in present) or len({a.ndim for a in have}) != 1:
            return None
        if any(
            a is not None and (a.ndim == 0 or a.shape[0] != n)
            for a, n in zip(arrays, self.sizes, strict=True)
        ):
            return None
        width = tuple(int(w) for w in np.max([a.shape[1:] for a in have], axis=0))
        dtype = np.result_type(*have)
        return np.concatenate(
            [
                _pad(a.astype(dtype, copy=False), width)
                if a is not None
                else np.full((n, *width), _fill(dtype), dtype)
                for a, n in zip(arrays, self.sizes, strict=True)
            ]
        )

    def reset(self, *, seed: Any = None, options: Any = None) -> tuple[np.ndarray, dict]:
        """Reset every part; an int ``seed`` seeds the users ``seed, seed + 1, ...`` in batch
        order (as one vector env of all of them would)."""
        mask = None if options is None else options.get("reset_mask")
        results = []
        for i, part in enumerate(self.parts):
            lo, hi = self._bounds[i], self._bounds[i + 1]
            part_seed = seed
            if isinstance(seed, int | np.integer):
                part_seed = int(seed) + int(lo)
            elif seed is not None:
                part_seed = list(seed)[lo:hi]
            part_options = None if mask is None else {"reset_mask": np.asarray(mask)[lo:hi]}
            results.append(self._call(part, "reset", seed=part_seed, options=part_options))
        results = self._wait_all(results)
        obs = np.concatenate([self._obs(i, r[0]) for i, r in enumerate(results)])
        return obs, self._info([r[1] for r in results])

    @staticmethod
    def _call(part: Any, command: str, *args: Any, **kwargs: Any) -> Any:
        """Start ``command`` on ``part``: sent to a worker's part
        (:class:`~agents.learned.parallel_env.RemoteUsers`), answered later by :meth:`_wait`;
        run at once on any other."""
        if hasattr(part, f"{command}_async") and hasattr(part, "wait"):
            getattr(part, f"{command}_async")(*args, **kwargs)
            return None
        return getattr(part, command)(*args, **kwargs)

    def _wait_all(self, started: list[Any]) -> list[Any]:
        """Every part's answer (a worker's, waited for); an error in one is raised after all
        have answered, so that no answer is left in a pipe."""
        results, error = [], None
        for part, result in zip(self.parts, started, strict=True):
            try:
                results.append(part.wait() if result is None else result)
            except Exception as err:
                error = error or err
        if error is not None:
            raise error
        return results

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        actions = np.asarray(actions)
        started = [
            self._call(part, "step", actions[self._bounds[i] : self._bounds[i + 1]])
            for i, part in enumerate(self.parts)
        ]
        results = self._wait_all(started)
        obs = np.concatenate([self._obs(i, r[0]) for i, r in enumerate(results)])
        reward, terminated, truncated = (
            np.concatenate([np.asarray(r[k]) for r in results]) for k in (1, 2, 3)
        )
        return obs, reward, terminated, truncated, self._info([r[4] for r in results])

    def close(self, **kwargs: Any) -> None:
        for part in self.parts:
            part.close()


def _pad(rows: np.ndarray, width: tuple[int, ...]) -> np.ndarray:
    """``rows`` padded at the end of each trailing axis to ``width`` (NaN for floats, False or
    0 otherwise)."""
    if rows.shape[1:] == width:
        return rows
    pad = [(0, 0)] + [(0, w - s) for s, w in zip(rows.shape[1:], width, strict=True)]
    return np.pad(rows, pad, constant_values=_fill(rows.dtype))


def _fill(dtype: Any) -> Any:
    """What an absent entry reads: NaN for floats, else 0 (False)."""
    return np.nan if np.issubdtype(dtype, np.floating) else 0


def training_cells(
    technique: Any = None, population: Any = None, variability: Any = None
) -> list[tuple[Any, Any, str | None]]:
    """The cells a run trains on, ``(technique, population, variability)`` each: one, or a mix
    whose users share the batch (:class:`MixedUsersEnv`).

    ``technique``: one (a name, ``"module:attr"``, a Technique or None), several (a list, or
    names joined by commas) or ``"all"`` (every registered technique). ``population``: one or
    several the same way (None or ``"none"``: no population). ``variability``: one population
    whose human variability every user has, or one per population (None or ``"none"``: none).
    The cells are every technique with every population (and its variability).

    Raises:
        ValueError: an unknown name (the registry's error, listing the registered names), a
            name given twice, or a variability list whose length is not the populations'.
    """
    from vrloco_env.techniques import TECHNIQUES, get_technique
    from vrloco_env.user.population import get_population

    techniques = _names(technique, "technique")
    if techniques == ["all"]:
        techniques = list(TECHNIQUES)
    for t in techniques:
        if t is not None:
            get_technique(t)
    populations = _names(population, "population")
    for p in populations:
        if p is not None:
            get_population(p)
    variabilities = _names(variability, "variability")
    if len(variabilities) == 1:
        variabilities = variabilities * len(populations)
    if len(variabilities) != len(populations):
        raise ValueError(
            f"variability: give one population, or one per population ({len(populations)}: "
            f"{', '.join(str(p) for p in populations)}), got {len(variabilities)}"
        )
    for v in variabilities:
        if v is not None:
            get_population(v, "variability")
    return [(t, p, v) for t in techniques for p, v in zip(populations, variabilities, strict=True)]


def _names(value: Any, field: str) -> list[Any]:
    """``value`` as a list: a list as it is, a string split at commas (``"none"`` read as None),
    anything else alone; a name given twice is an error naming ``field``."""
    if isinstance(value, str):
        value = [v.strip() for v in value.split(",")]
    elif not isinstance(value, list | tuple):
        value = [value]
    out = [None if v in ("none", "") else v for v in value]
    keys = [getattr(v, "name", v) for v in out]
    twice = sorted({str(k) for k in keys if keys.count(k) > 1})
    if twice:
        raise ValueError(f"{field}: {', '.join(twice)} given more than once")
    return out


def mix_cell(cells: list[tuple[Any, Any, str | None]]) -> dict[str, Any]:
    """The ``technique`` and ``population`` of a mix's cell: the one name every cell shares, or
    the list of its names (techniques by their registered name; no population as None)."""
    from vrloco_env.techniques import get_technique

    def once(values: list[Any]) -> Any:
        unique = list(dict.fromkeys(values))
        return unique[0] if len(unique) == 1 else unique

    return {
        "technique": once([None if t is None else get_technique(t).name for t, _, _ in cells]),
        "population": once([getattr(p, "name", p) for _, p, _ in cells]),
    }


def mixed_users(
    num_envs: int,
    task: str,
    sensor_preset: str | None,
    cells: list[tuple[Any, Any, str | None]],
    condition: str | None,
    reward: Any,
    seed: int,
    field: str = "num_envs",
) -> Any:
    """``num_envs`` users shared between ``cells`` (:func:`training_cells`) as one vector env
    (:class:`MixedUsersEnv`); each cell's users with its
    variability, seeded from ``seed`` and the cell's first user."""
    from agents.learned.models import env_settings
    from agents.learned.variability_env import HumanVariabilityEnv
    from vrloco_env.vector import VRLocoVectorEnv

    configs = {} if reward is None else {"reward": reward}
    parts, names, first = [], [], 0
    for n, (tech, pop, var) in zip(split_users(num_envs, len(cells), field), cells, strict=True):
        users = VRLocoVectorEnv(
            n, **env_settings(task, sensor_preset, tech, pop, condition, **configs)
        )
        parts.append(users if var is None else HumanVariabilityEnv(users, var, seed + first))
        names.append(f"{tech or 'default'}/{getattr(pop, 'name', pop)}/{var}")
        first += n
    return MixedUsersEnv(parts, names)
