"""The benchmark's grid: its cells (task, policy, technique, condition), cross products of them,
and the default run.

The default run (:data:`DEFAULT_GRIDS`): the main grid, Approach and Avoid x the goal seeker with
the ``typical`` population (gaze at the goal, at what is on its path and at the hand, occasional
scans and nods, the drift of stepping in place) x six techniques, and the scenarios in which a
technique is meant to differ from Zhang 2021's chain (:mod:`agents.benchmark.discrimination`): 20
cells of :data:`DEFAULT_EPISODES` episodes.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from agents.benchmark.conditions import DEFAULT_CONDITION

__all__ = [
    "DEFAULT_EPISODES",
    "DEFAULT_GRIDS",
    "DEFAULT_POLICIES",
    "DEFAULT_SENSORS",
    "DEFAULT_TASKS",
    "DEFAULT_TECHNIQUES",
    "Cell",
    "Grid",
]

#: The main grid's tasks, users and techniques.
DEFAULT_TASKS = ("approach", "avoid")
DEFAULT_POLICIES = ("goal_seeker+typical",)
DEFAULT_TECHNIQUES = (
    "zhang2021",
    "zhang2021_as_printed",
    "zhang2021_consumer",
    "threshold_steps",
    "nod_robust",
    "smooth",
)
#: The IMU presets of ``--sensors`` (Zhang 2021's chain on each).
DEFAULT_SENSORS = ("ig500n", "consumer_mems")
#: Episodes per cell: the smallest size at which, on development seeds 1000-1159, every technique
#: pair the default run's scenarios tell apart separates and three on an outcome in at least 99 %
#: of bootstrap resamples (``python benchmarks/pair_power.py --episodes 160 --sizes 40 60 80``).
DEFAULT_EPISODES = 60

#: Users per vector env in the batched runner (:func:`agents.benchmark.episodes.run_cell_batched`).
#: Batches shed their finished users once a job has none left to hand out, so a larger batch
#: costs no idle users. Chosen on development seeds 1000-1059 of the main grid (``python
#: benchmarks/bench_benchmark.py --seed 1000 --batch-size N``), where 30 users ran as fast as
#: 45 or 60 and faster than 20, with a third of 60's memory (the planner's maps take megabytes
#: per user).
DEFAULT_BATCH_SIZE = 30


@dataclass(frozen=True)
class Cell:
    """One cell of the benchmark grid: a task, a policy, a technique (a registered name, a
    ``"module:attr"`` naming a :class:`~vrloco_env.techniques.Technique`, or one) and the
    physical room's condition (:mod:`agents.benchmark.conditions`)."""

    task: str
    policy: str
    technique: Any = "zhang2021"
    condition: str = DEFAULT_CONDITION

    @property
    def technique_name(self) -> str:
        from vrloco_env.techniques import get_technique

        return get_technique(self.technique).name

    @property
    def population(self) -> str | None:
        """The env's user population: the policy's ``+<population>`` where it acts on the body
        (:func:`agents.benchmark.policies.env_population`), else None."""
        from agents.benchmark.policies import env_population

        return env_population(self.policy)

    @property
    def sensors(self) -> str:
        """The technique's IMU preset."""
        from vrloco_env.techniques import get_technique

        return get_technique(self.technique).sensor_preset

    @property
    def label(self) -> str:
        """A file-name-safe name: ``task_policy_technique``, then ``_condition`` outside the
        default condition (a policy or technique given as a path keeps only its file name; other
        characters become ``-``)."""

        def safe(text: str) -> str:
            return re.sub(r"[^A-Za-z0-9_]+", "-", text.replace("\\", "/").split("/")[-1])

        where = "" if self.condition == DEFAULT_CONDITION else f"_{safe(self.condition)}"
        return f"{self.task}_{safe(self.policy)}_{safe(self.technique_name)}{where}"


@dataclass(frozen=True)
class Grid:
    """A cross product of the benchmark: every task x policy x technique x condition. A run is
    one grid or several (the default run: :data:`DEFAULT_GRIDS`); a cell two grids share runs
    once."""

    tasks: tuple[str, ...]
    policies: tuple[str, ...]
    techniques: tuple[Any, ...]
    conditions: tuple[str, ...] = (DEFAULT_CONDITION,)

    def __post_init__(self) -> None:
        from vrloco_env.techniques import canonical_name

        # a technique's earlier name runs (and is reported) under its current one
        object.__setattr__(self, "techniques", tuple(canonical_name(t) for t in self.techniques))

    def cells(self) -> list[Cell]:
        """The grid's cells, condition by condition, then task, policy and technique."""
        return [
            Cell(t, p, k, w)
            for w in self.conditions
            for t in self.tasks
            for p in self.policies
            for k in self.techniques
        ]


#: The default run: the main grid, and the scenarios that put a technique where it is meant to
#: differ (:mod:`agents.benchmark.discrimination`): nodding users, also while they stand and hold
#: the hand at a pedestal, for the nod-robust step detector; gaze-scanning users in Avoid's corridor
#: for torso steering (in Doorway the goal seeker itself fails too often to tell steering apart);
#: a metal cabinet beside the play area for the magnetometer's gate.
DEFAULT_GRIDS = (
    Grid(DEFAULT_TASKS, DEFAULT_POLICIES, DEFAULT_TECHNIQUES),
    Grid(("approach", "reach"), ("goal_seeker+nodders",), ("zhang2021", "nod_robust")),
    Grid(("avoid",), ("goal_seeker+gaze_scanners",), ("zhang2021", "torso_steering")),
    Grid(("approach",), ("goal_seeker+typical",), ("zhang2021", "madgwick"), ("beside_metal",)),
)
