"""The goal seeker: a scripted user that remembers what it has seen and plans around it.

:class:`GoalSeeker` turns toward the goal, steps when aligned, and stops and re-aligns when the
bearing error grows. "Toward the goal" is toward the next stretch of the shortest way around what
the user has seen: it remembers the ray hits in a map of the virtual room (placed by counting its
own detected steps along its virtual heading, exactly how eq 17 moves the body) and plans on it
(:mod:`agents.scripted.planner`), as a VR user who sees the room would.

Why a map: rays are thin. An obstacle may be unseen between two rays from afar, and which edge of
it the rays catch changes as the user turns, so headings computed from one frame of rays jump (the
reactive users show this). The map accumulates every frame, which removes both. A seeker that
chooses its heading from the current rays alone (the free heading nearest the goal bearing, no
memory) reaches only 9-17 of 30 Avoid goals and 26-28 of 30 Approach goals at the default
difficulty: it stalls in front of the obstacle as the rays slide over its edges, with no collision
and with the estimators doing nothing wrong (the policy, not the estimation, loses those
episodes).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from agents.scripted.base import PolicyParams, ScriptedPolicy
from agents.scripted.observation import ObservationLayout, ObsView, ray_points
from agents.scripted.planner import plan_kernel
from estimators.batching import take_rows_in_place
from estimators.kernels import param_record
from estimators.rotations import wrap_angle

__all__ = ["GoalSeeker"]


class GoalSeeker(ScriptedPolicy):
    """Turn toward the goal, step when aligned, re-align when the bearing error grows.

    The user remembers what the rays have shown: every hit goes into a map of the virtual room
    (cells of ``map_cell_m``), placed by dead reckoning from the observation alone — each
    detected step carries the body one step length along the virtual heading, exactly eq (17)'s
    update, so the map is exact under eq (17) locomotion (a blocked step, seen as a step that
    left the goal where it was, does not count). The aim point is ``goal_depth_m`` inside the
    goal region along the goal bearing. Each control step it computes the cost to go from the
    aim point over the map (Dijkstra on the cells farther than ``avatar_radius_m +
    tight_margin_m`` from every hit, dearer within ``margin_m`` and within ``comfort_m`` more;
    unseen cells count as free), then scores the headings every ``candidate_step_deg`` all
    round: a heading qualifies when the next ``go_steps`` step lengths along it keep
    ``margin_m`` (or, at ``tight_penalty_m``, ``tight_margin_m``), or when the next landing —
    two step lengths for a bout that starts now, one for a bout under way — is in the goal;
    its score is the cost to go at the end, plus ``turn_cost_m`` per radian of turning, less
    ``hold_m`` for last step's aim. It turns to the best, walks when aligned within ``go_deg``
    and that way is clear, and stops to re-align beyond ``stop_deg``. A heading into unseen
    space is turned to first, and the rays then show what is there. The clearance map and the
    cost to go are planned again only when the map, its box, the aim point's cell, the user's
    cell or the length to check have changed since the last control step; otherwise the last
    ones are reused (the same inputs, the same maps). When only new hits were marked, the last
    search is repaired where they raised the cost of a step rather than run again (the same
    costs; :mod:`agents.scripted.planner`). ``reuse_plans = False`` plans anew every
    control step (the same actions, slower); ``plans_reused`` counts the user-steps whose plan
    was reused.

    Under the smooth locomotion filter (the smooth-locomotion paper) the body moves between detected
    steps, so the dead-reckoned map is approximate (the filter's lag, well under a metre). Under a
    technique that moves the body without steps (head tilt, look down to move) it places the map
    by the self-motion it sees instead (``PolicyParams.reckons_by_sight``).

    Args:
        layout: observation layout.
        params: behaviour parameters.
    """

    name = "goal_seeker"
    plans_along_walk = True  # its map, way-ahead checks and plans follow the walking direction
    per_user_fields = ScriptedPolicy.per_user_fields

    def __init__(
        self, layout: ObservationLayout | None = None, params: PolicyParams | None = None
    ) -> None:
        super().__init__(layout, params)
        p = self.params
        self._cells = round(p.map_size_m / p.map_cell_m)
        r = p.avatar_radius_m
        self._plan_prm = param_record(
            cell=p.map_cell_m,
            half=0.5 * self._cells * p.map_cell_m,
            look=p.go_steps * p.step_length_m,
            goal_tol=p.goal_depth_m,
            r_tight=r + p.tight_margin_m,
            r_block=self._half_width,
            r_comfort=self._half_width + p.comfort_m,
            comfort_cost=p.comfort_cost,
            tight_cost=p.tight_cost,
            turn_cost=p.turn_cost_m,
            step_a=np.deg2rad(p.candidate_step_deg) * 1.01,
            tight_penalty=p.tight_penalty_m,
            hold=p.hold_m,
        )
        n = int(np.floor(180.0 / p.candidate_step_deg))
        self.candidates = wrap_angle(np.deg2rad(p.candidate_step_deg) * np.arange(-n, n + 1))
        self.candidates = np.unique(np.round(self.candidates, 12))
        # the planner's last clearance map, multipliers and cost to go per user, (B, cells^2)
        # each, its search's steps back and level; which inputs they hold is ``plan_key`` of
        # the state, so a reset row never reuses them
        self._memo: tuple[NDArray, ...] | None = None
        self.reuse_plans = True
        self.plans_reused = 0

    def take_users(self, rows: NDArray[np.intp]) -> None:
        """Keep the users ``rows``, with the planner's memo of each (its ``plan_key`` holds no
        row index, so a kept user goes on reusing its plans). The maps (the memo's, megabytes
        per user, and the occupancy grid) move in place: only the rows that change place are
        copied."""
        r = np.asarray(rows, dtype=np.intp)
        memo, self._memo = self._memo, None
        occ = None if self._state is None else self._state.pop("occ")
        super().take_users(r)
        if occ is not None:
            self._state["occ"] = take_rows_in_place(occ, r)
        if memo is not None:
            self._memo = tuple(take_rows_in_place(m, r) for m in memo)

    def _init_state(self, b: int) -> dict[str, NDArray]:
        n = self._cells
        return {
            "walking": np.zeros(b, bool),
            "settle": np.zeros(b, np.int64),
            "started": np.zeros(b, bool),
            "landed": np.zeros(b, bool),
            "aim": np.full(b, np.nan),  # last aimed heading, room frame (rad)
            "goal_vec": np.zeros((b, 2)),
            "pos": np.zeros((b, 2)),
            "occ": np.zeros((b, n, n), bool),
            "lo": np.full((b, 2), n, np.int64),
            "hi": np.full((b, 2), -1, np.int64),
            "version": np.zeros(b, np.int64),  # changes of ``occ`` so far
            "plan_key": np.full((b, 10), -1, np.int64),  # what the planner's memo is from
        }

    def _remember(self, v: ObsView, state: dict[str, NDArray]) -> tuple[NDArray, NDArray]:
        """Dead-reckon the body and put the current ray hits into the map; the map's version
        before (B,) and the cells marked now (K, 3) = (user, i, j).

        A detected step toward or away from the goal that left the goal where it was (the
        vector to the goal region, in the room frame, unchanged to 1 mm) was blocked by an
        obstacle — the user sees that they did not move — and does not move the reckoned
        position.
        """
        p = self.params
        ang = v.heading + v.bearing
        goal_vec = v.waypoint[:, None] * np.stack([np.cos(ang), np.sin(ang)], -1)
        walk = v.heading - self.walk_offset(v)  # where the steps carry the body
        u = np.stack([np.cos(walk), np.sin(walk)], -1)
        # a step with a fair component toward (or away from) the goal changes the distance to a
        # goal disc or line; one that did not was blocked (a sideways step along an end line
        # leaves the goal vector alone either way, and is trusted)
        to_goal = goal_vec / np.maximum(np.linalg.norm(goal_vec, axis=1, keepdims=True), 1e-9)
        radial = np.abs(np.sum(u * to_goal, axis=1)) > 0.2
        still = np.linalg.norm(goal_vec - state["goal_vec"], axis=1) < 1e-3
        blocked = still & radial & (v.distance > 0.0)
        state["goal_vec"] = goal_vec
        if p.reckons_by_sight:  # the self-motion it sees, turned into the room by the heading
            c, s = np.cos(v.heading)[:, None], np.sin(v.heading)[:, None]
            seen = np.concatenate(
                [c * v.moved[:, :1] - s * v.moved[:, 1:], s * v.moved[:, :1] + c * v.moved[:, 1:]],
                axis=1,
            )
            state["pos"] += np.where(state["started"][:, None], seen, 0.0)
        else:
            moved = np.where(state["started"] & ~blocked, v.steps * p.step_length_m, 0.0)
            state["pos"] += moved[:, None] * u
        state["started"][:] = True
        pts, ok = ray_points(v.rays, self.offsets, self.layout.ray_range_m)
        c, s = np.cos(v.heading)[:, None], np.sin(v.heading)[:, None]
        wx = state["pos"][:, 0:1] + c * pts[..., 0] - s * pts[..., 1]
        wy = state["pos"][:, 1:2] + s * pts[..., 0] + c * pts[..., 1]
        half = 0.5 * self._cells * p.map_cell_m
        ix = np.floor((wx + half) / p.map_cell_m).astype(np.int64)
        iy = np.floor((wy + half) / p.map_cell_m).astype(np.int64)
        ok = ok & (ix >= 0) & (ix < self._cells) & (iy >= 0) & (iy < self._cells)
        rows = np.broadcast_to(np.arange(ok.shape[0])[:, None], ok.shape)
        r, ix_ok, iy_ok = rows[ok], ix[ok], iy[ok]
        new = ~state["occ"][r, ix_ok, iy_ok]
        state["occ"][r, ix_ok, iy_ok] = True
        changed = np.zeros(ok.shape[0], bool)
        changed[r[new]] = True
        prior = state["version"].copy()
        state["version"] += changed
        big, small = self._cells, -1
        state["lo"][:, 0] = np.minimum(state["lo"][:, 0], np.where(ok, ix, big).min(1))
        state["lo"][:, 1] = np.minimum(state["lo"][:, 1], np.where(ok, iy, big).min(1))
        state["hi"][:, 0] = np.maximum(state["hi"][:, 0], np.where(ok, ix, small).max(1))
        state["hi"][:, 1] = np.maximum(state["hi"][:, 1], np.where(ok, iy, small).max(1))
        return prior, np.stack([r[new], ix_ok[new], iy_ok[new]], axis=-1)

    def _steer(self, v, state):
        p = self.params
        prior, news = self._remember(v, state)
        b = v.heading.size
        offset = self.walk_offset(v)
        walk = v.heading - offset  # the plan is relative to the walking direction
        ang = v.heading + v.bearing
        depth = v.waypoint + p.goal_depth_m  # the next waypoint (Doorway), else the goal
        target = state["pos"] + depth[:, None] * np.stack([np.cos(ang), np.sin(ang)], -1)
        # a bout's first two steps land together: until they have, the next move is 2 SL (a
        # technique that moves the body continuously has no landing)
        stepless = not p.moves_by_steps
        state["landed"] = state["walking"] & (state["landed"] | (v.steps > 0) | stepless)
        single = state["walking"] & state["landed"]
        land = np.where(single | stepless, 0.0, 2.0 * p.step_length_m)
        keep_len = np.where(single, p.stop_steps * p.step_length_m, self._plan_prm[0]["look"])
        aim, valid = np.zeros(b), np.zeros(b, bool)
        can_go, can_keep = np.zeros(b, bool), np.zeros(b, bool)
        active = np.ones(b, bool) if self._active is None else self._active
        if self._memo is None or self._memo[0].shape[0] != b:
            n = (self._cells + 2) ** 2  # the planner's box, padded all round
            self._memo = (
                np.empty((b, n)),
                np.empty((b, n)),
                np.empty((b, n)),
                np.empty((b, n), np.int8),
                np.zeros(b, np.int64),
            )
        if not self.reuse_plans:
            state["plan_key"][:] = -1
        key = state["plan_key"].copy()
        plan_kernel(b)(
            (state["occ"], state["lo"], state["hi"], state["version"], prior, news),
            state["pos"],
            walk,
            target,
            keep_len,
            land,
            state["aim"],
            active,
            self.candidates,
            self._plan_prm,
            (state["plan_key"], *self._memo),
            (aim, valid, can_go, can_keep),
        )
        self.plans_reused += int(
            np.count_nonzero(np.all(key == state["plan_key"], axis=1) & active & (key[:, 0] >= 0))
        )
        state["aim"] = np.where(valid, walk + aim, np.nan)
        return np.where(valid, aim, v.bearing + offset), valid, can_go, can_keep
