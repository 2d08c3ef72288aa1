"""Avoid: Zhang 2021's Fig. 5 — walk down a corridor, pass the obstacle on the straight line and
reach the end line (success: the end line crossed without a single collision)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.validation import check_in_range, check_numbers, value_repr
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

__all__ = ["Avoid", "AvoidConfig", "avoid_layout"]


@dataclass(frozen=True)
class AvoidConfig:
    """The Avoid task's corridor and obstacle (Zhang 2021 Fig. 5).

    Attributes:
        corridor_width: interior width of the corridor (m).
        corridor_length: interior length of the corridor (m).
        corridor_width_jitter: the width is drawn in ``corridor_width +- jitter`` (m).
        corridor_margin: distance from each end wall to the start and to the end line (m).
        obstacle_distance_range: distance of the obstacle centre ahead of the start (m).
        obstacle_size_range: obstacle box half extent / cylinder radius (m); with the defaults a
            box is 0.5-1.0 m across, a table to a cabinet.
        obstacle_lateral_jitter: the obstacle centre is drawn within +- this of the straight line
            (m), less than the smallest obstacle, so that it always blocks the straight walk.
    """

    corridor_width: float = 3.0
    corridor_length: float = 14.0
    corridor_width_jitter: float = 0.2
    corridor_margin: float = 1.0
    obstacle_distance_range: tuple[float, float] = (5.0, 8.0)
    obstacle_size_range: tuple[float, float] = (0.25, 0.5)
    obstacle_lateral_jitter: float = 0.15

    def __post_init__(self) -> None:
        def fail(name: str, allowed: str) -> None:
            shown = value_repr(getattr(self, name))
            raise ValueError(f"AvoidConfig.{name}={shown}: must be {allowed}")

        for name in ("corridor_width", "corridor_length"):
            check_in_range(self, name, 0.0, 1000.0, "m", lo_open=True)
        for name in ("corridor_width_jitter", "corridor_margin", "obstacle_lateral_jitter"):
            check_in_range(self, name, 0.0, 1000.0, "m")
        check_numbers(self, "obstacle_size_range", 0.01, 100.0, "m", length=2, ordered=True)
        check_numbers(self, "obstacle_distance_range", 0.0, 1000.0, "m", length=2, ordered=True)
        if self.corridor_width_jitter >= self.corridor_width / 2.0:
            half = float(self.corridor_width) / 2
            fail("corridor_width_jitter", f"< corridor_width / 2 = {half:g} m")
        if self.obstacle_lateral_jitter >= self.obstacle_size_range[0]:
            fail(
                "obstacle_lateral_jitter",
                f"< obstacle_size_range[0] = {float(self.obstacle_size_range[0]):g} m, so the "
                "obstacle always blocks the straight line",
            )
        ahead_max = self.corridor_length - 2.0 * self.corridor_margin
        if ahead_max <= 0.0:
            half = float(self.corridor_length) / 2
            fail("corridor_margin", f"< corridor_length / 2 = {half:g} m")
        hi = self.obstacle_distance_range[1]
        if hi + self.obstacle_size_range[1] * math.sqrt(2.0) >= ahead_max:
            fail(
                "obstacle_distance_range",
                "a range whose high end + obstacle_size_range[1] * sqrt(2) is < corridor_length "
                f"- 2 * corridor_margin = {float(ahead_max):g} m (the obstacle ends before the "
                "end line)",
            )

    def check_room(self, room: RoomConfig) -> None:
        """Raise a ValueError unless the avatar of ``room`` can pass the smallest obstacle."""
        half_min = (self.corridor_width - self.corridor_width_jitter) / 2.0
        need = 2.0 * (room.avatar_radius + room.grid_resolution)
        if half_min - self.obstacle_size_range[0] < need:
            raise ValueError(
                f"AvoidConfig.corridor_width={value_repr(self.corridor_width)}: must be wide "
                "enough to pass the smallest obstacle: (corridor_width - corridor_width_jitter) "
                "/ 2 - obstacle_size_range[0] >= 2 * (RoomConfig.avatar_radius + "
                f"RoomConfig.grid_resolution) = {need:g} m"
            )


class Avoid(Task):
    """Cross the corridor's end line past an obstacle, without touching anything
    (:func:`avoid_layout`). The goal region is the half plane beyond the end line; the goal
    bearing points straight ahead across it."""

    name = "avoid"
    description = "pass the corridor's obstacle and reach the end line, collision-free"
    collision_free_success = True
    Config = AvoidConfig
    per_user_fields = (*Task.per_user_fields, "line_x")

    def __init__(self, batch_size: int, dt: float, config=None) -> None:
        super().__init__(batch_size, dt, config)
        self.line_x = np.zeros(self.batch_size)

    def draw_layout(self, room: RoomConfig, rng: np.random.Generator) -> Layout:
        return avoid_layout(room, rng, self.config)

    def draw(self, user: int, room: RoomConfig, rng: np.random.Generator) -> Layout:
        layout = super().draw(user, room, rng)
        assert layout.goal_line is not None
        self.line_x[user] = layout.goal_line[0][0]
        return layout

    def goal_distance(self, position: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.maximum(self.line_x - position[:, 0], 0.0)

    def goal_point(self, position: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.stack([self.line_x, position[:, 1]], -1)


def avoid_layout(
    config: RoomConfig, rng: np.random.Generator, task: AvoidConfig | None = None
) -> Layout:
    """The Avoid corridor of Zhang 2021 Fig. 5: walk straight, pass an obstacle, reach the end line.

    The corridor (interior ``corridor_length`` along +x by a width drawn in
    ``corridor_width +- corridor_width_jitter``) is closed by end walls. The start sits
    ``corridor_margin`` from the near end on the centre line, facing +x (yaw 0); the end line is
    ``corridor_margin`` before the far end. One box (turned by up to pi/8) or cylinder, of half
    size in ``obstacle_size_range``, is centred ``obstacle_distance_range`` ahead of the start and
    within ``obstacle_lateral_jitter`` of the centre line, which it therefore always blocks.

    Args:
        config: room parameters (walls, obstacle heights and kinds, the avatar).
        rng: the only source of randomness.
        task: the corridor and its obstacle (defaults if None).

    Returns:
        The layout (local frame, origin (0, 0)).

    Raises:
        ValueError: a corridor the avatar cannot pass (:meth:`AvoidConfig.check_room`).
        RuntimeError: if no feasible layout is drawn in ``config.max_attempts`` attempts.
    """
    cfg, rng = config, check_rng(rng)
    av = AvoidConfig() if task is None else task
    av.check_room(cfg)
    half_l = av.corridor_length / 2.0
    for _ in range(cfg.max_attempts):
        width = av.corridor_width + float(rng.uniform(-1.0, 1.0)) * av.corridor_width_jitter
        bounds = (-half_l, half_l, -width / 2.0, width / 2.0)
        start = np.array([-half_l + av.corridor_margin, 0.0])
        x_line = half_l - av.corridor_margin
        ahead = float(rng.uniform(*av.obstacle_distance_range))
        lateral = float(rng.uniform(-1.0, 1.0)) * av.obstacle_lateral_jitter
        c = (float(start[0] + ahead), lateral)
        height = float(rng.uniform(*cfg.obstacle_height_range))
        obstacle: Solid
        if rng.random() < cfg.cylinder_probability:
            obstacle = Cylinder(c, float(rng.uniform(*av.obstacle_size_range)), height)
        else:
            he = rng.uniform(*av.obstacle_size_range, size=2)
            yaw = float(rng.uniform(-np.pi / 8.0, np.pi / 8.0))
            obstacle = Box(c, (float(he[0]), float(he[1])), yaw, height)
        line = ((x_line, -width / 2.0), (x_line, width / 2.0))
        layout = finish_layout(
            cfg, "avoid", bounds, [obstacle], start, 0.0, np.array([x_line, 0.0]), line, None
        )
        if layout is not None:
            return layout
    raise no_layout_error(cfg, "avoid")
