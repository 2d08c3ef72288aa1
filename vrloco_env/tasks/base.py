"""The batched task protocol: what a user is asked to do, when it is done, what it adds to the
observation.

A task is one class, batched over the B users of a :class:`~vrloco_env.core.LocoCore` (no Python
loop over users per step). Per episode of user i, :meth:`Task.draw` draws the room and the
task's targets from that episode's generator; per control step, after the virtual body has
moved, the core asks the task for the distance to its goal region (progress and reward), the
point the goal bearing points at, whether the episode is finished, and the task's own
observation fields. Success is finishing — without a single collision where
:attr:`Task.collision_free_success`.

Adding a task: a file with a :class:`Task` subclass (its layout generator, built from the blocks
in :mod:`vrloco_env.world`, and optionally its own frozen config dataclass), plus one
:func:`vrloco_env.tasks.register_task` line, which also registers its Gymnasium id.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers
from vrloco_env.observation import Field
from vrloco_env.world import Layout, RoomConfig

__all__ = ["NoConfig", "Task"]


@dataclass(frozen=True)
class NoConfig:
    """The configuration of a task that has none."""


class Task(TakesUsers):
    """Base of every task: a goal disc taken from the layout, finished on entering it.

    Args:
        batch_size: B.
        dt: the control step (s).
        config: the task's configuration (an instance of :attr:`Config`; its defaults if None).

    Class attributes a task sets:
        name: the registry name (``"approach"``).
        description: one line for listings.
        Config: the task's frozen configuration dataclass.
        collision_free_success: success needs an episode without collisions.
        per_user_fields: the attributes with one row per user (a subclass lists its own too, so
            that a batch can drop users: :class:`~estimators.batching.TakesUsers`).
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    Config: ClassVar[type] = NoConfig
    collision_free_success: ClassVar[bool] = False
    per_user_fields: ClassVar[tuple[str, ...]] = ("goal", "goal_radius")
    batch_size_field: ClassVar[str | None] = "batch_size"

    def __init__(self, batch_size: int, dt: float, config: Any = None) -> None:
        if config is None:
            config = self.Config()
        if not isinstance(config, self.Config):
            raise TypeError(
                f"task {self.name!r} takes a {self.Config.__name__} as task_config, got "
                f"{type(config).__name__}"
            )
        self.config = config
        self.batch_size = int(batch_size)
        self.dt = float(dt)
        self.goal = np.zeros((self.batch_size, 2))
        self.goal_radius = np.zeros(self.batch_size)

    # ------------------------------------------------------------------ per episode
    def draw_layout(self, room: RoomConfig, rng: np.random.Generator) -> Layout:
        """The episode's room (local frame), every random number from ``rng``."""
        raise NotImplementedError

    def draw(self, user: int, room: RoomConfig, rng: np.random.Generator) -> Layout:
        """Draw user ``user``'s room and targets for a new episode; returns the room."""
        layout = self.draw_layout(room, rng)
        self.goal[user] = layout.goal
        self.goal_radius[user] = layout.goal_radius
        return layout

    def reset(self, rows: NDArray[np.intp]) -> None:
        """Clear the progress state (e.g. a dwell timer) of users ``rows``."""

    # ------------------------------------------------------------------ per step
    def goal_distance(self, position: NDArray[np.float64]) -> NDArray[np.float64]:
        """Distance (m) from the virtual positions (B, 2) to each user's goal region (0 inside)."""
        d = np.hypot(position[:, 0] - self.goal[:, 0], position[:, 1] - self.goal[:, 1])
        return np.maximum(d - self.goal_radius, 0.0)

    def goal_point(self, position: NDArray[np.float64]) -> NDArray[np.float64]:
        """The point the observation's goal bearing points at, (B, 2)."""
        return self.goal

    def finished(self, in_goal: NDArray[np.bool_], user_step: Any) -> NDArray[np.bool_]:
        """Whether each user's episode is done this step (``user_step``: the users' estimates,
        a :class:`~vrloco_env.users.UserStep`)."""
        return in_goal

    def hand_progress(self) -> NDArray[np.float64] | None:
        """How much closer (rad) each user's estimated hand came to the task's target
        orientation in the last :meth:`finished` (0 without an estimate before or after);
        None for a task without a hand target."""
        return None

    def fields(self) -> tuple[Field, ...]:
        """The task's own observation fields, after the common ones."""
        return ()

    def observe(self, user_step: Any, fresh: NDArray[np.bool_]) -> dict[str, ArrayLike]:
        """Physical values (B, size) of :meth:`fields` (``user_step`` None before any step;
        ``fresh``: users just reset)."""
        return {}

    def info(self) -> dict[str, NDArray]:
        """Per-user task quantities for ``info`` (copies)."""
        return {}
