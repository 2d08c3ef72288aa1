"""Sizes and draw ranges of the task rooms: :class:`RoomConfig`."""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["RoomConfig"]


@dataclass(frozen=True)
class RoomConfig:
    """Sizes and draw ranges of the task rooms. Lengths in metres, angles in radians.

    Defaults: an 8 m x 8 m room, 4-7 obstacles, avatar radius 0.25 m, start-goal distance >= 4 m,
    goal radius 0.5 m, 0.1 m planning grid, landmarks at 1.0-2.0 m height; the rest are
    engineering choices noted per field. What only one task uses lives in that task's config
    (:class:`~vrloco_env.tasks.avoid.AvoidConfig`,
    :class:`~vrloco_env.tasks.interact.InteractConfig`).

    Attributes:
        room_width: interior size along x of the Approach/Interact room.
        room_depth: interior size along y of the Approach/Interact room.
        wall_thickness: wall thickness (0.2 m, an interior partition wall).
        wall_height: wall height (2.5 m, a common ceiling height; above head rays at ~1.6 m).
        n_obstacles_min: fewest obstacles in a room.
        n_obstacles_max: most obstacles in a room.
        obstacle_size_range: box half extent / cylinder radius range.
        obstacle_height_range: obstacle height range (furniture to pillars; shorter than the
            eye height means head rays at eye level pass over it).
        cylinder_probability: chance that an obstacle is a cylinder rather than a box.
        avatar_radius: radius of the avatar capsule (shoulder half-width of an adult).
        avatar_height: height of the avatar capsule (1.7 m, adult stature).
        keepout_radius: no wall or obstacle surface closer than this to the start or the goal
            (the Interact pedestal excepted); >= avatar_radius + 2 * grid_resolution so that the
            start is free on the inflated planning grid.
        min_start_goal_distance: minimum straight-line start-goal distance.
        goal_radius: success radius around the goal point.
        grid_resolution: cell size of the planning grid.
        landmark_spacing: horizontal spacing of the wall landmarks (m, 0.1-100).
        landmark_heights: heights of the landmark rows.
        max_attempts: redraws before giving up with a RuntimeError.
    """

    room_width: float = 8.0
    room_depth: float = 8.0
    wall_thickness: float = 0.2
    wall_height: float = 2.5
    n_obstacles_min: int = 4
    n_obstacles_max: int = 7
    obstacle_size_range: tuple[float, float] = (0.2, 0.6)
    obstacle_height_range: tuple[float, float] = (0.8, 2.2)
    cylinder_probability: float = 0.4
    avatar_radius: float = 0.25
    avatar_height: float = 1.7
    keepout_radius: float = 1.0
    min_start_goal_distance: float = 4.0
    goal_radius: float = 0.5
    grid_resolution: float = 0.1
    landmark_spacing: float = 1.0
    landmark_heights: tuple[float, ...] = (1.0, 1.5, 2.0)
    max_attempts: int = 200

    def __post_init__(self) -> None:
        from estimators.validation import check_in_range, check_numbers, value_repr

        def num(x: float) -> str:  # fields may be ints, Fractions or numpy numbers
            return f"{float(x):g}"

        def fail(name: str, allowed: str) -> None:
            shown = value_repr(getattr(self, name))
            raise ValueError(f"RoomConfig.{name}={shown}: must be {allowed}")

        big = 1000.0
        for name in ("room_width", "room_depth"):
            check_in_range(self, name, 0.0, big, "m", lo_open=True)
        for name in (
            "wall_thickness",
            "wall_height",
            "avatar_radius",
            "avatar_height",
            "goal_radius",
        ):
            check_in_range(self, name, 0.0, 100.0, "m", lo_open=True)
        # a chosen floor: closer landmarks would be one blob to the camera, and a wall's count of
        # them (its length / spacing) would grow without bound
        check_in_range(self, "landmark_spacing", 0.1, 100.0, "m")
        check_in_range(self, "grid_resolution", 0.005, 1.0, "m")
        for name in ("min_start_goal_distance", "keepout_radius"):
            check_in_range(self, name, 0.0, big, "m")
        check_in_range(self, "cylinder_probability", 0.0, 1.0)
        check_in_range(self, "n_obstacles_max", 0, 100, integer=True)
        check_in_range(
            self, "n_obstacles_min", 0, self.n_obstacles_max, "(<= n_obstacles_max)", integer=True
        )
        check_in_range(self, "max_attempts", 1, 1_000_000, integer=True)
        check_numbers(self, "obstacle_size_range", 0.01, 100.0, "m", length=2, ordered=True)
        check_numbers(self, "obstacle_height_range", 0.01, 100.0, "m", length=2, ordered=True)
        check_numbers(self, "landmark_heights", 0.0, self.wall_height, "m (<= wall_height)")
        if self.avatar_height <= 2.0 * self.avatar_radius:
            fail("avatar_height", f"> 2 * avatar_radius = {num(2 * self.avatar_radius)} m")
        need = self.avatar_radius + 2.0 * self.grid_resolution
        if self.keepout_radius < need:
            fail("keepout_radius", f">= avatar_radius + 2 * grid_resolution = {float(need):.3f} m")
        free_w = self.room_width - 2.0 * self.keepout_radius
        free_d = self.room_depth - 2.0 * self.keepout_radius
        if free_w <= 0.0 or free_d <= 0.0:
            fail(
                "keepout_radius",
                f"< half the room's smaller side (room_width {num(self.room_width)} m, "
                f"room_depth {num(self.room_depth)} m)",
            )
        if self.min_start_goal_distance >= math.hypot(free_w, free_d):
            fail(
                "min_start_goal_distance",
                "< the diagonal of the room (room_width x room_depth) shrunk by keepout_radius "
                f"on every side, {float(math.hypot(free_w, free_d)):.2f} m",
            )
