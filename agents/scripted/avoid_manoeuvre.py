"""The avoid manoeuvre: Zhang 2021's Fig. 5 turn-away-and-back as a scripted user.

:class:`AvoidManoeuvre` walks at the goal; when an obstacle stands on the line ahead it turns away
by a fixed angle, steps until the original heading is clear, turns back to the original heading and
walks on. It knows only the current rays and a few numbers per user (its phase, the remembered
heading, the side it turned to).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from agents.scripted.base import PolicyParams, ScriptedPolicy
from agents.scripted.observation import ObservationLayout
from estimators.rotations import wrap_angle

__all__ = ["AvoidManoeuvre"]


class AvoidManoeuvre(ScriptedPolicy):
    """Zhang 2021 Fig. 5: turn away, step, turn back to the original heading.

    Phases per user: *cruise* (turn to the goal, walk when aligned); when the way along the
    heading, seen by the rays, is free for less than ``trigger_m`` short of the goal, remember
    the goal heading, pick the side whose rays see farther and *turn away* by ``away_deg``;
    *sidestep* — walk on the new heading until the rays show the remembered heading free for
    ``trigger_m + beyond_m`` (past where the obstacle stood), or into the goal region; *turn
    back* to the remembered heading; then *cruise* again (a new obstacle starts a new
    manoeuvre). If the way ahead closes while side-stepping, it turns back early and
    tries the other side at the next manoeuvre. No memory beyond these few numbers.

    Args:
        layout: observation layout.
        params: behaviour parameters.
        away_deg: how far to turn away (deg); Zhang 2021 Fig. 5 shows roughly 45 deg.
        trigger_m: start the manoeuvre when the obstacle ahead is this close (m).
        beyond_m: how far past the trigger distance the original heading must be free before
            turning back (m).
    """

    name = "avoid_manoeuvre"
    CRUISE, AWAY, SIDESTEP, BACK = 0, 1, 2, 3
    per_user_fields = ScriptedPolicy.per_user_fields  # all its per-row state is in ``_state``

    def __init__(
        self,
        layout: ObservationLayout | None = None,
        params: PolicyParams | None = None,
        away_deg: float = 40.0,
        trigger_m: float = 2.0,
        beyond_m: float = 1.5,
    ) -> None:
        super().__init__(layout, params)
        if not 5.0 <= away_deg <= 90.0:
            raise ValueError(f"away_deg must be in [5, 90] deg, got {away_deg}")
        if not 0.5 <= trigger_m <= self.layout.ray_range_m:
            raise ValueError(
                f"trigger_m must be in [0.5, {self.layout.ray_range_m}] m (the ray range), "
                f"got {trigger_m}"
            )
        if not 0.0 <= beyond_m <= 10.0:
            raise ValueError(f"beyond_m must be in [0, 10] m, got {beyond_m}")
        self.away = np.deg2rad(away_deg)
        self.trigger = float(trigger_m)
        self.beyond = float(beyond_m)

    def _init_state(self, b: int) -> dict[str, NDArray]:
        return {
            "walking": np.zeros(b, bool),
            "settle": np.zeros(b, np.int64),
            "phase": np.zeros(b, np.int64),
            "heading0": np.zeros(b),
            "side": np.zeros(b),
            "failed": np.zeros(b),  # side of a manoeuvre that got stuck: try the other one
        }

    def _steer(self, v, state):
        p = self.params
        sl = p.step_length_m
        phase, h0, side = state["phase"], state["heading0"], state["side"]
        ahead = self._ray_free(v, np.zeros(1))[:, 0]
        # cruise -> turn away when the way at the goal is blocked
        blocked = (
            (phase == self.CRUISE)
            & (np.abs(v.bearing) < np.deg2rad(p.stop_deg))
            & (ahead < np.minimum(self.trigger, v.distance + 0.5 * sl))
        )
        pos_side, neg_side = self.offsets > 0, self.offsets < 0
        left = v.rays[:, pos_side].mean(1) if np.any(pos_side) else v.rays[:, 0]
        right = v.rays[:, neg_side].mean(1) if np.any(neg_side) else v.rays[:, 0]
        h0 = np.where(blocked, v.heading + v.bearing, h0)
        fresh_side = np.where(left >= right, 1.0, -1.0)
        side = np.where(blocked, np.where(state["failed"] != 0, -state["failed"], fresh_side), side)
        state["failed"] = np.where(blocked, 0.0, state["failed"])
        phase = np.where(blocked, self.AWAY, phase)
        to_h0 = wrap_angle(h0 - v.heading)
        away_target = wrap_angle(to_h0 + side * self.away)
        # turn away -> sidestep when turned
        phase = np.where(
            (phase == self.AWAY) & (np.abs(away_target) < np.deg2rad(p.go_deg)),
            self.SIDESTEP,
            phase,
        )
        # sidestep -> turn back when the original heading is free (or the way ahead closes)
        in_fan = np.abs(to_h0) <= np.max(np.abs(self.offsets)) + 1e-9
        free_h0 = self._ray_free(v, to_h0[:, None])[:, 0]
        side_stepping = phase == self.SIDESTEP
        clear_len = np.minimum(v.distance + 0.5 * sl, self.trigger + self.beyond)
        passed = side_stepping & in_fan & (free_h0 >= clear_len)
        stuck = side_stepping & ~state["walking"] & (ahead < p.stop_steps * sl)
        phase = np.where(passed | stuck, self.BACK, phase)
        state["failed"] = np.where(stuck, side, state["failed"])
        # turn back -> cruise when turned back
        phase = np.where(
            (phase == self.BACK) & (np.abs(to_h0) < np.deg2rad(p.go_deg)), self.CRUISE, phase
        )
        target = np.select(
            [phase == self.AWAY, phase == self.SIDESTEP, phase == self.BACK],
            [away_target, away_target, to_h0],
            v.bearing,
        )
        want = (phase == self.CRUISE) | (phase == self.SIDESTEP)
        state["phase"], state["heading0"], state["side"] = phase, h0, side
        return target, want, *self._ray_gate(v, ahead)
