"""The environment's engine: B users in B rooms, stepped in one batched call.

Both the single :class:`~vrloco_env.env.VRLocoEnv` (B = 1) and the native
:class:`~vrloco_env.vector.VRLocoVectorEnv` (B = num_envs) are thin Gymnasium shells around
:class:`LocoCore`. Per control step::

    actions -> intents -> SimulatedUsers (motion, IMU, Kinect, estimators, locomotion)
            -> the virtual body moves by the locomotion displacement unless the swept avatar
               would touch a wall or obstacle (then it stays: a collision)
            -> rays from the virtual head, goal bearing and distance -> observation, reward

The world. Each user's room is a :class:`~vrloco_env.rooms.Layout`; the per-step queries (swept
avatar against the room, rays from the virtual head) run on the rooms' exact 2-D geometry
(:class:`~vrloco_env.rooms.RoomBatch`, one compiled call for all users), which the tests check
against PyBullet's own rays and contacts. PyBullet (:class:`~vrloco_env.sim.Simulation`) holds
the same rooms as bodies for rendering — the first-person view and the ``human`` GUI — and is only
created when a render mode asks for it: at 256 users its ray cast alone would take ~14 ms per
step on this machine, 30 times the 2-D twin.

Randomness. User i owns one generator (the single env's ``np_random``; sub-env i's in the vector
env). At each of its resets it draws the room and the task's targets from that generator, then
one integer that seeds the user's stream for motion and sensor noise (``BatchRng.reseed``), so a
sub-env of the vector env behaves exactly like a single env with the same seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import rotations as rot
from vrloco_env._core_numba import attitude_error_kernel, observation_kernel
from vrloco_env.actions import action_to_intent, check_actions
from vrloco_env.batch_rng import BatchRng
from vrloco_env.config import EnvConfig, EstimatorConfig, RewardConfig, SensorConfig
from vrloco_env.rooms import Layout, RoomBatch, RoomConfig
from vrloco_env.tasks import Task, get_task, goal_distance, hand_error
from vrloco_env.users import SimulatedUsers, UserStep

__all__ = ["MAX_GOAL_DISTANCE", "LocoCore", "observation_names"]

_SWEEP_SAMPLES = 8  # points along a step's displacement checked against the room
_SWEEP_FRACTIONS = (np.arange(1, _SWEEP_SAMPLES + 1) / _SWEEP_SAMPLES)[None, :, None]
#: Goal distance (m) that the observation scales to 1 (farther goals read 1).
MAX_GOAL_DISTANCE = 20.0


def observation_names(ray_count: int) -> list[str]:
    """Names of the observation's entries, in order (all scaled into [-1, 1])."""
    return (
        [
            "heading_sin",
            "heading_cos",
            "pitch",
            "roll",  # estimated head attitude (virtual yaw)
            "walking",
            "steps",
            "cadence",  # gait state
            "hand_yaw",
            "hand_pitch",
            "hand_roll",
            "hand_valid",  # estimated hand vs torso
            "goal_bearing_sin",
            "goal_bearing_cos",
            "goal_distance",
        ]  # from the virtual pose
        + [f"ray_{k}" for k in range(ray_count)]
        + ["hand_error_yaw", "hand_error_pitch", "hand_error_roll", "dwell"]  # Interact
    )




