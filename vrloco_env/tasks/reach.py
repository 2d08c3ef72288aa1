"""Reach: stop at arm's reach in front of a pedestal without touching it, then hold the hand on
target there (success: the hand held in the standing band for the dwell time, not a single
collision — touching the pedestal is one)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimators.validation import check_in_range, check_numbers
from vrloco_env.tasks.interact import Interact, InteractConfig, check_hand_hold, interact_layout
from vrloco_env.world import Layout, RoomConfig

__all__ = ["Reach", "ReachConfig", "reach_layout"]


@dataclass(frozen=True)
class ReachConfig:
    """The Reach task's settings: Interact's hand hold and pedestal, and the standing band.

    Attributes:
        hand_tolerance_deg: hand orientation tolerance (deg), as
            :attr:`InteractConfig.hand_tolerance_deg`.
        dwell_s: time the hand must be held within tolerance in the band (s).
        target_range_deg: target hand [yaw, pitch, roll] relative to the torso are drawn
            uniformly within +- these (deg).
        pedestal_half_size: half size of the pedestal's square footprint (m).
        pedestal_height: height of the pedestal (m).
        standoff_range: the standing band: the gap (m) between the avatar's surface and the plane
            of the pedestal's front (local +x) face. 0.3-0.8 m is about arm's reach: an adult's
            arm is roughly 0.7-0.8 m long, shoulder to fingertip, and the avatar's surface is at
            the shoulders (:attr:`RoomConfig.avatar_radius` is the shoulder half-width).
        band_half_width: the band reaches this far (m) to either side of the face's centre
            line (0.5 m: the 0.5 m face and 0.25 m beyond each edge).
    """

    hand_tolerance_deg: float = 15.0
    dwell_s: float = 1.0
    target_range_deg: tuple[float, float, float] = (40.0, 30.0, 60.0)
    pedestal_half_size: float = 0.25
    pedestal_height: float = 1.0
    standoff_range: tuple[float, float] = (0.3, 0.8)
    band_half_width: float = 0.5

    def __post_init__(self) -> None:
        check_hand_hold(self)
        check_numbers(self, "standoff_range", 0.0, 10.0, "m", length=2, ordered=True)
        if self.standoff_range[1] - self.standoff_range[0] < 0.05:
            raise ValueError(
                f"ReachConfig.standoff_range={self.standoff_range!r}: must be at least 0.05 m "
                "deep (high - low), a band a user can stand in"
            )
        check_in_range(self, "band_half_width", 0.05, 10.0, "m")

    @property
    def stand_radius(self) -> float:
        """Radius (m) of the disc inscribed in the band, around its centre: the layout's goal
        disc, which its planned path reaches."""
        return min((self.standoff_range[1] - self.standoff_range[0]) / 2.0, self.band_half_width)

    def interact(self) -> InteractConfig:
        """The :class:`InteractConfig` whose stand point is the middle of the band."""
        return InteractConfig(
            hand_tolerance_deg=self.hand_tolerance_deg,
            dwell_s=self.dwell_s,
            target_range_deg=self.target_range_deg,
            pedestal_half_size=self.pedestal_half_size,
            pedestal_height=self.pedestal_height,
            standoff=sum(self.standoff_range) / 2.0,
        )


class Reach(Interact):
    """Stop in the band in front of the pedestal, without touching it, and hold the hand on
    target (:func:`reach_layout`; the hand hold, its fields and its dwell are
    :class:`~vrloco_env.tasks.interact.Interact`'s).

    The goal region is the band of body centres whose avatar surface is
    ``standoff_range`` from the plane of the pedestal's front face and at most
    ``band_half_width`` to either side of the face's centre line: a rectangle in the pedestal's
    frame, so the goal distance is the exact distance to it. The goal bearing points at the
    band's centre. Touching the pedestal is a collision, and success needs none.

    ``info`` adds, per user: ``pedestal_gap_m`` (the gap between the avatar's surface and the
    pedestal, 0 when touching), ``face_gap_m`` (the gap to the plane of the front face, the
    band's depth coordinate), ``face_lateral_m`` (signed offset from the face's centre line)
    and Interact's ``dwell``.
    """

    name = "reach"
    description = "stop 0.3-0.8 m from the pedestal without touching it, hold the hand on target"
    collision_free_success = True
    Config = ReachConfig
    per_user_fields = (
        *Interact.per_user_fields,
        "pedestal",
        "pedestal_axes",
        "avatar_radius",
        "position",
    )

    def __init__(self, batch_size: int, dt: float, config: Any = None) -> None:
        super().__init__(batch_size, dt, config)
        b = self.batch_size
        self.pedestal = np.zeros((b, 2))
        self.pedestal_axes = np.tile([1.0, 0.0], (b, 1))  # cos, sin of the pedestal's yaw
        self.avatar_radius = np.zeros(b)
        self.position = np.zeros((b, 2))

    def draw_layout(self, room: RoomConfig, rng: np.random.Generator) -> Layout:
        return reach_layout(room, rng, self.config)

    def draw(self, user: int, room: RoomConfig, rng: np.random.Generator) -> Layout:
        layout = super().draw(user, room, rng)
        assert layout.target is not None
        self.pedestal[user] = layout.target.center
        self.pedestal_axes[user] = (math.cos(layout.target.yaw), math.sin(layout.target.yaw))
        self.avatar_radius[user] = room.avatar_radius
        return layout

    def _local(self, position: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """Body centres in the pedestal's frame: (along its +x axis, across it) (m)."""
        self.position = position.copy()
        d = position - self.pedestal
        c, s = self.pedestal_axes[:, 0], self.pedestal_axes[:, 1]
        return c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]

    def goal_distance(self, position: NDArray[np.float64]) -> NDArray[np.float64]:
        along, across = self._local(position)
        gap = along - self.config.pedestal_half_size - self.avatar_radius
        lo, hi = self.config.standoff_range
        depth = np.maximum(np.maximum(lo - gap, gap - hi), 0.0)
        side = np.maximum(np.abs(across) - self.config.band_half_width, 0.0)
        return np.hypot(depth, side)

    def info(self) -> dict[str, NDArray]:
        along, across = self._local(self.position)
        hs = self.config.pedestal_half_size
        qx, qy = np.abs(along) - hs, np.abs(across) - hs
        outside = np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0))
        inside = np.minimum(np.maximum(qx, qy), 0.0)
        return {
            **super().info(),
            "pedestal_gap_m": outside + inside - self.avatar_radius,
            "face_gap_m": along - hs - self.avatar_radius,
            "face_lateral_m": across,
        }


def reach_layout(
    config: RoomConfig, rng: np.random.Generator, task: ReachConfig | None = None
) -> Layout:
    """A Reach room: :func:`~vrloco_env.tasks.interact.interact_layout`'s room with its stand
    point in the middle of the band (:meth:`ReachConfig.interact`) and its goal disc the one
    inscribed in the band (:attr:`ReachConfig.stand_radius`), so that the planned path ends in
    the band.

    Args:
        config: room parameters.
        rng: the only source of randomness.
        task: the pedestal and the band (defaults if None).

    Returns:
        The layout (local frame, origin (0, 0)); :attr:`Layout.target` is the pedestal.

    Raises:
        RuntimeError: if no feasible layout is drawn in ``config.max_attempts`` attempts.
    """
    rc = ReachConfig() if task is None else task
    room = replace(config, goal_radius=rc.stand_radius)
    return replace(interact_layout(room, rng, rc.interact()), task="reach")
