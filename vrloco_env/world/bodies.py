"""A layout's bodies in the PyBullet world: :func:`build` and the colours it gives them.

The calls go through :class:`vrloco_env.world.sim.Simulation`, the only module that imports
``pybullet``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from vrloco_env.world.geometry import Box, Cylinder, Solid
from vrloco_env.world.layout import Layout

if TYPE_CHECKING:
    from vrloco_env.world.sim import Simulation

__all__ = ["COLORS", "build"]


#: Colours (RGBA in [0, 1]) of the built bodies.
COLORS = {
    "wall": (0.75, 0.75, 0.72, 1.0),
    "obstacle": (0.72, 0.35, 0.25, 1.0),
    "target": (0.25, 0.35, 0.8, 1.0),
    "target_marker": (1.0, 0.8, 0.1, 1.0),
    "goal": (0.1, 0.8, 0.25, 0.6),
    "floor": (0.9, 0.9, 0.86, 1.0),
    "avatar": (0.2, 0.45, 0.95, 1.0),
    "landmark": (0.1, 0.1, 0.1, 1.0),
}


def build(
    sim: Simulation,
    layout: Layout,
    prefix: str = "",
    avatar: bool = True,
    merge: bool = True,
    visuals: bool | None = None,
    landmark_markers: bool = False,
) -> dict[str, int]:
    """Create a layout's bodies in the simulation at ``layout.origin``.

    Solid bodies (hit by rays, touched by avatars): with ``merge`` (the default) ``walls`` and
    ``obstacles`` are one compound body each (:meth:`Simulation.create_compound`: a room builds
    several times faster, and rays report the compound); without it ``wall_i`` and ``obstacle_i``
    are one body per primitive. ``target`` is the Interact pedestal, always its own body so that a
    ray can tell it from the rest. ``avatar`` is the capsule at the start pose, standing on the
    floor. Visual-only bodies, which cost about 0.5 ms each in PyBullet and matter only for
    pictures: ``floor``, ``goal_marker`` (a floor disc of ``goal_radius``, or a strip on the
    Avoid end line), ``target_marker`` (a sphere on the pedestal) and, if asked, ``landmark_k``
    (the head camera projects :attr:`Layout.landmarks` analytically; these are for pictures).

    Every name is prefixed with ``prefix`` (e.g. ``"room3/"`` in a vector env, so that
    ``sim.remove_prefix(prefix)`` removes one room).

    Args:
        sim: the simulation.
        layout: the room.
        prefix: name prefix of every body.
        avatar: create the avatar capsule.
        merge: build walls and obstacles as two compound bodies.
        visuals: create the visual-only bodies; None = only if ``sim.render_mode`` is set.
        landmark_markers: create a visual sphere per landmark (needs ``visuals``).

    Returns:
        Body name (without the prefix) -> PyBullet id.
    """
    ox, oy = layout.origin
    if visuals is None:
        visuals = sim.render_mode is not None
    ids: dict[str, int] = {}

    def add_solid(key: str, s: Solid, color: tuple[float, ...]) -> None:
        pos = [s.center[0] + ox, s.center[1] + oy, s.height / 2.0]
        if isinstance(s, Box):
            he = [s.half_extents[0], s.half_extents[1], s.height / 2.0]
            ids[key] = sim.create_box(prefix + key, he, pos, s.yaw, color)
        else:
            ids[key] = sim.create_cylinder(prefix + key, s.radius, s.height, pos, color)

    def add_group(key: str, solids: tuple[Solid, ...], color: tuple[float, ...]) -> None:
        if not merge:
            for i, s in enumerate(solids):
                add_solid(f"{key[:-1]}_{i}", s, color)
            return
        if not solids:
            return
        boxes = [
            (
                [s.half_extents[0], s.half_extents[1], s.height / 2.0],
                [s.center[0], s.center[1], s.height / 2.0],
                s.yaw,
            )
            for s in solids
            if isinstance(s, Box)
        ]
        cyls = [
            (s.radius, s.height, [s.center[0], s.center[1], s.height / 2.0])
            for s in solids
            if isinstance(s, Cylinder)
        ]
        ids[key] = sim.create_compound(prefix + key, boxes, cyls, [ox, oy, 0.0], color)

    with sim.no_rendering():
        xmin, xmax, ymin, ymax = layout.bounds
        add_group("walls", layout.walls, COLORS["wall"])
        add_group("obstacles", layout.obstacles, COLORS["obstacle"])
        if layout.target is not None:
            add_solid("target", layout.target, COLORS["target"])
        if visuals:
            t = 2.0 * min(layout.walls[0].half_extents)  # wall thickness
            ids["floor"] = sim.create_floor(
                prefix + "floor",
                [(xmin + xmax) / 2.0 + ox, (ymin + ymax) / 2.0 + oy],
                [(xmax - xmin) / 2.0 + t, (ymax - ymin) / 2.0 + t],
                COLORS["floor"],
            )
            if layout.target is not None:
                tc, top = layout.target.center, layout.target.height + 0.08
                ids["target_marker"] = sim.create_marker(
                    prefix + "target_marker",
                    0.08,
                    [tc[0] + ox, tc[1] + oy, top],
                    COLORS["target_marker"],
                )
            gx, gy = layout.goal
            if layout.goal_line is not None:
                (x0, y0), (x1, y1) = layout.goal_line
                ids["goal_marker"] = sim.create_box(
                    prefix + "goal_marker",
                    [0.05, abs(y1 - y0) / 2.0, 0.005],
                    [(x0 + x1) / 2.0 + ox, (y0 + y1) / 2.0 + oy, 0.005],
                    rgba=COLORS["goal"],
                    collide=False,
                )
            else:
                ids["goal_marker"] = sim.create_cylinder(
                    prefix + "goal_marker",
                    layout.goal_radius,
                    0.01,
                    [gx + ox, gy + oy, 0.005],
                    rgba=COLORS["goal"],
                    collide=False,
                )
            if landmark_markers:
                for k, p in zip(layout.landmark_ids.tolist(), layout.landmarks, strict=True):
                    ids[f"landmark_{k}"] = sim.create_marker(
                        prefix + f"landmark_{k}",
                        0.03,
                        [p[0] + ox, p[1] + oy, p[2]],
                        COLORS["landmark"],
                    )
        if avatar:
            sx, sy, yaw = layout.start
            pos = np.array([[sx + ox, sy + oy, layout.avatar_height / 2.0]])
            ids["avatar"] = sim.create_capsule(
                prefix + "avatar",
                layout.avatar_radius,
                layout.avatar_height,
                pos[0],
                COLORS["avatar"],
            )
            sim.set_poses(np.array([ids["avatar"]]), pos, np.array([yaw]))
    return ids
