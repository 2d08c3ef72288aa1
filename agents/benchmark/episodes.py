"""Playing a cell's episodes: one alone in a single env, or many as users of one vector env.

:func:`run_episode` plays one episode of a policy in a single env; :func:`run_cell_episode` does so
for a grid cell (:class:`agents.benchmark.grid.Cell`: its task, technique, population and
condition's env, kept per process, and its policy). :func:`run_batched` plays episodes of cells that
share a task, a technique, a population and a condition as the users of one native vector env, a
user taking the next episode when its own ends (:func:`play_claimed`: those that a claim hands out,
which several processes may share); each episode gives exactly the numbers of
:func:`run_cell_episode` with its seed. :mod:`agents.benchmark` runs a grid's jobs with these.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from agents.benchmark.conditions import DEFAULT_CONDITION, get_condition
from agents.benchmark.grid import DEFAULT_BATCH_SIZE, Cell
from agents.benchmark.metrics import (
    STEP_KEYS,
    TRACE_KEYS,
    EpisodeRecorder,
    EpisodeStats,
    episode_stats,
)
from agents.benchmark.policies import build_policy
from agents.scripted import is_batched
from vrloco_env.actions import ACTION_NAMES
from vrloco_env.tasks import env_id

__all__ = [
    "DEFAULT_BATCH_SIZE",
    "play_claimed",
    "policy_actions",
    "policy_label",
    "run_batched",
    "run_cell_batched",
    "run_cell_episode",
    "run_episode",
]


_ENVS: dict[tuple, Any] = {}  # per process: one env per (task, technique, population, condition)


def _env(
    task: str, technique: Any, population: str | None = None, condition: str = DEFAULT_CONDITION
) -> Any:
    import gymnasium as gym

    import vrloco_env  # noqa: F401  (registers the ids)

    key = (task, technique, population, condition)
    if key not in _ENVS:
        _ENVS[key] = gym.make(
            env_id(task),
            technique=technique,
            population=population,
            sensors=get_condition(condition).sensors(),
        )
    return _ENVS[key]


def policy_actions(policy: Any, obs: Any, shape: tuple[int, ...], name: str) -> Any:
    """``policy.act(obs)``, checked to have ``shape`` (the env's actions, one row per user for a
    batch); a ValueError naming the policy ``name`` and both shapes otherwise."""
    actions = policy.act(obs)
    try:
        got: tuple[int, ...] | str = np.shape(actions)
    except ValueError:  # a ragged sequence
        got = "ragged (rows of different lengths)"
    if got != shape:
        rows = f" (one row of {shape[-1]} per user)" if len(shape) == 2 else ""
        raise ValueError(
            f"policy {name!r} returned actions of shape {got} from act(); expected "
            f"{shape}{rows}: [{', '.join(ACTION_NAMES)}], each in [-1, 1]"
        )
    return actions


def policy_label(policy: Any) -> str:
    """A policy's name for messages: its ``name``, else its class's."""
    name = getattr(policy, "name", None)
    return name if isinstance(name, str) and name else type(policy).__name__


def run_episode(
    env: Any, policy: Any, seed: int, trace: bool = False, name: str | None = None
) -> tuple[EpisodeStats, dict]:
    """Run one episode of ``policy`` (scripted, learned or a user's: ``reset(rng)``,
    ``act(obs)``) in the single env ``env`` with ``reset(seed=seed)``; the policy's randomness
    comes from ``default_rng([seed, 1])``. The stats come from ``info`` alone.

    Args:
        name: the policy's name in the error raised where ``act`` returns an action of another
            shape than the env's (default: :func:`policy_label`).

    Returns:
        The episode's :class:`~agents.benchmark.metrics.EpisodeStats` (with ``trace``: per-step
        traces, the room in ``trace["layout"]`` for figures) and the reset info.
    """
    obs, reset_info = env.reset(seed=seed)
    policy.reset(np.random.default_rng([seed, 1]))
    rec = EpisodeRecorder(seed, reset_info, trace=trace)
    shape = env.action_space.shape
    label = policy_label(policy) if name is None else name
    while True:
        obs, _, terminated, truncated, info = env.step(policy_actions(policy, obs, shape, label))
        rec.add(info)
        if terminated or truncated:
            break
    stats = rec.finish(start_position=reset_info["position"])
    if stats.trace is not None:
        stats.trace["layout"] = env.unwrapped.layout  # for the figures only
    return stats, reset_info


def run_cell_episode(cell: Cell, seed: int, trace: bool = False) -> tuple[EpisodeStats, dict]:
    """Episode ``seed`` of ``cell``: its task and technique's env, its policy."""
    env = _env(cell.task, cell.technique, cell.population, cell.condition)
    return run_episode(env, build_policy(cell.policy, env), seed, trace, name=cell.policy)


