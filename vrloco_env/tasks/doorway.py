"""Doorway: walk through a sequence of doorways, one per wall across the room, to a goal beyond
the last (success: every doorway passed, the goal reached, not a single collision)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimators.validation import check_in_range, check_numbers, value_repr
from vrloco_env.observation import MAX_GOAL_DISTANCE, Field
from vrloco_env.tasks.base import Task
from vrloco_env.world import Box, Layout, RoomConfig, check_rng, finish_layout, no_layout_error

__all__ = ["Doorway", "DoorwayConfig", "doorway_layout"]


@dataclass(frozen=True)
class DoorwayConfig:
    """The Doorway task's room: walls across it, each with one gap.

    The user walks along +x. ``n_doorways`` walls, ``wall_spacing`` apart centre to centre,
    split the room into ``n_doorways + 1`` bays of equal pitch; each wall has one gap whose width
    is drawn in ``width_range`` and whose centre is drawn anywhere across the room that leaves
    both jambs at least ``jamb_min`` long.

    Attributes:
        n_doorways: number of walls (and doorways) to pass.
        width_range: doorway width range (m): 0.8-1.2 m, from a narrow interior door (about
            the smallest clear width accessibility codes allow, 32 in = 0.81 m in the 2010 ADA
            Standards, 404.2.3) to a wide one.
        wall_spacing: distance between consecutive walls, centre to centre, and the pitch of the
            first and last bays (m).
        width: interior size of the room across the walking direction, along y (m).
        jamb_min: shortest wall piece beside a doorway (m).
        aim_lead: the goal bearing points at a doorway's aim point, on its centre line this far
            (m) beyond where the body is through it (its disc past the wall's far face). A point
            ahead of that line keeps the bearing defined while the body is in the doorway (a
            point in the doorway itself would lie beside the body there).
    """

    n_doorways: int = 3
    width_range: tuple[float, float] = (0.8, 1.2)
    wall_spacing: float = 3.0
    width: float = 6.0
    jamb_min: float = 0.5
    aim_lead: float = 0.5

    def __post_init__(self) -> None:
        check_in_range(self, "n_doorways", 1, 10, integer=True)
        check_numbers(self, "width_range", 0.01, 100.0, "m", length=2, ordered=True)
        check_in_range(self, "wall_spacing", 0.0, 100.0, "m", lo_open=True)
        check_in_range(self, "width", 0.0, 100.0, "m", lo_open=True)
        check_in_range(self, "jamb_min", 0.0, 100.0, "m")
        check_in_range(self, "aim_lead", 0.0, 100.0, "m", lo_open=True)
        room = self.width_range[1] + 2.0 * self.jamb_min
        if room > self.width:
            raise ValueError(
                f"DoorwayConfig.width={value_repr(self.width)}: must be >= width_range[1] + 2 * "
                f"jamb_min = {float(room):g} m (the widest doorway and its jambs fit across)"
            )

    def check_room(self, room: RoomConfig) -> None:
        """Raise a ValueError naming the field unless the avatar of ``room`` fits through the
        narrowest doorway, the start and goal keep ``room.keepout_radius`` from every wall and
        the aim points lie in the bays.

        The narrowest doorway must exceed the avatar's diameter by three planning cells
        (``2 * (avatar_radius + grid_resolution) + grid_resolution``): the layout's planner
        inflates every solid by one cell more than the avatar radius, and a gap that wide always
        holds a free column of cells.
        """
        r, h = room.avatar_radius, room.grid_resolution
        need = 2.0 * (r + h) + h
        if self.width_range[0] < need - 1e-9:
            raise ValueError(
                f"DoorwayConfig.width_range={value_repr(self.width_range)}: width_range[0] must be "
                ">= 2 * (RoomConfig.avatar_radius + RoomConfig.grid_resolution) + "
                f"RoomConfig.grid_resolution = {need:g} m (the avatar passes the narrowest "
                "doorway)"
            )
        k, t = room.keepout_radius, room.wall_thickness
        pitch = 2.0 * k + t / 2.0
        if self.wall_spacing < pitch - 1e-9:
            raise ValueError(
                f"DoorwayConfig.wall_spacing={value_repr(self.wall_spacing)}: must be >= 2 * "
                f"RoomConfig.keepout_radius + RoomConfig.wall_thickness / 2 = {pitch:g} m (the "
                "start and the goal keep clear of the walls)"
            )
        lead = self.wall_spacing - t - 2.0 * r
        if self.aim_lead > lead + 1e-9:
            raise ValueError(
                f"DoorwayConfig.aim_lead={value_repr(self.aim_lead)}: must be <= wall_spacing - "
                f"RoomConfig.wall_thickness - 2 * RoomConfig.avatar_radius = {lead:g} m (the aim "
                "point lies where the body fits before the next wall)"
            )
        if self.width <= 2.0 * k:
            raise ValueError(
                f"DoorwayConfig.width={value_repr(self.width)}: must be > 2 * "
                f"RoomConfig.keepout_radius = {2.0 * k:g} m"
            )


class Doorway(Task):
    """Pass every doorway in order, then reach the goal disc, without touching anything
    (:func:`doorway_layout`).

    A doorway is passed when the body centre is ``wall_thickness / 2 + avatar_radius`` beyond
    the wall's centre line: the avatar's disc is past the wall's far face (the walls close the
    room but for their doorways, so that is the only way there). The goal bearing points at the
    next doorway's aim point (:attr:`DoorwayConfig.aim_lead` beyond that line, on the doorway's
    centre line across), then at the goal. The goal distance is the length of the route still
    ahead: straight to the next aim point, on through the later ones, to the goal disc; it is 0
    only in the goal disc, and drops (by at most twice the distance to the aim point) as a
    doorway is passed. The task's observation field ``waypoint_distance`` is the straight
    distance to the point the bearing points at (the aim point, then the goal region), so that
    bearing and waypoint distance make the vector to the current waypoint.

    ``info`` adds, per user, what the nearest wall (the one whose centre line is nearest along
    x) has to do with the body: ``doorways_passed``, ``doorway_index`` (the nearest wall),
    ``doorway_width_m``, ``doorway_along_m`` (body centre minus the wall's centre line, along x:
    negative before it), ``doorway_offset_m`` (body centre minus the doorway centre, across),
    and ``doorway_margin_m`` = width / 2 - avatar radius - |offset|: how far the body could move
    across before touching a jamb while in the doorway (negative: it would touch one).
    """

    name = "doorway"
    description = "pass a sequence of doorways 0.8-1.2 m wide, collision-free"
    collision_free_success = True
    Config = DoorwayConfig
    per_user_fields = (
        *Task.per_user_fields,
        "door_x",
        "door_y",
        "door_w",
        "through_x",
        "aim",
        "rest",
        "avatar_radius",
        "passed",
        "position",
    )

    def __init__(self, batch_size: int, dt: float, config: Any = None) -> None:
        super().__init__(batch_size, dt, config)
        b, n = self.batch_size, self.config.n_doorways
        self.door_x = np.zeros((b, n))  # wall centre lines (m)
        self.door_y = np.zeros((b, n))  # doorway centres, across (m)
        self.door_w = np.ones((b, n))  # doorway widths (m)
        self.through_x = np.zeros((b, n))  # body centre x beyond which a doorway is passed (m)
        self.aim = np.zeros((b, n, 2))  # the aim points (m)
        self.rest = np.zeros((b, n))  # route length from aim point k to the goal disc (m)
        self.avatar_radius = np.zeros(b)
        self.passed = np.zeros(b, np.int64)
        self.position = np.zeros((b, 2))

    def draw_layout(self, room: RoomConfig, rng: np.random.Generator) -> Layout:
        return doorway_layout(room, rng, self.config)

    def draw(self, user: int, room: RoomConfig, rng: np.random.Generator) -> Layout:
        layout = super().draw(user, room, rng)
        walls = layout.obstacles  # two pieces per wall, in wall order
        lo = np.array([w.center[1] + w.half_extents[1] for w in walls[0::2]])
        hi = np.array([w.center[1] - w.half_extents[1] for w in walls[1::2]])
        x = np.array([w.center[0] for w in walls[0::2]])
        through = x + room.wall_thickness / 2.0 + room.avatar_radius
        self.door_x[user], self.door_y[user], self.door_w[user] = x, (lo + hi) / 2.0, hi - lo
        self.through_x[user] = through
        aim = np.column_stack([through + self.config.aim_lead, (lo + hi) / 2.0])
        self.aim[user] = aim
        legs = np.hypot(*np.diff(aim, axis=0).T)
        last = max(float(np.hypot(*(aim[-1] - self.goal[user]))) - layout.goal_radius, 0.0)
        self.rest[user] = np.append(np.cumsum(legs[::-1])[::-1], 0.0) + last
        self.avatar_radius[user] = room.avatar_radius
        return layout

    def reset(self, rows: NDArray[np.intp]) -> None:
        self.passed[rows] = 0

    def _next(self, position: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray]:
        """The doorways each body has passed (the next one's index) and the point the goal
        bearing points at."""
        self.position = position.copy()
        self.passed = k = (self.through_x < position[:, :1]).sum(axis=1)
        ahead = k < self.config.n_doorways
        aim = self.aim[np.arange(self.batch_size), np.minimum(k, self.config.n_doorways - 1)]
        return k, np.where(ahead[:, None], aim, self.goal)

    def goal_distance(self, position: NDArray[np.float64]) -> NDArray[np.float64]:
        k, point = self._next(position)
        kk = np.minimum(k, self.config.n_doorways - 1)
        route = np.hypot(*(position - point).T) + self.rest[np.arange(self.batch_size), kk]
        return np.where(k < self.config.n_doorways, route, super().goal_distance(position))

    def goal_point(self, position: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._next(position)[1]

    def fields(self) -> tuple[Field, ...]:
        return (
            Field(
                "waypoint_distance",
                scale=MAX_GOAL_DISTANCE,
                unit="m",
                doc="distance from the virtual body to the next doorway's aim point (then "
                "to the goal region)",
            ),
        )

    def observe(self, user_step: Any, fresh: NDArray[np.bool_]) -> dict[str, NDArray]:
        k, point = self._next(self.position)
        straight = np.hypot(*(self.position - point).T)
        ahead = k < self.config.n_doorways
        to_goal = super().goal_distance(self.position)
        return {"waypoint_distance": np.where(ahead, straight, to_goal)[:, None]}

    def info(self) -> dict[str, NDArray]:
        p, rows = self.position, np.arange(self.batch_size)
        j = np.argmin(np.abs(self.door_x - p[:, :1]), axis=1)
        width = self.door_w[rows, j]
        offset = p[:, 1] - self.door_y[rows, j]
        return {
            "doorways_passed": self.passed.copy(),
            "doorway_index": j.astype(np.int64),
            "doorway_width_m": width,
            "doorway_along_m": p[:, 0] - self.door_x[rows, j],
            "doorway_offset_m": offset,
            "doorway_margin_m": width / 2.0 - self.avatar_radius - np.abs(offset),
        }


def doorway_layout(
    config: RoomConfig, rng: np.random.Generator, task: DoorwayConfig | None = None
) -> Layout:
    """A Doorway room: ``n_doorways`` walls across the room along +x, each with one gap.

    The interior runs ``(n_doorways + 1) * wall_spacing`` along x and ``width`` along y, centred
    on the origin; wall k (``wall_thickness`` thick, ``wall_height`` tall, its two pieces
    reaching into the side walls) stands at ``(k + 1) * wall_spacing`` from the near end. Each
    gap's width is drawn in ``width_range`` and its centre uniformly where both jambs keep
    ``jamb_min``. The start is in the middle of the first bay along x, anywhere across it that
    keeps ``keepout_radius`` from the side walls, with a random yaw; the goal likewise in the
    last bay. :attr:`Layout.obstacles` holds the wall pieces, in wall order, the lower (-y)
    piece first.

    Args:
        config: room parameters (walls, the avatar, the goal radius; its room size and obstacle
            counts are not used).
        rng: the only source of randomness.
        task: the walls and doorways (defaults if None).

    Returns:
        The layout (local frame, origin (0, 0)).

    Raises:
        ValueError: a room the avatar cannot pass (:meth:`DoorwayConfig.check_room`).
        RuntimeError: if no feasible layout is drawn in ``config.max_attempts`` attempts.
    """
    cfg, rng = config, check_rng(rng)
    dc = DoorwayConfig() if task is None else task
    dc.check_room(cfg)
    n, s, t = dc.n_doorways, dc.wall_spacing, cfg.wall_thickness
    half_l, half_w = (n + 1) * s / 2.0, dc.width / 2.0
    bounds = (-half_l, half_l, -half_w, half_w)
    k = cfg.keepout_radius
    bay = (s - t / 2.0) / 2.0  # the first bay's middle, from the near end
    for _ in range(cfg.max_attempts):
        widths = rng.uniform(*dc.width_range, size=n)
        room = half_w - dc.jamb_min - widths / 2.0
        centres = rng.uniform(-1.0, 1.0, size=n) * room
        pieces = []
        for i in range(n):
            x = -half_l + (i + 1) * s
            lo, hi = centres[i] - widths[i] / 2.0, centres[i] + widths[i] / 2.0
            bottom, top = -half_w - t, half_w + t  # into the side walls
            for a, c in ((bottom, lo), (hi, top)):
                mid = (a + c) / 2.0
                pieces.append(
                    Box((x, float(mid)), (t / 2.0, float(c - a) / 2.0), 0.0, cfg.wall_height)
                )
        start = np.array([-half_l + bay, rng.uniform(-half_w + k, half_w - k)])
        goal = np.array([half_l - bay, rng.uniform(-half_w + k, half_w - k)])
        yaw = float(rng.uniform(-math.pi, math.pi))
        layout = finish_layout(cfg, "doorway", bounds, pieces, start, yaw, goal, None, None)
        if layout is not None:
            return layout
    raise no_layout_error(cfg, "doorway")
