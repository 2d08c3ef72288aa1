"""Avoid: seed 000's Fig. 5 — walk down a corridor, pass the obstacle on the straight line and
reach the end line (success: the end line crossed without a single collision)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from vrloco_env.tasks.base import Task
from vrloco_env.world import (
    Box,
    Cylinder,
    Layout,
    RoomConfig,
    Solid,
    check_rng,
    finish_layout,
    no_layout_error,
)

__all__ = ["Avoid", "avoid_layout"]


class Avoid(Task):
    """Cross the corridor's end line past an obstacle, without touching anything
    (:func:`avoid_layout`). The goal region is the half plane beyond the end line; the goal
    bearing points straight ahead across it."""

    name = "avoid"
    description = "pass the corridor's obstacle and reach the end line, collision-free"
    collision_free_success = True

    def __init__(self, batch_size: int, dt: float, config=None) -> None:
        super().__init__(batch_size, dt, config)
        self.line_x = np.zeros(self.batch_size)

    def draw_layout(self, room: RoomConfig, rng: np.random.Generator) -> Layout:
        return avoid_layout(room, rng)

    def draw(self, user: int, room: RoomConfig, rng: np.random.Generator) -> Layout:
        layout = super().draw(user, room, rng)
        assert layout.goal_line is not None
        self.line_x[user] = layout.goal_line[0][0]
        return layout

    def goal_distance(self, position: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.maximum(self.line_x - position[:, 0], 0.0)

    def goal_point(self, position: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.stack([self.line_x, position[:, 1]], -1)


def avoid_layout(config: RoomConfig, rng: np.random.Generator) -> Layout:
    """The Avoid corridor of seed 000 Fig. 5: walk straight, pass an obstacle, reach the end line.

    The corridor (interior ``corridor_length`` along +x by a width drawn in
    ``corridor_width +- corridor_width_jitter``) is closed by end walls. The start sits
    ``corridor_margin`` from the near end on the centre line, facing +x (yaw 0); the end line is
    ``corridor_margin`` before the far end. One box (turned by up to pi/8) or cylinder, of half
    size in ``avoid_size_range``, is centred ``avoid_distance_range`` ahead of the start and within
    ``avoid_lateral_jitter`` of the centre line, which it therefore always blocks.

    Args:
        config: room parameters.
        rng: the only source of randomness.

    Returns:
        The layout (local frame, origin (0, 0)).

    Raises:
        RuntimeError: if no feasible layout is drawn in ``config.max_attempts`` attempts.
    """
    cfg, rng = config, check_rng(rng)
    half_l = cfg.corridor_length / 2.0
    for _ in range(cfg.max_attempts):
        width = cfg.corridor_width + float(rng.uniform(-1.0, 1.0)) * cfg.corridor_width_jitter
        bounds = (-half_l, half_l, -width / 2.0, width / 2.0)
        start = np.array([-half_l + cfg.corridor_margin, 0.0])
        x_line = half_l - cfg.corridor_margin
        ahead = float(rng.uniform(*cfg.avoid_distance_range))
        lateral = float(rng.uniform(-1.0, 1.0)) * cfg.avoid_lateral_jitter
        c = (float(start[0] + ahead), lateral)
        height = float(rng.uniform(*cfg.obstacle_height_range))
        obstacle: Solid
        if rng.random() < cfg.cylinder_probability:
            obstacle = Cylinder(c, float(rng.uniform(*cfg.avoid_size_range)), height)
        else:
            he = rng.uniform(*cfg.avoid_size_range, size=2)
            yaw = float(rng.uniform(-np.pi / 8.0, np.pi / 8.0))
            obstacle = Box(c, (float(he[0]), float(he[1])), yaw, height)
        line = ((x_line, -width / 2.0), (x_line, width / 2.0))
        layout = finish_layout(
            cfg, "avoid", bounds, [obstacle], start, 0.0, np.array([x_line, 0.0]), line, None
        )
        if layout is not None:
            return layout
    raise no_layout_error(cfg, "avoid")