def run_cell_batched(
    cell: Cell,
    seeds: Sequence[int],
    trace: Sequence[bool] | None = None,
    batch_size: int = DEFAULT_BATCH_SIZE,
) -> list[tuple[EpisodeStats, dict]]:
    """Episodes ``seeds`` of ``cell`` as users of one vector env (:func:`run_batched`).

    Returns:
        ``(stats, reset_info)`` per episode, in the order of ``seeds``.
    """
    trace = [False] * len(seeds) if trace is None else list(trace)
    if len(trace) != len(seeds):
        raise ValueError(f"trace must hold one flag per seed ({len(seeds)}), got {len(trace)}")
    return run_batched([(cell, s, t) for s, t in zip(seeds, trace, strict=True)], batch_size)


def run_batched(
    episodes: Sequence[tuple[Cell, int, bool]], batch_size: int = DEFAULT_BATCH_SIZE
) -> list[tuple[EpisodeStats, dict]]:
    """Episodes ``(cell, seed, trace)`` of cells that share a task and a technique, as users of
    one native vector env: :func:`play_claimed` taking them all, in order.

    Returns:
        ``(stats, reset_info)`` per episode, in the order of ``episodes``.
    """
    taken = iter(range(len(episodes)))

    def claim(n: int) -> list[int]:
        return [j for _, j in zip(range(n), taken, strict=False)]

    done = play_claimed(episodes, batch_size, claim)
    return [done[j] for j in range(len(episodes))]


def play_claimed(
    episodes: Sequence[tuple[Cell, int, bool]],
    batch_size: int,
    claim: Callable[[int], list[int]],
) -> dict[int, tuple[EpisodeStats, dict]]:
    """The episodes ``(cell, seed, trace)`` that ``claim`` hands out, of cells that share a task
    and a technique, as users of one native vector env.

    ``claim(n)`` gives the indices (into ``episodes``) of up to ``n`` episodes not taken yet,
    none once every one is: other processes may play the rest (:mod:`agents.benchmark` lets an
    idle worker help with a job that is still running). ``min(batch_size, len(episodes))`` users
    start with the first episodes claimed; a user whose episode ends claims the next one,
    whichever cell it belongs to, with that episode's seed (autoreset is disabled, so no user
    ever starts an episode the grid did not ask for); once none is left, the users whose episode
    has ended leave the batch (``take_users`` of the env and of every policy: the batch shrinks
    to the users still playing) or, where a part cannot drop users (a plug-in stage or policy
    without ``take_users``), idle until the batch is done. Each cell has one policy that acts
    for the users playing its episodes (the others' rows are masked out with ``set_active``
    where the policy has it, and their actions discarded). Each episode gives exactly the
    numbers of :func:`run_cell_episode` with its seed: the users of a batch are independent, the
    env and the policy are seeded per user as the single env is, and the stats come from the
    same ``info`` values. A policy that does not take batches (:func:`agents.scripted.is_batched`)
    plays its episodes one at a time instead.

    Args:
        episodes: ``(cell, seed, trace)`` per episode; ``trace`` keeps its per-step traces for
            the figures.
        batch_size: users stepped together (>= 1).

    Returns:
        ``{index: (stats, reset_info)}`` for every episode claimed.

    Raises:
        ValueError: cells of different tasks or techniques, a bad batch size.
    """
    from gymnasium.vector import AutoresetMode

    import vrloco_env  # noqa: F401  (registers the tasks)
    from vrloco_env.techniques import get_technique
    from vrloco_env.vector import VRLocoVectorEnv

    if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1:
        raise ValueError(f"batch_size must be an integer >= 1, got {batch_size!r}")
    jobs = [(c, int(s), bool(t)) for c, s, t in episodes]
    if not jobs:
        return []
    first = jobs[0][0]
    task, tech, population = first.task, get_technique(first.technique), first.population
    condition = first.condition
    for c, _, _ in jobs:
        if (
            c.task != task
            or get_technique(c.technique) != tech
            or c.population != population
            or c.condition != condition
        ):
            raise ValueError(
                "run_batched: every episode must share one task, technique, population and "
                f"condition, got {c.task!r}/{c.technique_name!r}/{c.population!r}/"
                f"{c.condition!r} beside {task!r}/{tech.name!r}/{population!r}/{condition!r}"
            )
    n = min(batch_size, len(jobs))
    env = VRLocoVectorEnv(
        n,
        task=task,
        technique=first.technique,
        population=population,
        sensors=get_condition(condition).sensors(),
        autoreset_mode=AutoresetMode.DISABLED,
    )
    done: dict[int, tuple[EpisodeStats, dict]] = {}
    alone_jobs: list[int] = []  # claimed episodes of policies written for the single env
    try:
        cells = list(dict.fromkeys(c for c, _, _ in jobs))
        policies = {c: build_policy(c.policy, env) for c in cells}
        alone = {c for c, pol in policies.items() if not is_batched(pol)}

        def take(k: int) -> list[int]:
            """Up to ``k`` claimed episodes for the batch; the others' aside."""
            got: list[int] = []
            while len(got) < k and (new := claim(k - len(got))):
                for j in new:
                    (alone_jobs if jobs[j][0] in alone else got).append(j)
            return got

        if len(alone) < len(cells):
            done.update(_play_batch(env, policies, jobs, take))
        else:
            while take(len(jobs)):
                pass
    finally:
        env.close()
    for j in alone_jobs:
        c, s, t = jobs[j]
        done[j] = run_cell_episode(c, s, t)
    return done


