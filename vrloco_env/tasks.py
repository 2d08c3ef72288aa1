"""The three tasks: what the user is asked to do, when it counts as done, and how it is rewarded.

* ``approach`` — reach the goal in a room with obstacles (success: the virtual body within the
  goal radius).
* ``avoid`` — seed 000's Fig. 5: walk down a corridor, pass the obstacle on the straight line and
  reach the end line (success: the end line crossed without a single collision).
* ``interact`` — approach a pedestal, then hold the hand — as the Kinect pipeline estimates it —
  within ``EnvConfig.hand_tolerance_deg`` of a target orientation for ``EnvConfig.dwell_s``.

Each task is a small strategy over arrays of B users (no Python loop over users per step): the
per-episode quantities (goal point, goal radius or end line, target hand orientation) are drawn at
reset and kept in arrays by :class:`~vrloco_env.core.LocoCore`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators import rotations as rot
from vrloco_env._hand_frame_numba import hand_error as _hand_error_kernel
from vrloco_env.rooms import Layout, RoomConfig, make_layout

__all__ = ["TASKS", "Task", "get_task"]

#: Interact: target hand [yaw, pitch, roll] relative to the torso are drawn within these (deg).
HAND_TARGET_RANGE_DEG = (40.0, 30.0, 60.0)


@dataclass(frozen=True)
class Task:
    """A task kind.

    Attributes:
        name: ``approach``, ``avoid`` or ``interact``.
        collision_free_success: success requires zero collisions in the episode (Avoid).
        hand_target: success also requires holding a hand orientation (Interact).
    """

    name: str
    collision_free_success: bool = False
    hand_target: bool = False

    def draw_layout(self, room: RoomConfig, rng: np.random.Generator) -> Layout:
        """This task's room, drawn from the episode's generator."""
        return make_layout(self.name, room, rng)

    def draw_hand_target(self, rng: np.random.Generator) -> NDArray[np.float64]:
        """Target hand [yaw, pitch, roll] relative to the torso (rad); zeros without a target."""
        if not self.hand_target:
            return np.zeros(3)
        lim = np.deg2rad(np.asarray(HAND_TARGET_RANGE_DEG))
        return rng.uniform(-lim, lim)


TASKS: dict[str, Task] = {
    "approach": Task("approach"),
    "avoid": Task("avoid", collision_free_success=True),
    "interact": Task("interact", hand_target=True),
}


def get_task(name: str) -> Task:
    """The task called ``name``, or a ValueError listing the valid names."""
    if name not in TASKS:
        raise ValueError(f"task={name!r}: must be one of {', '.join(TASKS)}")
    return TASKS[name]


def goal_distance(xy: NDArray, goal: NDArray, radius: NDArray, line_x: NDArray) -> NDArray:
    """Distance (m) from local points (B, 2) to each user's goal region.

    The region is a disc (``goal``, ``radius``) or, where ``line_x`` is finite, the half plane
    beyond the end line x >= line_x (Avoid). Inside the region the distance is 0.
    """
    disc = np.maximum(np.hypot(xy[:, 0] - goal[:, 0], xy[:, 1] - goal[:, 1]) - radius, 0.0)
    line = np.maximum(line_x - xy[:, 0], 0.0)
    return np.where(np.isfinite(line_x), line, disc)


def hand_error(estimate: NDArray, target: NDArray) -> NDArray:
    """Rotation angle (rad) between estimated and target hand orientations ([yaw, pitch, roll]
    (B, 3) each); NaN where there is no estimate. Compiled; see :func:`hand_error_reference`."""
    out = np.empty(estimate.shape[0])
    _hand_error_kernel(np.ascontiguousarray(estimate, dtype=np.float64),
                       np.ascontiguousarray(target, dtype=np.float64), out)  # fmt: skip
    return out


def hand_error_reference(estimate: NDArray, target: NDArray) -> NDArray:
    """The numpy version of :func:`hand_error`."""
    q = rot.quat_multiply(
        rot.quat_conjugate(rot.quat_from_ypr(target)), rot.quat_from_ypr(np.nan_to_num(estimate))
    )
    return np.where(np.all(np.isfinite(estimate), axis=-1), rot.rotation_angle(q), np.nan)
