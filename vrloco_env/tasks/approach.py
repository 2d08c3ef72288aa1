"""Approach: reach the goal in a room with obstacles (success: the virtual body within the goal
radius)."""

from __future__ import annotations

import numpy as np

from vrloco_env.tasks.base import Task
from vrloco_env.world import (
    Layout,
    RoomConfig,
    check_rng,
    finish_layout,
    no_layout_error,
    room_bounds,
    scatter_obstacles,
)

__all__ = ["Approach", "approach_layout"]


class Approach(Task):
    """Walk to a goal disc across a room with obstacles (:func:`approach_layout`)."""

    name = "approach"
    description = "reach the goal in a room with obstacles"
    per_user_fields = Task.per_user_fields

    def draw_layout(self, room: RoomConfig, rng: np.random.Generator) -> Layout:
        return approach_layout(room, rng)


def approach_layout(config: RoomConfig, rng: np.random.Generator) -> Layout:
    """An Approach room: start and goal at least ``min_start_goal_distance`` apart, obstacles kept
    ``keepout_radius`` away from both, and a guaranteed collision-free path for the avatar.

    Args:
        config: room parameters.
        rng: the only source of randomness (the env's ``np_random``).

    Returns:
        The layout (local frame, origin (0, 0)).

    Raises:
        RuntimeError: if no feasible layout is drawn in ``config.max_attempts`` attempts.
    """
    cfg, rng = config, check_rng(rng)
    bounds = room_bounds(cfg)
    k = cfg.keepout_radius
    inner = np.array([[bounds[0] + k, bounds[2] + k], [bounds[1] - k, bounds[3] - k]])
    for _ in range(cfg.max_attempts):
        start = rng.uniform(inner[0], inner[1])
        goal = rng.uniform(inner[0], inner[1])
        yaw = float(rng.uniform(-np.pi, np.pi))
        if np.hypot(*(goal - start)) < cfg.min_start_goal_distance:
            continue
        obstacles = scatter_obstacles(cfg, rng, bounds, [(start, k), (goal, k)])
        if obstacles is None:
            continue
        layout = finish_layout(cfg, "approach", bounds, obstacles, start, yaw, goal, None, None)
        if layout is not None:
            return layout
    raise no_layout_error(cfg, "approach")