def _play_batch(
    env: Any, policies: dict, jobs: list, take: Callable[[int], list[int]]
) -> dict[int, tuple]:
    """The loop of :func:`play_claimed` over the episodes of ``jobs`` that ``take(n)`` hands out
    (up to ``n``; ``env`` with autoreset disabled); returns ``{episode index: (stats,
    reset_info)}``."""
    from estimators.batching import takes_users

    n = env.num_envs
    cells = list(policies)
    # once no episode is left to claim, finished users leave the batch if the env and every
    # policy acting in it can drop them; otherwise they idle
    acting = [p for p in policies.values() if is_batched(p)]
    shrinks = env.can_take_users and all(takes_users(p) for p in acting)
    job = np.full(n, -1)  # the episode each user plays (-1: idle)
    owner = np.full(n, -1)  # the index in ``cells`` of its cell
    done: dict[int, tuple[EpisodeStats, dict]] = {}
    keys = (*STEP_KEYS, *(k for k in TRACE_KEYS if k not in STEP_KEYS))
    steps = _StepLog(keys)  # per control step: the info arrays of all users
    first = np.zeros(n, np.intp)  # the step index each user's episode started at
    start_info: list[dict] = [{}] * n

    def start(rows: NDArray[np.intp], got: list[int], reset_all: bool) -> NDArray[np.float32]:
        """Give ``rows`` the episodes ``got`` (as many, or fewer: the other rows idle); their
        first observations."""
        rows = rows[: len(got)]
        for i, j in zip(rows, got, strict=True):
            job[i] = j
            owner[i] = cells.index(jobs[j][0])
        # an idle user of the first reset plays seed 0, unused (every reset is seeded)
        seeds = [jobs[job[i]][1] if i in rows else (0 if reset_all else None) for i in range(n)]
        if reset_all:
            obs, info = env.reset(seed=seeds)
        else:
            mask = np.zeros(n, bool)
            mask[rows] = True
            obs, info = env.reset(seed=seeds, options={"reset_mask": mask})
        for k, cell in enumerate(cells):
            mine = rows[owner[rows] == k]
            if reset_all:  # every policy learns the batch size; rows not its own are idle
                rngs = [
                    np.random.default_rng([seeds[i] if owner[i] == k else 0, 1]) for i in range(n)
                ]
                policies[cell].reset(rngs, None)
            elif mine.size:
                policies[cell].reset(
                    [np.random.default_rng([jobs[job[i]][1], 1]) for i in mine], mine
                )
        for i in rows:
            first[i] = len(steps)
            start_info[i] = _row_info(info, i)
        _set_active(policies, cells, owner)
        return obs

    obs = start(np.arange(n), take(n), reset_all=True)
    while (job >= 0).any():
        actions = np.zeros((n, env.single_action_space.shape[0]), np.float32)
        for k, cell in enumerate(cells):
            mine = owner == k
            if mine.any():
                act = policy_actions(policies[cell], obs, actions.shape, cell.policy)
                actions[mine] = np.asarray(act, np.float32)[mine]
        obs, _, terminated, truncated, info = env.step(actions)
        steps.append(info)
        ended = np.flatnonzero((terminated | truncated) & (job >= 0))
        if ended.size == 0:
            continue
        for i in ended:  # once per episode: the user's rows of the stacked steps
            j = int(job[i])
            per_step = steps.user(i, first[i])
            last = {k: info[k][i] for k in ("is_success", "collisions", "elapsed_time", "walked")}
            tr = {k: per_step[k] for k in TRACE_KEYS} if jobs[j][2] else None
            stats = episode_stats(
                jobs[j][1],
                start_info[i]["shortest_path"],
                per_step,
                last,
                tr,
                start_info[i]["position"],
            )
            if stats.trace is not None:
                stats.trace["layout"] = env.core.layouts[i]
            done[j] = (stats, start_info[i])
        job[ended], owner[ended] = -1, -1
        got = take(ended.size)
        if got:
            obs = start(ended, got, reset_all=False)
        elif shrinks and (job >= 0).any():  # the batch keeps only the users still playing
            live = np.flatnonzero(job >= 0)
            keep = np.arange(live.size)  # the last users move into the places left free
            keep[job[: live.size] < 0] = live[live >= live.size]
            env.take_users(keep)
            for pol in acting:
                pol.take_users(keep)
            n = keep.size
            job, owner, first, obs = job[keep], owner[keep], first[keep], obs[keep]
            start_info = [start_info[i] for i in keep]
            steps.take(keep)
        if not got:  # the rows each policy acts for have changed
            _set_active(policies, cells, owner)
        running = job >= 0
        if running.any() and 2 * first[running].min() >= len(steps):  # forget old steps
            drop = int(first[running].min())
            steps.forget(drop)
            first -= drop
    return done


