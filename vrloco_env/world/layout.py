"""A drawn room (:class:`Layout`), the queries on one room, and the building blocks that tasks
draw their rooms with.

A :class:`Layout` is plain data: walls and obstacles as frozen
:class:`~vrloco_env.world.geometry.Box` / :class:`~vrloco_env.world.geometry.Cylinder` primitives
standing on the floor (z = 0), a start pose, a goal region, an optional target pedestal, wall
landmarks for a head camera, and the shortest collision-free path length for the avatar (for SPL,
Anderson et al. 2018, "On Evaluation of Embodied Navigation Agents", arXiv:1807.06757: ``success *
shortest / max(shortest, walked)``).

Frames: every coordinate stored in a layout, and every point passed to or returned by the
functions here, is in the room's **local** frame — x, y in metres, the origin at the centre of the
room's interior, yaw counter-clockwise from +x (ENU, z up, as in :mod:`estimators.rotations`).
:func:`vrloco_env.world.bodies.build` places the room at ``layout.origin`` in the PyBullet world;
:meth:`Layout.to_world` does the same for points. Several rooms tile one world with
:func:`tile_origins`; rooms are closed by walls, so a horizontal ray never leaves its room.

Each task draws its own layout (:mod:`vrloco_env.tasks`, one file per task) with the building
blocks here — :func:`room_bounds`, :func:`scatter_obstacles`, :func:`finish_layout` — from the
``numpy.random.Generator`` it is given (the env's ``np_random``), so the same seed gives the same
layout. :func:`finish_layout` plans the avatar's path (:mod:`vrloco_env.world.planning`); a draw
without a path is redrawn.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass, field, fields, replace
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.validation import check_value
from vrloco_env.world._planning_numba import goal_nearest
from vrloco_env.world.config import RoomConfig
from vrloco_env.world.geometry import (
    Box,
    Cylinder,
    Solid,
    _pack,
    _points,
    _ray_cast_fast,
    _sdf,
    _sdf_fast,
    _Solids,
)
from vrloco_env.world.planning import _in_goal, _path_length, _plan

__all__ = [
    "Layout",
    "check_rng",
    "finish_layout",
    "no_layout_error",
    "ray_cast_2d",
    "room_bounds",
    "scatter_obstacles",
    "signed_distance",
    "tile_origins",
]


@dataclass(frozen=True, eq=False)
class Layout:
    """One drawn room, in its local frame (see the module docstring).

    Attributes:
        task: the name of the task the layout was drawn for (:mod:`vrloco_env.tasks`).
        bounds: interior ``(xmin, xmax, ymin, ymax)`` (m); walls lie outside it.
        walls: wall boxes.
        obstacles: static obstacles (the Interact pedestal is :attr:`target`, not in here).
        start: ``(x, y, yaw)`` start pose of the avatar (m, m, rad).
        goal: ``(x, y)`` goal point (m): the room goal (Approach), the centre of the end line
            (Avoid) or the stand point in front of the pedestal (Interact).
        goal_radius: success radius around :attr:`goal` (m); for Avoid, success is crossing
            :attr:`goal_line` instead.
        goal_line: Avoid only: the end line's two endpoints ``((x, ymin), (x, ymax))``.
        target: Interact only: the pedestal to stand in front of (its local +x face faces the
            goal), an obstacle like any other for collisions and rays.
        landmarks: ``(K, 3)`` points on the inner wall faces (m), for a head camera.
        landmark_ids: ``(K,)`` integer ids of the landmarks.
        path: ``(M, 2)`` planned collision-free path from the start to the goal region (m).
        shortest_path_length: length of :attr:`path` (m): an upper bound, about 1 % above, of
            the shortest collision-free path for the avatar to the goal region (for SPL).
        avatar_radius: avatar radius the path was planned for (m).
        avatar_height: avatar capsule height for :func:`build` (m).
        wall_height: height of the walls (m).
        origin: ``(x, y)`` offset of the room in the PyBullet world (m).
    """

    task: str
    bounds: tuple[float, float, float, float]
    walls: tuple[Box, ...]
    obstacles: tuple[Solid, ...]
    start: tuple[float, float, float]
    goal: tuple[float, float]
    goal_radius: float
    goal_line: tuple[tuple[float, float], tuple[float, float]] | None
    target: Box | None
    landmarks: NDArray[np.float64]
    landmark_ids: NDArray[np.int64]
    path: NDArray[np.float64]
    shortest_path_length: float
    avatar_radius: float
    avatar_height: float
    wall_height: float
    origin: tuple[float, float] = field(default=(0.0, 0.0))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Layout):
            return NotImplemented
        for f in fields(self):
            a, b = getattr(self, f.name), getattr(other, f.name)
            if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
                if not np.array_equal(a, b):
                    return False
            elif a != b:
                return False
        return True

    __hash__ = None  # type: ignore[assignment]

    @property
    def solids(self) -> tuple[Solid, ...]:
        """Everything an avatar collides with: walls, obstacles and the target pedestal."""
        return self.walls + self.obstacles + ((self.target,) if self.target is not None else ())

    @cached_property
    def _packed(self) -> _Solids:
        return _pack(self.solids)

    @property
    def half_extent(self) -> float:
        """Largest distance (m) from the local origin to the outside of a wall, along x or y."""
        xmin, xmax, ymin, ymax = self.bounds
        t = max((min(w.half_extents) for w in self.walls), default=0.0)  # half thickness
        return max(abs(xmin), abs(xmax), abs(ymin), abs(ymax)) + 2.0 * t

    def with_origin(self, origin: ArrayLike) -> Layout:
        """The same layout placed at another world offset ``(x, y)`` (m)."""
        o = np.asarray(origin, dtype=np.float64)
        if o.shape != (2,) or not np.all(np.isfinite(o)):
            raise ValueError(f"origin must be a finite (2,) array in metres, got {origin!r}")
        return replace(self, origin=(float(o[0]), float(o[1])))

    def to_world(self, points: ArrayLike) -> NDArray[np.float64]:
        """Local points ``(..., 2)`` or ``(..., 3)`` to world coordinates (adds the origin)."""
        p = np.array(points, dtype=np.float64)
        if p.ndim == 0 or p.shape[-1] not in (2, 3):
            raise ValueError(f"points must have shape (..., 2) or (..., 3), got {p.shape}")
        p[..., 0] += self.origin[0]
        p[..., 1] += self.origin[1]
        return p

    @property
    def goal_region(self) -> tuple[float, float, float, float]:
        """The goal region as numbers ``(x, y, radius, line_x)``: the disc of
        :attr:`goal_radius` around :attr:`goal`, or where ``line_x`` is not NaN (Avoid's end
        line) the half-plane ``x >= line_x``."""
        line = math.nan if self.goal_line is None else float(self.goal_line[0][0])
        return (float(self.goal[0]), float(self.goal[1]), float(self.goal_radius), line)

    def in_goal(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether local points ``(P, 2)`` are in the goal region (beyond the Avoid end line)."""
        return _in_goal(_points("points", points), self.goal_region)

    def nearest_goal_point(self, points: ArrayLike) -> NDArray[np.float64]:
        """The point of the goal region nearest to each local point ``(P, 2)`` (itself if in it);
        obstacles are ignored."""
        p = np.ascontiguousarray(_points("points", points))
        out = np.empty_like(p)
        goal_nearest(p, *self.goal_region, out)
        return out


