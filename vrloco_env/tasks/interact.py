"""Interact: approach a pedestal, then hold the hand — as the Kinect pipeline estimates it —
within :attr:`InteractConfig.hand_tolerance_deg` of a target orientation for
:attr:`InteractConfig.dwell_s` while standing at it."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimators.rotations import wrap_angle
from estimators.validation import check_in_range, check_numbers
from vrloco_env._hand_frame_numba import hand_error
from vrloco_env.observation import Field
from vrloco_env.tasks.base import Task
from vrloco_env.world import (
    Box,
    Layout,
    RoomConfig,
    check_rng,
    finish_layout,
    no_layout_error,
    room_bounds,
    scatter_obstacles,
    solid_distance,
)

__all__ = ["Interact", "InteractConfig", "check_hand_hold", "hand_error", "interact_layout"]


@dataclass(frozen=True)
class InteractConfig:
    """The Interact task's settings.

    Attributes:
        hand_tolerance_deg: hand orientation tolerance (deg): the rotation angle between the
            estimated and the target hand orientation.
        dwell_s: time the hand must be held within tolerance in the goal region (s).
        target_range_deg: target hand [yaw, pitch, roll] relative to the torso are drawn
            uniformly within +- these (deg).
        pedestal_half_size: half size of the pedestal's square footprint (m).
        pedestal_height: height of the pedestal (1.0 m, a table/pedestal top at hand height).
        standoff: gap between the avatar surface at the goal and the pedestal face (0.3 m:
            within arm's reach).
    """

    hand_tolerance_deg: float = 15.0
    dwell_s: float = 1.0
    target_range_deg: tuple[float, float, float] = (40.0, 30.0, 60.0)
    pedestal_half_size: float = 0.25
    pedestal_height: float = 1.0
    standoff: float = 0.3

    def __post_init__(self) -> None:
        check_hand_hold(self)
        check_in_range(self, "standoff", 0.0, 1000.0, "m")


def check_hand_hold(config: Any) -> None:
    """Check the hand-hold and pedestal fields a task config shares with :class:`InteractConfig`
    (``hand_tolerance_deg``, ``dwell_s``, ``target_range_deg``, ``pedestal_half_size``,
    ``pedestal_height``): an error names the field and its range."""
    check_in_range(config, "hand_tolerance_deg", 1.0, 90.0, "deg")
    check_in_range(config, "dwell_s", 0.0, 30.0, "s", lo_open=True)
    check_numbers(config, "target_range_deg", 0.0, 90.0, "deg", length=3)
    check_in_range(config, "pedestal_half_size", 0.0, 100.0, "m", lo_open=True)
    check_in_range(config, "pedestal_height", 0.0, 100.0, "m", lo_open=True)


class Interact(Task):
    """Stand at the pedestal and hold a target hand orientation (:func:`interact_layout`)."""

    name = "interact"
    description = "reach the pedestal and hold the hand at a target orientation"
    Config = InteractConfig
    per_user_fields = (*Task.per_user_fields, "hand_target", "dwell", "hand_err", "_closer")

    def __init__(self, batch_size: int, dt: float, config: Any = None) -> None:
        super().__init__(batch_size, dt, config)
        self.hand_target = np.zeros((self.batch_size, 3))
        self.dwell = np.zeros(self.batch_size)
        self.hand_err = np.full(self.batch_size, np.nan)  # the last known error (rad)
        self._closer = np.zeros(self.batch_size)  # how much closer in the last step (rad)

    def draw_layout(self, room: RoomConfig, rng: np.random.Generator) -> Layout:
        return interact_layout(room, rng, self.config)

    def draw(self, user: int, room: RoomConfig, rng: np.random.Generator) -> Layout:
        layout = super().draw(user, room, rng)
        lim = np.deg2rad(np.asarray(self.config.target_range_deg, dtype=np.float64))
        self.hand_target[user] = rng.uniform(-lim, lim)
        return layout

    def reset(self, rows: NDArray[np.intp]) -> None:
        self.dwell[rows] = 0.0
        self.hand_err[rows] = np.nan
        self._closer[rows] = 0.0

    def finished(self, in_goal: NDArray[np.bool_], user_step: Any) -> NDArray[np.bool_]:
        err = hand_error(user_step.hand_est, self.hand_target)
        known = np.isfinite(err) & np.isfinite(self.hand_err)
        self._closer = np.where(known, self.hand_err - np.where(known, err, 0.0), 0.0)
        self.hand_err = np.where(np.isfinite(err), err, self.hand_err)
        holding = in_goal & (err <= np.deg2rad(self.config.hand_tolerance_deg))
        self.dwell = np.where(holding, self.dwell + self.dt, 0.0)
        return self.dwell >= self.config.dwell_s - 1e-9

    def hand_progress(self) -> NDArray[np.float64]:
        return self._closer

    def fields(self) -> tuple[Field, ...]:
        return (
            Field(
                "hand_error",
                ("hand_error_yaw", "hand_error_pitch", "hand_error_roll"),
                math.pi,
                "rad",
                "target minus estimated hand [yaw, pitch, roll] (0 without "
                "estimate; the target itself just after a reset)",
            ),
            Field("dwell", doc="fraction of the dwell time held so far"),
        )

    def observe(self, user_step: Any, fresh: NDArray[np.bool_]) -> dict[str, Any]:
        target = self.hand_target
        if user_step is None:
            err = target.copy()
        else:
            est = user_step.hand_est
            ok = np.all(np.isfinite(est), axis=-1) & ~fresh
            diff = wrap_angle(target - np.nan_to_num(est))
            err = np.where(fresh[:, None], target, np.where(ok[:, None], diff, 0.0))
        return {"hand_error": err, "dwell": (self.dwell / self.config.dwell_s)[:, None]}

    def info(self) -> dict[str, NDArray]:
        return {"dwell": self.dwell.copy()}


def interact_layout(
    config: RoomConfig, rng: np.random.Generator, task: InteractConfig | None = None
) -> Layout:
    """An Interact room: an Approach room whose goal is the stand point in front of a pedestal.

    The pedestal (square footprint ``pedestal_half_size``, ``pedestal_height`` tall, random yaw)
    is placed so that its stand point — ``pedestal_half_size + avatar_radius + standoff`` in front
    of its local +x face — keeps ``keepout_radius`` from the walls. The start is at least
    ``min_start_goal_distance`` from the stand point and ``keepout_radius`` from the pedestal;
    the other obstacles keep out of both and clear of the pedestal.

    Args:
        config: room parameters.
        rng: the only source of randomness.
        task: the pedestal (:class:`InteractConfig`; defaults if None).

    Returns:
        The layout (local frame, origin (0, 0)); :attr:`Layout.target` is the pedestal.

    Raises:
        RuntimeError: if no feasible layout is drawn in ``config.max_attempts`` attempts.
    """
    cfg, rng = config, check_rng(rng)
    ped = InteractConfig() if task is None else task
    bounds = room_bounds(cfg)
    k = cfg.keepout_radius
    inner = np.array([[bounds[0] + k, bounds[2] + k], [bounds[1] - k, bounds[3] - k]])
    hs = ped.pedestal_half_size
    reach = hs + cfg.avatar_radius + ped.standoff
    for _ in range(cfg.max_attempts):
        yaw_t = float(rng.uniform(-np.pi, np.pi))
        goal = rng.uniform(inner[0], inner[1])
        center = goal - reach * np.array([math.cos(yaw_t), math.sin(yaw_t)])
        start = rng.uniform(inner[0], inner[1])
        yaw = float(rng.uniform(-np.pi, np.pi))
        rb = hs * math.sqrt(2.0)
        if (
            center[0] - rb < bounds[0]
            or center[0] + rb > bounds[1]
            or center[1] - rb < bounds[2]
            or center[1] + rb > bounds[3]
        ):
            continue
        target = Box((float(center[0]), float(center[1])), (hs, hs), yaw_t, ped.pedestal_height)
        if np.hypot(*(goal - start)) < cfg.min_start_goal_distance:
            continue
        if solid_distance((target,), start[None])[0] < k:
            continue
        obstacles = scatter_obstacles(cfg, rng, bounds, [(start, k), (goal, k), (center, rb + k)])
        if obstacles is None:
            continue
        layout = finish_layout(cfg, "interact", bounds, obstacles, start, yaw, goal, None, target)
        if layout is not None:
            return layout
    raise no_layout_error(cfg, "interact")