@dataclass
class _Episode:
    """Per-user episode state, arrays over the B users."""

    position: NDArray[np.float64]  # (B, 2) virtual body, room frame (m)
    true_position: NDArray[np.float64]  # (B, 2) where perfect sensing would have walked
    collisions: NDArray[np.int64]
    elapsed: NDArray[np.int64]  # control steps since reset
    walked: NDArray[np.float64]  # path length of the virtual body (m)
    distance: NDArray[np.float64]  # to the goal region (m)
    goal: NDArray[np.float64]  # (B, 2)
    goal_radius: NDArray[np.float64]
    line_x: NDArray[np.float64]  # Avoid end line x (NaN elsewhere)
    shortest: NDArray[np.float64]  # shortest path length (m), for SPL
    hand_target: NDArray[np.float64]  # (B, 3) rad
    dwell: NDArray[np.float64]  # s the hand has been held on target in the goal region
    start_time: NDArray[np.float64]  # batch time at reset (s)
    detector_start: NDArray[np.float64]  # step detector's clock at reset, less one sample (s)
    virtual_yaw: NDArray[np.float64]
    done: NDArray[np.bool_] = field(default=None)  # type: ignore[assignment]

    @classmethod
    def empty(cls, b: int) -> _Episode:
        z = np.zeros(b)
        return cls(
            position=np.zeros((b, 2)),
            true_position=np.zeros((b, 2)),
            collisions=np.zeros(b, np.int64),
            elapsed=np.zeros(b, np.int64),
            walked=z.copy(),
            distance=z.copy(),
            goal=np.zeros((b, 2)),
            goal_radius=z.copy(),
            line_x=np.full(b, np.nan),
            shortest=z.copy(),
            hand_target=np.zeros((b, 3)),
            dwell=z.copy(),
            start_time=z.copy(),
            detector_start=z.copy(),
            virtual_yaw=z.copy(),
            done=np.zeros(b, bool),
        )


