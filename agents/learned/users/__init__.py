"""Learned users shipped with the package: one PPO user per task, ``vrloco benchmark --policies
ppo`` (or ``ppo+typical``, with a population's variability as for the scripted users).

Each user is three files in this folder: ``<task>.zip`` (the stable-baselines3 model, carrying its
cell, env settings, policy settings and observation layout: :mod:`agents.learned.models`),
``<task>.json`` (its card: the command that trained it, the development choices and the
held-out evaluation, with the commands that made them) and ``<task>_curve.png`` (its learning
curve on the development evaluation seeds). A model whose observation no longer matches the
env's is refused with the field that changed (:class:`agents.benchmark.policies.LearnedPolicy`).

A second user of a task is registered under another name: ``<task>_any_technique`` is the one
trained on every technique of the registry at once (domain randomisation), for a technique the
task's own user was not trained on; play it by its file
(``--policies agents/learned/users/avoid_any_technique.zip``).

A user that misses the idealised bar is shipped only where its task cannot reach it, with the
limit in its registry entry (:attr:`LearnedUser.limit`).

A new user is its three files plus one registry line below.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from estimators.registry import Registry

__all__ = ["LEARNED_USERS", "NOT_SHIPPED", "LearnedUser", "shipped_user"]

HERE = Path(__file__).resolve().parent


@dataclass(frozen=True)
class LearnedUser:
    """A shipped learned user.

    Attributes:
        task: the task it was trained on (its registry name).
        file: the model's file name in this folder.
        limit: empty for a user that meets the idealised bar on its held-out seeds; for one
            that does not, what limits the task, with the command that shows it.
    """

    task: str
    file: str
    limit: str = ""

    @property
    def path(self) -> Path:
        """The model's ``.zip``."""
        return HERE / self.file

    @property
    def card(self) -> dict[str, Any]:
        """The user's card (``<task>.json``): how it was trained and how it does."""
        return json.loads(self.path.with_suffix(".json").read_text())


#: name (the task, or a task's second user) -> the shipped learned user.
LEARNED_USERS: Registry[LearnedUser] = Registry("learned user", kind=LearnedUser)
LEARNED_USERS.register(
    "avoid",
    LearnedUser("avoid", "avoid.zip"),
    "PPO trained with the typical population and its human variability, 3M steps: held-out "
    "collision-free success 1.00 idealised, 0.98 typical, 0.98 nodders, 0.85 gaze scanners "
    "(avoid.json)",
)


LEARNED_USERS.register(
    "doorway",
    LearnedUser("doorway", "doorway.zip"),
    "PPO with a 4-frame stack, trained idealised, then with idealised and typical users, then "
    "with every population: held-out collision-free success 0.96 idealised, 0.20 typical, 0.20 "
    "nodders, 0.23 gaze scanners (doorway.json)",
)
LEARNED_USERS.register(
    "approach",
    LearnedUser("approach", "approach.zip"),
    "PPO with a 4-frame stack, started from an imitation of the goal seeker, trained idealised, "
    "then with every population, then with collision=20: held-out collision-free success 0.97 "
    "idealised (goal seeker 1.00), 0.88 typical, 0.87 nodders, 0.81 gaze scanners (goal seeker "
    "0.78, 0.77, 0.63) (approach.json)",
)
LEARNED_USERS.register(
    "reach",
    LearnedUser("reach", "reach.zip"),
    "a correction of the goal seeker (--residual-on goal_seeker) with a 4-frame stack, trained "
    "idealised; it turns until the Kinect finds it again where the sensor has lost it at the "
    "pedestal: held-out collision-free success over 300 episodes 0.97 idealised, 0.07 typical, "
    "0.01 nodders, 0.08 gaze scanners (goal seeker 0.63, 0.05, 0.02, 0.07) (reach.json)",
)
LEARNED_USERS.register(
    "interact",
    LearnedUser("interact", "interact.zip"),
    "a correction of the goal seeker (--residual-on goal_seeker) with a 4-frame stack, trained "
    "idealised at learning rate 3e-5; it turns until the Kinect finds it again, as the Reach "
    "user: held-out collision-free success over 300 episodes 0.95 idealised, 0.12 typical, 0.01 "
    "nodders, 0.10 gaze scanners (goal seeker 0.64, 0.10, 0.03, 0.07) (interact.json)",
)
LEARNED_USERS.register(
    "avoid_any_technique",
    LearnedUser("avoid", "avoid_any_technique.zip"),
    "the Avoid user for any technique: trained on every registered technique at once, with the "
    "typical population and its variability, 5M steps; held-out on the default technique 1.00 "
    "idealised, 0.97 typical, 0.96 nodders, 0.87 gaze scanners (avoid_any_technique.json)",
)
LEARNED_USERS.register(
    "approach_any_technique",
    LearnedUser("approach", "approach_any_technique.zip"),
    "the Approach user for any technique: the Approach user trained on every registered "
    "technique at once with every population, 400k steps; held-out on the default technique over "
    "300 episodes 0.95 idealised (goal seeker 0.99), 0.86 typical, 0.84 nodders, 0.81 gaze "
    "scanners (goal seeker 0.81, 0.78, 0.70) (approach_any_technique.json)",
)
LEARNED_USERS.register(
    "doorway_any_technique",
    LearnedUser("doorway", "doorway_any_technique.zip"),
    "the Doorway user for any technique: the Doorway user trained on every registered technique "
    "at once with every population, 200k steps; held-out on the default technique over 300 "
    "episodes 0.98 idealised, 0.24 typical, 0.19 nodders, 0.21 gaze scanners (goal seeker 0.74, "
    "0.18, 0.19, 0.10) (doorway_any_technique.json)",
)


#: task -> why no learned user is shipped for it (where one was tried), with where it is shown.
NOT_SHIPPED: dict[str, str] = {}


def shipped_user(task: str) -> LearnedUser:
    """The shipped learned user of ``task``.

    Raises:
        ValueError: no user is shipped for ``task`` (naming the tasks that have one, and why
            none is shipped for ``task`` where :data:`NOT_SHIPPED` says).
    """
    if task not in LEARNED_USERS:
        shipped = ", ".join(n for n, u in LEARNED_USERS.items() if n == u.task) or "none yet"
        why = f": {NOT_SHIPPED[task]}" if task in NOT_SHIPPED else ""
        raise ValueError(
            f"policy 'ppo': no learned user is shipped for task {task!r} (shipped: {shipped})"
            f"{why}; train one with vrloco train --task {task}"
        )
    return LEARNED_USERS[task]