class _StepLog:
    """The info arrays ``keys`` of all users, control step after control step: one array per
    key, (steps, users, ...), grown as needed; a user's episode is a slice of its column."""

    def __init__(self, keys: tuple[str, ...]) -> None:
        self.keys = keys
        self.log: dict[str, NDArray] = {}
        self.size = 0
        self.columns: NDArray[np.intp] | None = None  # each user's column (None: its index)

    def __len__(self) -> int:
        return self.size

    def append(self, info: dict) -> None:
        """Log one control step's ``info`` (each key's array of the same shape and dtype at
        every step)."""
        if not self.log:
            self.log = {
                k: np.empty((64, *np.shape(info[k])), np.asarray(info[k]).dtype) for k in self.keys
            }
        cols = self.columns
        for k, log in self.log.items():
            value = np.asarray(info[k])
            shape = log.shape[1:] if cols is None else (cols.size, *log.shape[2:])
            if value.dtype != log.dtype or value.shape != shape:
                raise RuntimeError(
                    f"internal error: info[{k!r}] changed from {log.dtype}"
                    f"{shape} to {value.dtype}{value.shape}"
                )
            if self.size == log.shape[0]:
                log = self.log[k] = np.concatenate([log, np.empty_like(log)])
            if cols is None:
                log[self.size] = value
            else:
                log[self.size, cols] = value
        self.size += 1

    def take(self, rows: NDArray[np.intp]) -> None:
        """Keep the users ``rows`` (in their new order): user ``k`` is the old user
        ``rows[k]``, whose column it goes on writing (the others' columns are left unread)."""
        if self.columns is None:  # every user still writes its own index's column
            self.columns = np.arange(next(iter(self.log.values())).shape[1])
        self.columns = self.columns[rows]

    def user(self, i: int, start: int) -> dict[str, NDArray]:
        """User ``i``'s values from step ``start`` to the last logged, (steps, ...) per key."""
        c = i if self.columns is None else int(self.columns[i])
        return {k: log[start : self.size, c].copy() for k, log in self.log.items()}

    def forget(self, n: int) -> None:
        """Drop the first ``n`` steps (step ``n`` becomes step 0)."""
        for log in self.log.values():
            log[: self.size - n] = log[n : self.size]
        self.size -= n


def _set_active(policies: dict, cells: list, owner: NDArray) -> None:
    """Tell each policy which rows are its own (where it can be told)."""
    for k, cell in enumerate(cells):
        if callable(getattr(policies[cell], "set_active", None)):
            policies[cell].set_active(owner == k)


def _row_info(reset_info: dict, i: int) -> dict:
    """User ``i``'s reset info as the single env gives it (scalars and (3,) arrays)."""
    return {k: (v[i] if np.ndim(v[i]) else v[i].item()) for k, v in reset_info.items()}
