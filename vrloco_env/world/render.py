"""Pictures of an episode: a top-down map drawn with OpenCV and a first-person view from PyBullet.

The map shows the room (walls, obstacles, the goal or end line, the Interact pedestal), the true
path (where perfect sensing would have walked, grey) and the virtual path (what the estimates did,
blue), the virtual body with its heading, the VR rays, and the estimated hand axes (Yao 2023 draws
them on the colour image; we draw them in a corner of the map).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from estimators import rotations as rot
from vrloco_env.world.geometry import Box
from vrloco_env.world.layout import Layout

__all__ = ["draw_map"]

_BG = (245, 245, 240)
_WALL = (150, 150, 145)
_OBSTACLE = (60, 90, 185)  # BGR-free: we draw RGB directly
_GOAL = (40, 170, 60)
_TRUE = (150, 150, 150)
_VIRTUAL = (30, 90, 220)
_RAY = (230, 170, 40)
_BODY = (20, 20, 20)


def draw_map(
    layout: Layout,
    position: NDArray,
    yaw: float,
    virtual_path: NDArray,
    true_path: NDArray,
    ray_ranges: NDArray,
    ray_offsets: NDArray,
    hand_ypr: NDArray | None = None,
    size: int = 480,
) -> NDArray[np.uint8]:
    """A (size, size, 3) uint8 RGB top-down map of one user's room, in the room's local frame."""
    x0, x1, y0, y1 = layout.bounds
    margin = 0.4
    span = max(x1 - x0, y1 - y0) + 2 * margin
    scale = size / span
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2

    def px(p: NDArray) -> NDArray[np.int32]:
        p = np.asarray(p, dtype=np.float64).reshape(-1, 2)
        u = (p[:, 0] - cx) * scale + size / 2
        v = size / 2 - (p[:, 1] - cy) * scale
        return np.stack([u, v], -1).round().astype(np.int32)

    img = np.full((size, size, 3), _BG, dtype=np.uint8)
    for solid, color in [(w, _WALL) for w in layout.walls] + [
        (o, _OBSTACLE) for o in layout.obstacles
    ]:
        _fill_solid(img, solid, color, px, scale)
    if layout.target is not None:
        _fill_solid(img, layout.target, (120, 60, 150), px, scale)
    if layout.goal_line is not None:
        a, b = px(np.asarray(layout.goal_line))
        cv2.line(img, tuple(int(v) for v in a), tuple(int(v) for v in b), _GOAL, 3)
    else:
        g = px(layout.goal)[0]
        cv2.circle(img, (int(g[0]), int(g[1])), max(2, int(layout.goal_radius * scale)), _GOAL, 2)
    if len(true_path) > 1:
        cv2.polylines(img, [px(true_path)], False, _TRUE, 2, cv2.LINE_AA)
    if len(virtual_path) > 1:
        cv2.polylines(img, [px(virtual_path)], False, _VIRTUAL, 2, cv2.LINE_AA)
    p = np.asarray(position, dtype=np.float64)
    for r, off in zip(ray_ranges, ray_offsets, strict=True):
        end = p + r * np.array([np.cos(yaw + off), np.sin(yaw + off)])
        a, b = px(p)[0], px(end)[0]
        cv2.line(img, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), _RAY, 1, cv2.LINE_AA)
    c = px(p)[0]
    cv2.circle(img, (int(c[0]), int(c[1])), max(2, int(layout.avatar_radius * scale)), _BODY, 2)
    nose = px(p + 0.45 * np.array([np.cos(yaw), np.sin(yaw)]))[0]
    cv2.line(img, (int(c[0]), int(c[1])), (int(nose[0]), int(nose[1])), _BODY, 2, cv2.LINE_AA)
    if hand_ypr is not None and np.all(np.isfinite(hand_ypr)):
        _hand_axes(img, np.asarray(hand_ypr, dtype=np.float64), size)
    return img


def _fill_solid(img, solid, color, px, scale) -> None:
    if isinstance(solid, Box):
        hx, hy = solid.half_extents
        c, s = np.cos(solid.yaw), np.sin(solid.yaw)
        corners = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]]) @ np.array(
            [[c, s], [-s, c]]
        ) + np.asarray(solid.center)
        cv2.fillPoly(img, [px(corners)], color)
    else:
        ctr = px(solid.center)[0]
        cv2.circle(img, (int(ctr[0]), int(ctr[1])), max(1, int(solid.radius * scale)), color, -1)


def _hand_axes(img: NDArray[np.uint8], hand_ypr: NDArray, size: int) -> None:
    """The hand frame's x (red), y (green), z (blue) axes, seen from above, in the top-right."""
    r = rot.quat_to_matrix(rot.quat_from_ypr(hand_ypr))
    centre = np.array([size - 45, 45])
    cv2.circle(img, (int(centre[0]), int(centre[1])), 38, (255, 255, 255), -1)
    for k, color in enumerate([(220, 40, 40), (40, 170, 40), (40, 60, 220)]):
        axis = r[:, k]
        tip = centre + 32 * np.array([axis[0], -axis[1]])
        cv2.arrowedLine(
            img,
            (int(centre[0]), int(centre[1])),
            (int(tip[0]), int(tip[1])),
            color,
            2,
            cv2.LINE_AA,
            tipLength=0.25,
        )
    cv2.putText(
        img,
        "hand",
        (int(centre[0]) - 16, int(centre[1]) + 36),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.35,
        (60, 60, 60),
        1,
        cv2.LINE_AA,
    )
