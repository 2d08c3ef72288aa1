"""Learned users shipped with the package: one PPO user per task, ``vrloco benchmark --policies
ppo`` (or ``ppo+typical``, with a population's variability as for the scripted users).

Each user is three files in this folder: ``<task>.zip`` (the stable-baselines3 model, carrying its
cell, env settings, policy settings and observation layout: :mod:`agents.learned.models`),
``<task>.json`` (its card: the command that trained it, the development choices and the
held-out evaluation, with the commands that made them) and ``<task>_curve.png`` (its learning
curve on the development evaluation seeds). A model whose observation no longer matches the
env's is refused with the field that changed (:class:`agents.benchmark.policies.LearnedPolicy`).

A new user is its three files plus one registry line below.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from estimators.registry import Registry

__all__ = ["LEARNED_USERS", "LearnedUser", "shipped_user"]

HERE = Path(__file__).resolve().parent


@dataclass(frozen=True)
class LearnedUser:
    """A shipped learned user.

    Attributes:
        task: the task it was trained on (its registry name).
        file: the model's file name in this folder.
    """

    task: str
    file: str

    @property
    def path(self) -> Path:
        """The model's ``.zip``."""
        return HERE / self.file

    @property
    def card(self) -> dict[str, Any]:
        """The user's card (``<task>.json``): how it was trained and how it does."""
        return json.loads(self.path.with_suffix(".json").read_text())


#: task -> the shipped learned user of that task.
LEARNED_USERS: Registry[LearnedUser] = Registry("learned user", kind=LearnedUser)
LEARNED_USERS.register(
    "avoid",
    LearnedUser("avoid", "avoid.zip"),
    "PPO trained with the typical population and its human variability, 3M steps: held-out "
    "collision-free success 1.00 idealised, 0.98 typical, 0.98 nodders, 0.85 gaze scanners "
    "(avoid.json)",
)


def shipped_user(task: str) -> LearnedUser:
    """The shipped learned user of ``task``.

    Raises:
        ValueError: no user is shipped for ``task`` (naming the tasks that have one).
    """
    if task not in LEARNED_USERS:
        shipped = ", ".join(LEARNED_USERS) or "none yet"
        raise ValueError(
            f"policy 'ppo': no learned user is shipped for task {task!r} (shipped: {shipped}); "
            "train one with vrloco train --task " + str(task)
        )
    return LEARNED_USERS[task]