class LocoCore:
    """B users, each in its own room, with their sensors, estimators and task.

    Args:
        task: ``"approach"``, ``"avoid"`` or ``"interact"``.
        num_users: B.
        config, sensors, estimators, room, reward: the configuration dataclasses.
    """

    def __init__(
        self,
        task: str,
        num_users: int,
        config: EnvConfig,
        sensors: SensorConfig,
        estimators: EstimatorConfig,
        room: RoomConfig,
        reward: RewardConfig,
    ) -> None:
        if not isinstance(num_users, int | np.integer) or num_users < 1:
            raise ValueError(f"num_users must be an integer >= 1, got {num_users!r}")
        self.task: Task = get_task(task)
        self.batch_size = b = int(num_users)
        self.config, self.sensors, self.estimators = config, sensors, estimators
        self.room, self.reward = room, reward
        self.generators = [np.random.default_rng() for _ in range(b)]
        self.rng = BatchRng([np.random.default_rng(0) for _ in range(b)])
        self.users = SimulatedUsers(
            b, self.rng, config.motion, sensors, estimators, pose_source=config.pose_source
        )
        self.dt = self.users.dt
        self.layouts: list[Layout | None] = [None] * b
        self.rooms: RoomBatch | None = None
        self.ep = _Episode.empty(b)
        half = np.deg2rad(config.ray_fov_deg) / 2.0
        if config.ray_count == 1:
            self.ray_offsets = np.zeros(1)
        elif config.ray_fov_deg >= 360.0:
            self.ray_offsets = np.linspace(-np.pi, np.pi, config.ray_count, endpoint=False)
        else:
            self.ray_offsets = np.linspace(-half, half, config.ray_count)
        self.obs_size = len(observation_names(config.ray_count))
        self.last: UserStep | None = None
        self._zeros = np.zeros(b)
        # What observe() reads before a user's first step: nothing estimated yet.
        self._standing = SimpleNamespace(
            ypr_est=np.zeros((b, 3)), walking=np.zeros(b, bool), steps=self._zeros,
            cadence=self._zeros, hand_est=np.full((b, 3), np.nan),
        )  # fmt: skip
        self.last_rays = np.full((b, config.ray_count), config.ray_range_m)
        self.batch_time = 0.0

    # ------------------------------------------------------------------------------ reset
    def reset(
        self, users: ArrayLike | None = None, seeds: list[int | None] | None = None
    ) -> NDArray[np.float32]:
        """Start new episodes for ``users`` (None: all), seeding their generators from ``seeds``
        (one per reset user; None keeps the generator). Returns the observations of all users
        (the others' are their last)."""
        b = self.batch_size
        rows = np.arange(b) if users is None else np.asarray(users, dtype=np.intp).ravel()
        if seeds is not None and len(seeds) != rows.size:
            raise ValueError(f"seeds must hold one entry per reset user ({rows.size})")
        start = np.zeros((rows.size, 3))
        for k, i in enumerate(rows):  # per reset user: its room and targets from its generator
            if seeds is not None and seeds[k] is not None:
                self.generators[i] = np.random.default_rng(seeds[k])
            g = self.generators[i]
            layout = self.task.draw_layout(self.room, g)
            self.ep.hand_target[i] = self.task.draw_hand_target(g)
            self.rng.reseed(i, np.random.default_rng(int(g.integers(2**63))))
            self.layouts[i] = layout
            self.users.set_room(int(i), layout)
            if self.rooms is not None:
                self.rooms.set(i, layout)
            start[k] = layout.start
            self.ep.goal[i] = layout.goal
            self.ep.goal_radius[i] = layout.goal_radius
            self.ep.line_x[i] = layout.goal_line[0][0] if layout.goal_line is not None else np.nan
            self.ep.shortest[i] = layout.shortest_path_length
        if self.rooms is None:
            self.rooms = RoomBatch(self.layouts)  # type: ignore[arg-type]
        if rows.size == b:
            self.batch_time = 0.0  # a full reset restarts the motion model's clock too
        self.users.reset(
            None if rows.size == b else rows, start_yaw=start[:, 2], start_xy=start[:, :2]
        )
        ep = self.ep
        ep.position[rows] = start[:, :2]
        ep.true_position[rows] = start[:, :2]
        ep.virtual_yaw[rows] = start[:, 2]
        ep.collisions[rows] = 0
        ep.elapsed[rows] = 0
        ep.walked[rows] = 0.0
        ep.dwell[rows] = 0.0
        ep.done[rows] = False
        ep.start_time[rows] = self.batch_time
        gait = self.users.gait
        ep.detector_start[rows] = (gait.samples_seen - 1) / gait.fs
        ep.distance[rows] = goal_distance(
            ep.position[rows], ep.goal[rows], ep.goal_radius[rows], ep.line_x[rows]
        )
        self.last_rays[rows] = self._rays(rows)
        return self.observe(reset_rows=rows)

    # ------------------------------------------------------------------------------ step
    def step(
        self, actions: ArrayLike
    ) -> tuple[
        NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict
    ]:
        """Advance every user by one control step.

        Returns:
            observations (B, obs) float32, rewards (B,), terminated (B,), truncated (B,), and a
            dict of per-user arrays (see :meth:`infos`).
        """
        if self.rooms is None:
            raise RuntimeError("reset() must be called before step()")
        a = check_actions(actions, self.batch_size)
        us = self.users.step(action_to_intent(a, self.users.motion_params), validated=True)
        self.last = us
        self.batch_time += self.dt
        ep, cfg, rw = self.ep, self.config, self.reward

        # Move the virtual body unless the swept avatar would touch the room.
        move = us.displacement
        path = ep.position[:, None, :] + _SWEEP_FRACTIONS * move[:, None, :]
        clearance = self.rooms.signed_distance(path).min(axis=1)
        moving = np.hypot(move[:, 0], move[:, 1]) > 1e-12
        blocked = moving & (clearance <= self.room.avatar_radius)
        ep.position = np.where(blocked[:, None], ep.position, ep.position + move)
        ep.walked += np.where(blocked, 0.0, np.hypot(move[:, 0], move[:, 1]))
        ep.collisions += blocked
        ep.virtual_yaw = us.virtual_yaw
        ep.true_position += us.true_displacement
        ep.elapsed += 1

        # Task progress.
        prev = ep.distance
        ep.distance = goal_distance(ep.position, ep.goal, ep.goal_radius, ep.line_x)
        in_goal = ep.distance <= 0.0
        if self.task.hand_target:
            err = hand_error(us.hand_est, ep.hand_target)
            holding = in_goal & (err <= np.deg2rad(cfg.hand_tolerance_deg))
            ep.dwell = np.where(holding, ep.dwell + self.dt, 0.0)
            finished = ep.dwell >= cfg.dwell_s - 1e-9
        else:
            finished = in_goal
        success = finished & ((ep.collisions == 0) | (not self.task.collision_free_success))
        terminated = finished | (blocked & cfg.terminate_on_collision)
        truncated = (ep.elapsed >= cfg.max_episode_steps) & ~terminated
        ep.done = terminated | truncated
        reward = (
            rw.progress * (prev - ep.distance)
            + rw.success * success
            - rw.collision * blocked
            - rw.effort * (a * a).sum(axis=1) / a.shape[1]
            - rw.time
        )
        self.last_rays = self._rays()
        infos = self.infos(us, blocked, success, finished)
        return self.observe(), reward, terminated, truncated, infos

    # ------------------------------------------------------------------------------ views
    def _rays(self, rows: NDArray[np.intp] | None = None) -> NDArray[np.float64]:
        """Ranges (m) along the rays from the virtual head of users ``rows`` (None: all)."""
        assert self.rooms is not None
        rng = self.config.ray_range_m
        r = self.rooms.ray_fan(self.ep.position, self.ep.virtual_yaw, self.ray_offsets, rng)
        return np.minimum(r if rows is None else r[rows], rng)

    def observe(self, reset_rows: NDArray[np.intp] | None = None) -> NDArray[np.float32]:
        """The observations of all users (see :func:`observation_names`).

        Users in ``reset_rows`` have just been reset: they stand still, their estimated attitude
        is the start heading and no hand estimate exists yet. Compiled
        (:func:`~vrloco_env._core_numba.observation_kernel`); :meth:`observe_reference` is the
        numpy version the tests compare it with.
        """
        b, ep, cfg, last = self.batch_size, self.ep, self.config, self.last
        fresh = np.zeros(b, bool) if last is not None else np.ones(b, bool)
        if reset_rows is not None:
            fresh[reset_rows] = True
        if last is None:
            last = self._standing
        out = np.empty((b, self.obs_size), np.float32)
        observation_kernel(
            ep.virtual_yaw, last.ypr_est, last.walking, last.steps, last.cadence, last.hand_est,
            ep.hand_target, self.task.hand_target, self._goal_points(), ep.position, ep.distance,
            self.last_rays, cfg.ray_range_m,
            ep.dwell / cfg.dwell_s if self.task.hand_target else self._zeros,
            fresh, MAX_GOAL_DISTANCE, out,
        )  # fmt: skip
        return out

    def observe_reference(self, reset_rows: NDArray[np.intp] | None = None) -> NDArray[np.float32]:
        """The numpy version of :meth:`observe`."""
        b, ep, cfg = self.batch_size, self.ep, self.config
        last = self.last
        pitch = np.zeros(b)
        roll = np.zeros(b)
        walking = np.zeros(b)
        steps = np.zeros(b)
        cadence = np.zeros(b)
        hand = np.zeros((b, 3))
        hand_valid = np.zeros(b)
        hand_err = np.zeros((b, 3))
        if last is not None:
            pitch, roll = last.ypr_est[:, 1], last.ypr_est[:, 2]
            walking = last.walking.astype(np.float64)
            steps = last.steps
            cadence = last.cadence
            ok = np.all(np.isfinite(last.hand_est), axis=-1)
            hand = np.where(ok[:, None], last.hand_est, 0.0)
            hand_valid = ok.astype(np.float64)
            if self.task.hand_target:
                hand_err = np.where(ok[:, None], rot.angle_diff(ep.hand_target, hand), 0.0)
        if reset_rows is not None and reset_rows.size:
            r = reset_rows
            pitch, roll, walking, steps, cadence = (
                x.copy() for x in (pitch, roll, walking, steps, cadence)
            )
            hand, hand_valid, hand_err = hand.copy(), hand_valid.copy(), hand_err.copy()
            for x in (pitch, roll, walking, steps, cadence, hand_valid):
                x[r] = 0.0
            hand[r] = 0.0
            hand_err[r] = ep.hand_target[r] if self.task.hand_target else 0.0
        to_goal = self._goal_points() - ep.position
        bearing = np.arctan2(to_goal[:, 1], to_goal[:, 0]) - ep.virtual_yaw
        dwell = ep.dwell / cfg.dwell_s if self.task.hand_target else np.zeros(b)
        obs = np.concatenate(
            [
                np.stack(
                    [
                        np.sin(ep.virtual_yaw),
                        np.cos(ep.virtual_yaw),
                        pitch / (np.pi / 2),
                        roll / np.pi,
                        walking,
                        np.minimum(steps / 3.0, 1.0),
                        np.minimum(cadence / 3.0, 1.0),
                    ],
                    -1,
                ),
                hand / np.pi,
                hand_valid[:, None],
                np.stack(
                    [
                        np.sin(bearing),
                        np.cos(bearing),
                        np.minimum(ep.distance / MAX_GOAL_DISTANCE, 1.0),
                    ],
                    -1,
                ),
                self.last_rays / cfg.ray_range_m,
                hand_err / np.pi,
                np.minimum(dwell, 1.0)[:, None],
            ],
            axis=-1,
        )
        return np.clip(obs, -1.0, 1.0).astype(np.float32)

    def _goal_points(self) -> NDArray[np.float64]:
        """The goal point each user heads for: the goal, or straight ahead across the end line."""
        ep = self.ep
        line = np.isfinite(ep.line_x)
        ahead = np.stack([np.where(line, ep.line_x, 0.0), ep.position[:, 1]], -1)
        return np.where(line[:, None], ahead, ep.goal)

    def infos(self, us: UserStep, blocked, success, finished) -> dict[str, NDArray]:
        """Per-user arrays: ground truth, estimation errors and task state."""
        ep = self.ep
        att_err = np.empty(self.batch_size)
        attitude_error_kernel(us.motion.quat[:, -1], us.ypr_est, att_err)
        hand_err = hand_error(us.hand_est, us.hand_true)
        # Heel-strike times in episode time, padded with +inf to a fixed width (an array of one
        # shape stacks in any vector env, and inf == inf where gymnasium's checker compares
        # infos): the motion clock and the detector's clock count from their own origins; each
        # user's offsets were stored at its reset.
        true_times = np.nan_to_num(us.motion.step_time - ep.start_time[:, None], nan=np.inf)
        detected_times = np.nan_to_num(
            us.step_peak_time - ep.detector_start[:, None], nan=np.inf
        )
        return {
            "true_ypr": np.rad2deg(us.ypr_true),
            "est_ypr": np.rad2deg(us.ypr_est),
            "attitude_error_deg": np.rad2deg(att_err),
            "heading_error_deg": np.rad2deg(rot.angle_diff(us.virtual_yaw, us.true_virtual_yaw)),
            "true_steps": us.true_steps.astype(np.int64),
            "detected_steps": us.steps.astype(np.int64),
            "true_step_times": true_times,
            "detected_step_times": detected_times,
            "true_hand_ypr": np.rad2deg(us.hand_true),
            "est_hand_ypr": np.rad2deg(us.hand_est),
            "hand_error_deg": np.rad2deg(hand_err),
            "collision": blocked.copy(),
            "collisions": ep.collisions.copy(),
            "cost": blocked.astype(np.float64),
            "distance_to_goal": ep.distance.copy(),
            "is_success": success.copy(),
            "task_done": finished.copy(),
            "position": ep.position.copy(),
            "true_position": ep.true_position.copy(),
            "virtual_yaw": ep.virtual_yaw.copy(),
            "walked": ep.walked.copy(),
            "shortest_path": ep.shortest.copy(),
            "elapsed_time": ep.elapsed * self.dt,
        }
