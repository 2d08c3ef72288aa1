"""The environment's engine: B users in B rooms, stepped in one batched call.

Both the single :class:`~vrloco_env.env.VRLocoEnv` (B = 1) and the native
:class:`~vrloco_env.vector.VRLocoVectorEnv` (B = num_envs) are thin Gymnasium shells around
:class:`LocoCore`. Per control step::

    actions -> intents -> SimulatedUsers (motion, IMU, Kinect, estimators, locomotion)
            -> the virtual body moves by the locomotion displacement unless the swept avatar
               would touch a wall or obstacle (then it stays: a collision)
            -> rays from the virtual head, goal bearing and distance -> observation, reward

The world. Each user's room is a :class:`~vrloco_env.world.layout.Layout`; the per-step queries
(swept avatar against the room, rays from the virtual head) run on the rooms' exact 2-D geometry
(:class:`~vrloco_env.world.room_batch.RoomBatch`, one compiled call for all users), which the tests
check against PyBullet's own rays and contacts. PyBullet (:class:`~vrloco_env.world.sim.Simulation`)
holds the same rooms as bodies for rendering — the first-person view and the ``human`` GUI — and is
only created when a render mode asks for it: at 256 users its ray cast alone would take ~14 ms per
step on this machine, 30 times the 2-D twin.

The human. With a user population (:attr:`EnvConfig.population
<vrloco_env.config.EnvConfig.population>`) a :class:`~vrloco_env.user.GazeBehaviour` adds the
head's own behaviour to each intent — gaze at the goal, glances at what is near, scans, looking
down at the hand while interacting (in the goal region of a task that observes a hand target),
nods — from what the user perceived at the end of the last step: the goal's bearing and the rays
in the view the headset showed, and the head's true yaw on the torso (proprioception), which the
observation then carries as ``head_on_torso``. A population with a drift range
(``Population.wip_drift_mps``) draws each user's drift rate with the behaviour's values and a
lateral fraction next; walking in place, the user's standing spot then drifts while stepping
(:mod:`vrloco_env.user.play_area`), and ``info`` reports it in the play area
(``play_area_position_m``, ``play_area_boundary_m``, ``play_area_outside``).

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
from estimators.batching import TakesUsers, stream_rows, takes_users
from vrloco_env._core_numba import attitude_error_kernel, observation_kernel, observation_offsets
from vrloco_env._hand_frame_numba import hand_error
from vrloco_env.actions import action_to_intent, check_actions
from vrloco_env.batch_rng import BatchRng
from vrloco_env.config import EnvConfig, EstimatorConfig, RewardConfig, SensorConfig
from vrloco_env.observation import (
    MAX_GOAL_DISTANCE,
    ObservationSpec,
    env_spec,
    population_fields,
    ray_offsets,
)
from vrloco_env.pipeline import build_stages
from vrloco_env.tasks import get_task
from vrloco_env.tasks.base import Task
from vrloco_env.user import GazeBehaviour, Intent, get_population
from vrloco_env.user.gestures import gesture_performer
from vrloco_env.users import SimulatedUsers, UserStep
from vrloco_env.world import Layout, RoomBatch, RoomConfig

__all__ = ["MAX_GOAL_DISTANCE", "LocoCore"]

_SWEEP_SAMPLES = 8  # points along a step's displacement checked against the room
_SWEEP_FRACTIONS = (np.arange(1, _SWEEP_SAMPLES + 1) / _SWEEP_SAMPLES)[None, :, None]


#: A turn action above this (a fraction of the largest turn rate) counts as meaning to turn.
TURNING = 0.02


#: Height of the eyes above the neck joint (m): about 0.1 m in adult anthropometry. A choice
#: within that range; it places the view the rays stand for.
EYE_ABOVE_NECK_M = 0.1


@dataclass
class _Episode:
    """Per-user episode state, arrays over the B users."""

    position: NDArray[np.float64]  # (B, 2) virtual body, room frame (m)
    true_position: NDArray[np.float64]  # (B, 2) where perfect sensing would have walked
    collisions: NDArray[np.int64]
    elapsed: NDArray[np.int64]  # control steps since reset
    walked: NDArray[np.float64]  # path length of the virtual body (m)
    distance: NDArray[np.float64]  # to the goal region (m)
    shortest: NDArray[np.float64]  # shortest path length (m), for SPL
    virtual_yaw: NDArray[np.float64]
    moved: NDArray[np.float64]  # (B, 2) displacement of the last control step (m), room frame
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
            shortest=z.copy(),
            virtual_yaw=z.copy(),
            moved=np.zeros((b, 2)),
            done=np.zeros(b, bool),
        )


class LocoCore(TakesUsers):
    """B users, each in its own room, with their sensors, estimators and task.

    Args:
        task: a registered task's name (:mod:`vrloco_env.tasks`).
        num_users: B.
        config, sensors, estimators, room, reward: the configuration dataclasses.
        task_config: the task's own configuration (its ``Config``; defaults if None).
    """

    per_user_fields = (
        "generators",
        "layouts",
        "ep",
        "last",
        "last_rays",
        "_head_on_torso",
        "_moving",
        "_head_pitch",
        "_zeros",
        "_standing",
    )
    # the random streams, the users (motion, sensors, stages), the task, the head behaviour, the
    # technique's gesture and the rooms
    per_user_parts = ("rng", "users", "task", "behaviour", "gestures", "rooms")
    batch_size_field = "batch_size"

    def __init__(
        self,
        task: str,
        num_users: int,
        config: EnvConfig,
        sensors: SensorConfig,
        estimators: EstimatorConfig,
        room: RoomConfig,
        reward: RewardConfig,
        task_config: object = None,
    ) -> None:
        if not isinstance(num_users, int | np.integer) or num_users < 1:
            raise ValueError(f"num_users must be an integer >= 1, got {num_users!r}")
        task_class = get_task(task)
        self.batch_size = b = int(num_users)
        self.config, self.sensors, self.estimators = config, sensors, estimators
        self.room, self.reward = room, reward
        self.generators = [np.random.default_rng() for _ in range(b)]
        self.rng = BatchRng([np.random.default_rng(0) for _ in range(b)])
        self.stages = build_stages(estimators, sensors, b, config.pose_source, self.rng)
        self.users = SimulatedUsers(
            b,
            self.rng,
            config.motion,
            sensors,
            self.stages,
            play_area=config.play_area,
        )
        self.dt = self.users.dt
        self.task: Task = task_class(b, self.dt, task_config)
        #: the user population (None: the idealised user) and its head behaviour
        self.population = None if config.population is None else get_population(config.population)
        self.behaviour: GazeBehaviour | None = None
        self.layouts: list[Layout | None] = [None] * b
        self.rooms: RoomBatch | None = None
        self.ep = _Episode.empty(b)
        self.ray_offsets = ray_offsets(config.ray_count, config.ray_fov_deg)
        #: the population's users drift in the play area while stepping in place
        self._drifts = (
            self.population is not None
            and self.population.wip_drift_mps[1] > 0.0
            and config.pose_source == "walk_in_place"
        )
        if self.population is not None and (self.population.moves_head or self._drifts):
            self.behaviour = GazeBehaviour(
                self.population,
                self.rng,
                self.dt,
                self.ray_offsets,
                max_turn_rate=self.users.motion_params.max_turn_rate,
                walk_in_place=config.pose_source == "walk_in_place",
            )
        self._head_on_torso = np.zeros(b)  # the head's true yaw on the torso (rad)
        #: the technique's gesture, performed by the users (None: they step in place)
        self.gestures = gesture_performer(self.stages, b, self.dt, self.users.motion_params)
        # the locomotion moved, or pushed against what blocked it, the body in the last step:
        # what a look-down user judges its auto-walk by
        self._moving = np.zeros(b, bool)
        self._head_pitch = np.zeros(b)  # the head's true pitch at the last step's end (rad)
        # what the user sees follows the head: the view's vertical half-angle and eye height
        self._half_fov = np.deg2rad(config.view_vertical_fov_deg) / 2.0
        self._eye_height = config.motion.neck_height_m + EYE_ABOVE_NECK_M
        self._hand_task = any(f.name == "hand_error" for f in self.task.fields())
        extra = population_fields(self.population)
        #: the observation's fields, scales and units (:mod:`vrloco_env.observation`)
        self.spec: ObservationSpec = env_spec(
            config.ray_count, config.ray_range_m, (*self.task.fields(), *extra)
        )
        self._observe_head = bool(extra)
        self.obs_size = self.spec.size
        self._obs_at = observation_offsets(self.spec)
        self._task_fields = [f.name for f in self.task.fields()]
        self.last: UserStep | None = None
        self._zeros = np.zeros(b)
        # What observe() reads before a user's first step: nothing estimated yet.
        self._standing = SimpleNamespace(
            ypr_est=np.zeros((b, 3)),
            walking=np.zeros(b, bool),
            steps=self._zeros,
            cadence=self._zeros,
            hand_est=np.full((b, 3), np.nan),
        )
        self.last_rays = np.full((b, config.ray_count), config.ray_range_m)
        #: the longest delay (s) from a heel strike to its step being reported (the step
        #: stage's ``report_delay_s``; its ``latency``, or 0, for a stage that gives none)
        steps = self.stages.steps
        self.step_report_delay_s = float(
            getattr(steps, "report_delay_s", getattr(steps, "latency", 0.0))
        )

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
            layout = self.task.draw(int(i), self.room, g)
            self.rng.reseed(i, np.random.default_rng(int(g.integers(2**63))))
            self.layouts[i] = layout
            self.users.set_room(int(i), layout)
            if self.rooms is not None:
                self.rooms.set(i, layout)
            start[k] = layout.start
            self.ep.shortest[i] = layout.shortest_path_length
        if self.rooms is None:
            self.rooms = RoomBatch(self.layouts)  # type: ignore[arg-type]
        self.users.reset(
            None if rows.size == b else rows, start_yaw=start[:, 2], start_xy=start[:, :2]
        )
        if self.behaviour is not None:
            self.users.motion.scale_style(rows, self.behaviour.reset(rows))
        if self._drifts:  # the drift rate was drawn with the behaviour; its lateral part next
            assert self.behaviour is not None
            forward = self.behaviour.values["wip_drift_mps"][rows]
            side = 2.0 * self.rng.uniform((), rows=rows) - 1.0
            self.users.set_drift(
                rows, forward, side * self.config.play_area.lateral_ratio * forward
            )
        self._head_on_torso[rows] = 0.0
        self._moving[rows] = False
        self._head_pitch[rows] = 0.0
        if self.gestures is not None:
            self.gestures.reset(rows)
        ep = self.ep
        ep.position[rows] = start[:, :2]
        ep.true_position[rows] = start[:, :2]
        ep.virtual_yaw[rows] = start[:, 2]
        ep.moved[rows] = 0.0
        ep.collisions[rows] = 0
        ep.elapsed[rows] = 0
        ep.walked[rows] = 0.0
        ep.done[rows] = False
        self.task.reset(rows)
        ep.distance[rows] = self.task.goal_distance(ep.position)[rows]
        self.last_rays[rows] = self._rays(rows, level=True)
        return self.observe(reset_rows=rows)

    # ------------------------------------------------------------------------------ users
    @property
    def can_take_users(self) -> bool:
        """Whether :meth:`take_users` works: every part holding per-user state (a plug-in stage,
        a task, the tracker) can drop users."""
        return takes_users(self)

    def take_users(self, rows: ArrayLike) -> None:
        """Keep the users ``rows`` (distinct indices, in their new order) and drop the others:
        the batch becomes ``len(rows)`` users, each going on exactly as it would have in the
        whole batch (a runner whose remaining users are few steps only those).

        Raises:
            RuntimeError: before the first :meth:`reset`.
            ValueError: bad or repeated indices, or none.
            TypeError: a part that cannot drop users (a plug-in stage, the task or the tracker;
                see :attr:`can_take_users`); nothing is changed.
        """
        if self.rooms is None:
            raise RuntimeError("reset() must be called before take_users()")
        r = stream_rows(rows, self.batch_size, "rows")
        if r.size == 0:
            raise ValueError("take_users: rows must keep at least one user")
        super().take_users(r)

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
        intent = action_to_intent(a, self.users.motion_params)
        if self.behaviour is not None:
            intent = self._human(intent)
        if self.gestures is not None:
            intent = self.gestures.intent(intent, self._moving, self._head_pitch)
        us = self.users.step(intent, validated=True)
        self.last = us
        self._head_on_torso = us.motion.ypr[:, -1, 0] - us.motion.body_yaw[:, -1]
        self._head_pitch = us.ypr_true[:, 1]
        ep, cfg, rw = self.ep, self.config, self.reward

        # Move the virtual body unless the swept avatar would touch the room.
        move = us.displacement
        path = ep.position[:, None, :] + _SWEEP_FRACTIONS * move[:, None, :]
        clearance = self.rooms.signed_distance(path).min(axis=1)
        moving = np.hypot(move[:, 0], move[:, 1]) > 1e-12
        self._moving = moving
        blocked = moving & (clearance <= self.room.avatar_radius)
        ep.moved = np.where(blocked[:, None], 0.0, move)
        ep.position = ep.position + ep.moved
        ep.walked += np.where(blocked, 0.0, np.hypot(move[:, 0], move[:, 1]))
        ep.collisions += blocked
        ep.virtual_yaw = us.virtual_yaw
        ep.true_position += us.true_displacement
        ep.elapsed += 1

        # Task progress.
        prev = ep.distance
        ep.distance = self.task.goal_distance(ep.position)
        finished = self.task.finished(ep.distance <= 0.0, us)
        success = finished & ((ep.collisions == 0) | (not self.task.collision_free_success))
        terminated = finished | (blocked & cfg.terminate_on_collision)
        if cfg.max_episode_steps is None:  # a wrapper (gymnasium's TimeLimit) ends it
            truncated = np.zeros_like(terminated)
        else:
            truncated = (ep.elapsed >= cfg.max_episode_steps) & ~terminated
        ep.done = terminated | truncated
        paid = success & ((ep.collisions == 0) | (not rw.success_without_collision))
        reward = (
            rw.progress * (prev - ep.distance)
            + rw.success * paid
            - rw.collision * blocked
            - rw.effort * (a * a).sum(axis=1) / a.shape[1]
            - rw.time
        )
        if rw.hand_progress > 0.0:
            closer = self.task.hand_progress()
            if closer is not None:
                reward = reward + rw.hand_progress * closer
        self.last_rays = self._rays()
        infos = self.infos(us, blocked, success, finished)
        infos["intent_walk"] = a[:, 0] > 0.0  # the user means to step (the action's walk > 0)
        infos["intent_turn"] = np.abs(a[:, 1]) > TURNING  # ... or to turn
        return self.observe(), reward, terminated, truncated, infos

    def _human(self, intent: Intent) -> Intent:
        """The intent with the population's head behaviour, from what each user perceived at
        the end of the last step (see the module docstring)."""
        assert self.behaviour is not None
        ep = self.ep
        to_goal = self.task.goal_point(ep.position) - ep.position
        bearing = np.arctan2(to_goal[:, 1], to_goal[:, 0]) - ep.virtual_yaw
        interacting = (ep.distance <= 0.0) & self._hand_task
        return self.behaviour.intent(
            intent, self._head_on_torso, bearing, self.last_rays, interacting
        )

    # ------------------------------------------------------------------------------ views
    def _rays(
        self, rows: NDArray[np.intp] | None = None, level: bool = False
    ) -> NDArray[np.float64]:
        """Ranges (m) along the rays from the virtual head of users ``rows`` (None: all);
        ``level``: the users ``rows`` have just been reset, their heads level.

        The view follows the head the headset renders from (the estimated pitch): pitched down
        past the view's vertical half-angle, the user sees the floor only up to where the view's
        upper edge meets it, ``eye_height / tan(pitch - half_fov)``; an obstacle farther away is
        out of view and its ray reads the full range (nothing seen)."""
        assert self.rooms is not None
        rng = self.config.ray_range_m
        r = self.rooms.ray_fan(self.ep.position, self.ep.virtual_yaw, self.ray_offsets, rng)
        r = np.minimum(r, rng)
        if self.last is not None and not level:
            below = self.last.ypr_est[:, 1] - self._half_fov  # the upper edge's angle down
            if (below > 0.0).any():
                seen = self._eye_height / np.tan(np.clip(below, 1e-6, np.pi / 2 - 1e-6))
                r = np.where((below > 0.0)[:, None] & (r > seen[:, None]), rng, r)
        return r if rows is None else r[rows]

    def observe(self, reset_rows: NDArray[np.intp] | None = None) -> NDArray[np.float32]:
        """The observations of all users (fields: :attr:`spec`).

        Users in ``reset_rows`` have just been reset: they stand still, their estimated attitude
        is the start heading and no hand estimate exists yet. The common fields are one compiled
        call (:func:`~vrloco_env._core_numba.observation_kernel`), the task's own fields its
        :meth:`~vrloco_env.tasks.base.Task.observe`.
        """
        b, ep, last = self.batch_size, self.ep, self.last
        fresh = np.zeros(b, bool) if last is not None else np.ones(b, bool)
        if reset_rows is not None:
            fresh[reset_rows] = True
        src = last if last is not None else self._standing
        out = np.empty((b, self.obs_size), np.float32)
        observation_kernel(b)(
            (src.ypr_est, src.walking, src.steps, src.cadence, src.hand_est),
            ep.virtual_yaw,
            self.task.goal_point(ep.position),
            ep.position,
            ep.moved,
            ep.distance,
            self.last_rays,
            fresh,
            self._obs_at,
            self.spec.scales,
            out,
        )
        if self._task_fields:
            values = self.task.observe(last, fresh)
            for name in self._task_fields:
                self.spec.encode(name, values[name], out)
        if self._observe_head:
            self.spec.encode("head_on_torso", self._head_on_torso[:, None], out)
        return out

    def infos(self, us: UserStep, blocked, success, finished) -> dict[str, NDArray]:
        """Per-user arrays: ground truth, estimation errors and task state."""
        ep = self.ep
        att_err = np.empty(self.batch_size)
        attitude_error_kernel(self.batch_size)(us.motion.quat[:, -1], us.ypr_est, att_err)
        hand_err = hand_error(us.hand_est, us.hand_true)
        # Heel-strike times in episode time, padded with +inf to a fixed width (an array of one
        # shape stacks in any vector env, and inf == inf where gymnasium's checker compares
        # infos). Both come from each user's own clock, so a user reset mid-run reports what a
        # new env would: the motion's offsets within this control step after the episode's
        # completed steps, and the detector's times since its reset, whose sample 0 is the
        # first IMU sample of the episode, one sample period after its start.
        started = (ep.elapsed - 1)[:, None] / self.users.motion_params.control_rate_hz
        true_times = started + us.motion.step_offset
        detected_times = us.step_peak_time + 1.0 / self.users.imu_rate_hz
        for times in (true_times, detected_times):
            np.copyto(times, np.inf, where=np.isnan(times))
        area_xy = self.users.play_area_position()
        area_margin = self.config.play_area.boundary_distance(area_xy)
        return {
            "true_ypr": np.rad2deg(us.ypr_true),
            "est_ypr": np.rad2deg(us.ypr_est),
            "attitude_error_deg": np.rad2deg(att_err),
            "heading_error_deg": np.rad2deg(rot.angle_diff(us.virtual_yaw, us.true_virtual_yaw)),
            "walk_yaw_deg": np.rad2deg(rot.wrap_angle(us.walk_yaw)),
            "true_body_yaw_deg": np.rad2deg(rot.wrap_angle(us.true_body_yaw)),
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
            "play_area_position_m": area_xy,
            "play_area_boundary_m": area_margin,
            "play_area_outside": area_margin < 0.0,
            **self.task.info(),
        }