def signed_distance(
    layout: Layout, points: ArrayLike, z: float | None = None
) -> NDArray[np.float64]:
    """Signed distance (m) from local points to the nearest wall/obstacle/pedestal surface.

    Negative inside a solid. The avatar of radius r centred at p touches the world where
    ``signed_distance(p) <= r``.

    Args:
        layout: the room.
        points: ``(P, 2)`` local points (m).
        z: if given, only solids taller than ``z`` (m) count: the horizontal slice at that height.

    Returns:
        ``(P,)`` distances (m); +inf if there is no solid.
    """
    return _sdf_fast(layout._packed.above(z), _points("points", points)[None])[0]


def ray_cast_2d(
    layout: Layout,
    origins: ArrayLike,
    angles: ArrayLike,
    max_range: float,
    z: float | None = None,
) -> NDArray[np.float64]:
    """Analytic horizontal ray cast against the room's solids (to cross-check PyBullet's rays).

    Args:
        layout: the room.
        origins: ``(R, 2)`` local ray starts (m).
        angles: ``(R,)`` ray directions, counter-clockwise from +x (rad).
        max_range: ray length (m), > 0.
        z: if given, only solids taller than ``z`` (m) count (rays cast at height z).

    Returns:
        ``(R,)`` distance (m) to the first surface, ``max_range`` where nothing is hit, 0 for a
        ray starting inside a solid.
    """
    o = _points("origins", origins)
    a = np.asarray(angles, dtype=np.float64)
    if a.shape != (o.shape[0],) or not np.all(np.isfinite(a)):
        raise ValueError(f"angles must be a finite ({o.shape[0]},) array in rad, got {a.shape}")
    check_value("max_range", max_range, 0.0, 1e6, "m", lo_open=True)
    r = float(max_range)
    u = np.stack([np.cos(a), np.sin(a)], axis=-1)
    return _ray_cast_fast(layout._packed.above(z), o[None], u[None], r)[0]


