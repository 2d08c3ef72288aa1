"""The reactive avoider: a potential field on the current rays (Khatib 1986) as a scripted user.

:class:`ReactiveAvoider` lets the goal attract the heading and close ray hits repel it, with a
fixed detour toward the more open side where the field stalls in front of an obstacle. No memory
beyond the detour heading: a baseline that keeps the classic weakness of potential fields.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from agents.scripted.base import PolicyParams, ScriptedPolicy
from agents.scripted.observation import ObservationLayout
from estimators.rotations import wrap_angle

__all__ = ["ReactiveAvoider"]


class ReactiveAvoider(ScriptedPolicy):
    """A potential field on the VR rays: the goal attracts, close ray hits repel.

    The aimed heading is the direction of ``goal_weight * e(bearing) - sum_j w_j e(offset_j)``
    with ``w_j = (1 / (r_j - avatar radius) - 1 / influence_m)^+`` for ray j at range ``r_j``
    (Khatib's repulsive potential gradient, up to a constant); it walks when the heading is near
    the aim and the way ahead is free (the walk gate of :class:`ScriptedPolicy`). Where the field
    points at a blocked way it turns ``detour_deg`` toward the more open side and holds that
    heading until the goal bearing is clear (or that way closes too). It knows only the
    current rays, so it can still dither between obstacles: the classic weakness of potential
    fields, kept on purpose as a baseline.

    Args:
        layout: observation layout.
        params: behaviour parameters.
        influence_m: ray hits closer than this repel (m).
        goal_weight: attraction of the goal (1/m: in the units of the repulsion).
        detour_deg: when the field points at a blocked way (its symmetric local minimum in
            front of an obstacle), turn this far toward the side whose rays see farther (deg).
        clear_m: the detour ends when the goal bearing is free for this long (m), or into the
            goal region.
    """

    name = "reactive_avoider"
    per_user_fields = ScriptedPolicy.per_user_fields  # all its per-row state is in ``_state``

    def __init__(
        self,
        layout: ObservationLayout | None = None,
        params: PolicyParams | None = None,
        influence_m: float = 1.5,
        goal_weight: float = 1.0,
        detour_deg: float = 45.0,
        clear_m: float = 3.5,
    ) -> None:
        super().__init__(layout, params)
        if not 0.1 <= influence_m <= self.layout.ray_range_m:
            raise ValueError(
                f"influence_m must be in [0.1, {self.layout.ray_range_m}] m, got {influence_m}"
            )
        if not 0.0 < goal_weight <= 100.0:
            raise ValueError(f"goal_weight must be in (0, 100], got {goal_weight}")
        if not 0.0 < detour_deg <= 90.0:
            raise ValueError(f"detour_deg must be in (0, 90] deg, got {detour_deg}")
        self.influence = float(influence_m)
        self.goal_weight = float(goal_weight)
        self.detour = np.deg2rad(detour_deg)
        if not 0.5 <= clear_m <= self.layout.ray_range_m:
            raise ValueError(
                f"clear_m must be in [0.5, {self.layout.ray_range_m}] m, got {clear_m}"
            )
        self.clear_m = float(clear_m)

    def _steer(self, v, state):
        p = self.params
        ahead = self._ray_free(v, np.zeros(1))[:, 0]
        r = np.maximum(v.rays - p.avatar_radius_m, 0.05)
        w = np.maximum(1.0 / r - 1.0 / self.influence, 0.0)
        fx = self.goal_weight * np.cos(v.bearing) - (w * np.cos(self.offsets)).sum(1)
        fy = self.goal_weight * np.sin(v.bearing) - (w * np.sin(self.offsets)).sum(1)
        target = np.arctan2(fy, fx)
        can_go, can_keep = self._ray_gate(v, ahead)
        # a symmetric field stalls in front of an obstacle: turn to the more open side
        stalled = ~can_go & (np.abs(target) < np.deg2rad(p.go_deg))
        pos_side, neg_side = self.offsets > 0, self.offsets < 0
        left = v.rays[:, pos_side].mean(1) if np.any(pos_side) else v.rays[:, 0]
        right = v.rays[:, neg_side].mean(1) if np.any(neg_side) else v.rays[:, 0]
        detour = v.heading + np.where(left >= right, 1.0, -1.0) * self.detour
        going = state["detour"]
        # the detour ends when the goal bearing is clear well past the obstacle, or its own
        # way closes
        sl = p.step_length_m
        goal_free = self._ray_free(v, v.bearing[:, None])[:, 0]
        in_fan = np.abs(v.bearing) <= np.max(np.abs(self.offsets)) + 1e-9
        clear = in_fan & (goal_free >= np.minimum(v.distance + 0.5 * sl, self.clear_m))
        done = clear | (state["walking"] & ~can_keep)
        going = np.where(done, np.nan, going)
        going = np.where(stalled & np.isnan(going), detour, going)
        state["detour"] = going
        target = np.where(np.isnan(going), target, wrap_angle(going - v.heading))
        return target, np.ones_like(ahead, bool), can_go, can_keep

    def _init_state(self, b: int) -> dict[str, NDArray]:
        return {**super()._init_state(b), "detour": np.full(b, np.nan)}