def tile_origins(n: int, spacing: float = 30.0) -> NDArray[np.float64]:
    """World offsets ``(n, 2)`` (m) on a square-ish grid, row by row, for n rooms in one world.

    Args:
        n: number of rooms, >= 1.
        spacing: distance between neighbouring origins (m); must exceed twice the largest
            :attr:`Layout.half_extent` (the 14 m Avoid corridor: 7.4 m) — 30 m leaves a wide gap.

    Returns:
        ``(n, 2)`` offsets; the first is ``(0, 0)``.
    """
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"n must be an integer >= 1, got {n!r}")
    check_value("spacing", spacing, 0.0, 1e5, "m", lo_open=True)
    s = float(spacing)
    cols = math.ceil(math.sqrt(n))
    k = np.arange(n)
    return np.stack([(k % cols) * s, (k // cols) * s], axis=-1).astype(np.float64)


def _walls(cfg: RoomConfig, bounds: tuple[float, float, float, float]) -> tuple[Box, ...]:
    """Four walls outside the interior; the x-facing pair covers the corners."""
    xmin, xmax, ymin, ymax = bounds
    t, hgt = cfg.wall_thickness, cfg.wall_height
    cx, cy = (xmin + xmax) / 2.0, (ymin + ymax) / 2.0
    hx, hy = (xmax - xmin) / 2.0, (ymax - ymin) / 2.0
    return (
        Box((cx, ymin - t / 2.0), (hx + t, t / 2.0), 0.0, hgt),
        Box((cx, ymax + t / 2.0), (hx + t, t / 2.0), 0.0, hgt),
        Box((xmin - t / 2.0, cy), (t / 2.0, hy), 0.0, hgt),
        Box((xmax + t / 2.0, cy), (t / 2.0, hy), 0.0, hgt),
    )


def _landmarks(
    cfg: RoomConfig, bounds: tuple[float, float, float, float]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A regular grid of points on each inner wall face: columns ~``landmark_spacing`` apart
    (centred in equal slots, so none sits in a corner), one row per ``landmark_heights``."""
    xmin, xmax, ymin, ymax = bounds
    faces = (
        ((xmin, ymin), (xmax, ymin)),
        ((xmax, ymin), (xmax, ymax)),
        ((xmax, ymax), (xmin, ymax)),
        ((xmin, ymax), (xmin, ymin)),
    )
    pts = []
    for a, b in faces:
        a_, b_ = np.asarray(a), np.asarray(b)
        length = float(np.linalg.norm(b_ - a_))
        n = max(1, round(length / cfg.landmark_spacing))
        s = (np.arange(n) + 0.5) / n
        xy = a_ + s[:, None] * (b_ - a_)
        for z in cfg.landmark_heights:
            pts.append(np.column_stack([xy, np.full(n, float(z))]))
    lm = np.concatenate(pts)
    return lm, np.arange(lm.shape[0], dtype=np.int64)


def _draw_obstacle(
    cfg: RoomConfig, rng: np.random.Generator, size: tuple[float, float], center: NDArray
) -> Solid:
    height = float(rng.uniform(*cfg.obstacle_height_range))
    c = (float(center[0]), float(center[1]))
    if rng.random() < cfg.cylinder_probability:
        return Cylinder(c, float(rng.uniform(*size)), height)
    he = rng.uniform(*size, size=2)
    return Box(c, (float(he[0]), float(he[1])), float(rng.uniform(-np.pi, np.pi)), height)


def _bounding_radius(s: Solid) -> float:
    return s.radius if isinstance(s, Cylinder) else float(np.hypot(*s.half_extents))


def scatter_obstacles(
    cfg: RoomConfig,
    rng: np.random.Generator,
    bounds: tuple[float, float, float, float],
    keep_clear: list[tuple[NDArray[np.float64], float]],
) -> list[Solid] | None:
    """Draw the room's obstacles inside ``bounds``, clear of the given (point, radius) discs and
    of each other (bounding circles); None if one cannot be placed in 50 tries."""
    xmin, xmax, ymin, ymax = bounds
    n = int(rng.integers(cfg.n_obstacles_min, cfg.n_obstacles_max + 1))
    out: list[Solid] = []
    for _ in range(n):
        for _try in range(50):
            proto = _draw_obstacle(cfg, rng, cfg.obstacle_size_range, np.zeros(2))
            rb = _bounding_radius(proto)
            if xmax - xmin <= 2 * rb or ymax - ymin <= 2 * rb:
                continue
            c = np.array([rng.uniform(xmin + rb, xmax - rb), rng.uniform(ymin + rb, ymax - rb)])
            s = replace(proto, center=(float(c[0]), float(c[1])))
            sd = _sdf(_pack((s,)), np.array([p for p, _ in keep_clear]).reshape(-1, 2))
            if np.any(sd < np.array([r for _, r in keep_clear])):
                continue
            if any(np.hypot(*(c - np.asarray(o.center))) < rb + _bounding_radius(o) for o in out):
                continue
            out.append(s)
            break
        else:
            return None
    return out


def room_bounds(cfg: RoomConfig) -> tuple[float, float, float, float]:
    """The interior ``(xmin, xmax, ymin, ymax)`` (m) of a room of ``cfg``'s size, centred."""
    return (
        -cfg.room_width / 2.0,
        cfg.room_width / 2.0,
        -cfg.room_depth / 2.0,
        cfg.room_depth / 2.0,
    )


def finish_layout(
    cfg: RoomConfig,
    task: str,
    bounds: tuple[float, float, float, float],
    obstacles: list[Solid],
    start: NDArray[np.float64],
    yaw: float,
    goal: NDArray[np.float64],
    goal_line: tuple[tuple[float, float], tuple[float, float]] | None,
    target: Box | None,
) -> Layout | None:
    """Plan the path and assemble the layout; None if the goal region is unreachable."""
    walls = _walls(cfg, bounds)
    landmarks, ids = _landmarks(cfg, bounds)
    layout = Layout(
        task=task,
        bounds=tuple(float(b) for b in bounds),  # type: ignore[arg-type]
        walls=walls,
        obstacles=tuple(obstacles),
        start=(float(start[0]), float(start[1]), float(yaw)),
        goal=(float(goal[0]), float(goal[1])),
        goal_radius=cfg.goal_radius,
        goal_line=goal_line,
        target=target,
        landmarks=landmarks,
        landmark_ids=ids,
        path=np.zeros((0, 2)),
        shortest_path_length=math.nan,
        avatar_radius=cfg.avatar_radius,
        avatar_height=cfg.avatar_height,
        wall_height=cfg.wall_height,
    )
    key = (
        task,
        layout.bounds,
        layout.solids,  # frozen dataclasses: equal by type and fields
        layout.start[:2],
        layout.goal,
        layout.goal_radius,
        goal_line,
        cfg.avatar_radius,
        cfg.grid_resolution,
    )
    if key in _PATHS:
        _PATHS.move_to_end(key)
        path = _PATHS[key]
    else:
        path = _plan(
            layout._packed,
            bounds,
            start,
            layout.goal_region,
            cfg.avatar_radius,
            cfg.grid_resolution,
        )
        if path is not None:
            path.setflags(write=False)  # shared by every layout of this geometry
        _PATHS[key] = path
        if len(_PATHS) > _PATHS_KEPT:
            _PATHS.popitem(last=False)
    if path is None:
        return None
    return replace(layout, path=path, shortest_path_length=_path_length(path))


#: Planned paths (None: unreachable) by everything the plan depends on: the solids, bounds, start,
#: goal region, avatar radius and grid. Planning is a pure function of these, and it is most of
#: the cost of drawing a room; the benchmark draws each task's seeds once per technique, so each
#: process plans a room once. The :data:`_PATHS_KEPT` most recently used are kept.
_PATHS: OrderedDict[tuple, NDArray[np.float64] | None] = OrderedDict()
_PATHS_KEPT = 2048


def check_rng(rng: object) -> np.random.Generator:
    """``rng`` if it is a numpy Generator, else a TypeError."""
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return rng


def no_layout_error(cfg: RoomConfig, task: str) -> RuntimeError:
    """The error of a generator that drew no feasible layout in ``cfg.max_attempts``."""
    return RuntimeError(
        f"no feasible {task} layout in max_attempts={cfg.max_attempts} draws; the RoomConfig "
        "leaves too little free space (fewer/smaller obstacles or a larger room would help)"
    )
