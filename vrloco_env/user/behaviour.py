"""What a simulated human does on top of what they mean to do: gaze, nods and drift.

:class:`GazeBehaviour` belongs to the simulated human, not to the action: each control step the env
hands it the intent the action asks for and what the user perceives (the goal's bearing and the
ray ranges in the view the headset shows, the head's yaw on the torso that proprioception gives,
whether the hand is being used), and it returns the intent with the human's part filled in
(every number below is a :class:`~vrloco_env.user.population.Population` field, whose doc gives
its source, fit, bound or choice):

* **Gaze** (population ``gaze``). The user looks at one thing at a time, as a direction relative
  to the torso:

  - the goal, by default (walkers look where they are going: Hollands, Patla & Vickers, Exp.
    Brain Res. 143, 2002, find the head turning toward a new travel direction before the body);
  - while stepping, a *glance* at the nearest thing the rays see within ``glance_range_m`` and
    within +-``glance_cone_deg`` of the torso's direction (the travel path), started at
    ``glance_rate_hz`` (a Poisson process) and held ``glance_s``, until nothing is near or the
    user stops stepping;
  - a *look around*: bouts started at ``scan_rate_hz``; each look shifts the gaze from where it
    is (the goal, or the bout's last look) by an exponential size of mean
    ``scan_amplitude_deg``, left or right alike, and is held an exponential time of mean
    ``scan_s``; standing, a look is followed by another with chance ``1 - 1 / scan_looks``,
    else the gaze returns to the goal; stepping, a bout is one look;
  - the hand, while interacting (in the goal region of a task with a hand target): straight
    ahead, pitched down by ``look_down_deg`` (the intent's ``lean``).

  The eyes take the first ``eye_range_deg`` of any gaze offset and the head the rest (a hinge,
  :mod:`vrloco_env.user.population`), clipped to +-``max_head_yaw_deg``; stepping, a glance or
  look keeps the head within +-``walking_head_deg`` of where the goal holds it (head rotations
  during locomotion stay within 38 deg: Pozzo et al. 1990). That is the head's target
  (:attr:`GazeBehaviour.head_target`); the intent's ``head_yaw`` moves toward it with the user's
  peak angular acceleration ``head_accel_deg_s2`` (speeding up, then braking to stop on it), and
  the motion model follows that with its head-movement dynamics
  (``MotionParams.head_turn_lag_s``). For the first ``gaze_onset_s`` of an episode the head
  stays straight (the time to see the scene).
* **Nods** (population ``nod_rate_hz``): bouts of ``nod_cycles`` cycles at the user's
  ``nod_frequency_hz``, peak ``nod_amplitude_deg``, started at ``nod_rate_hz``, as the intent's
  pitch gesture (whose amplitude the motion model ramps with ``MotionParams.gesture_lag_s``).
* **Stride oscillation** (population ``stride_yaw_deg``): while stepping, the head yaws by
  +-``stride_yaw_deg`` once per stride (half the cadence), as the intent's yaw gesture.
* **Turning drift** (population ``wip_turn_deg_per_step``, users stepping in place): the body
  turns by the user's drawn degrees per step on top of the intent's turn rate
  (:func:`vrloco_env.user.play_area.turning_drift`; the module says how it reaches the true
  motion and why the action keeps its meaning).

Each user's values are drawn from the population's ranges at every episode start, and every
control step draws the same four uniform numbers per user (glance onset, a look's onset or end,
a look's size and side, nod onset), used or not — all from the user's own stream of the env's
:class:`~vrloco_env.batch_rng.BatchRng`, so a batch of B users reproduces B single runs bit for
bit.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers, stream_rows
from estimators.rotations import wrap_angle
from vrloco_env.batch_rng import BatchRng
from vrloco_env.user.intent import MAX_HEAD_YAW, Intent
from vrloco_env.user.motion_params import MotionParams
from vrloco_env.user.play_area import turning_drift
from vrloco_env.user.population import RANGE_FIELDS, Population, get_population

__all__ = ["GLANCE", "GOAL", "HAND", "SCAN", "GazeBehaviour"]

#: What a user looks at (:attr:`GazeBehaviour.mode`).
GOAL, GLANCE, SCAN, HAND = 0, 1, 2, 3
_DONE = 1e-9  # s: a timer this close to 0 has run out (sums of dt carry rounding)


def _hinge(
    gaze: NDArray[np.float64], eye: NDArray[np.float64], limit: float
) -> NDArray[np.float64]:
    """The head's part of a gaze direction on the torso (rad): the eyes take the first ``eye``,
    the head the rest, within +-``limit``."""
    head = np.sign(gaze) * np.maximum(np.abs(gaze) - eye, 0.0)
    return np.clip(head, -limit, limit)


class GazeBehaviour(TakesUsers):
    """Gaze, nods and drift of B simulated users drawn from one population (see the module
    docstring).

    Args:
        population: a registered name or a :class:`~vrloco_env.user.population.Population`.
        rng: one stream per user (the env's :class:`~vrloco_env.batch_rng.BatchRng`).
        dt: control period (s).
        ray_offsets: ray directions relative to the view heading (rad), (R,).
        max_turn_rate: the body's largest yaw rate (rad/s,
            :attr:`~vrloco_env.user.motion.MotionParams.max_turn_rate`): the turning drift
            never takes the intent's turn rate beyond it.
        walk_in_place: the user steps in place (the turning drift applies); False for a user
            who really walks (``EnvConfig.pose_source="visual_inertial"``), who sees the room.

    Call :meth:`reset` for new episodes, then :meth:`intent` once per control step.
    """

    # each user's drawn behaviour and gaze state (the random streams belong to the core)
    per_user_fields = (
        "values",
        "mode",
        "_timer",
        "_scan_dir",
        "_nod_left",
        "_elapsed",
        "_stride_hz",
        "head_target",
        "_cmd",
        "_cmd_rate",
    )
    batch_size_field = "batch_size"

    def __init__(
        self,
        population: str | Population,
        rng: BatchRng,
        dt: float,
        ray_offsets: ArrayLike,
        max_turn_rate: float = MotionParams.max_turn_rate,
        walk_in_place: bool = True,
    ) -> None:
        self.population = get_population(population)
        if not isinstance(rng, BatchRng):
            raise TypeError(f"rng must be a BatchRng, got {type(rng).__name__}")
        if not (isinstance(dt, int | float) and 0.0 < dt <= 10.0):
            raise ValueError(f"GazeBehaviour dt={dt!r}: must be in (0, 10] s")
        if not (isinstance(max_turn_rate, int | float) and 0.0 < max_turn_rate <= 2 * np.pi):
            raise ValueError(
                f"GazeBehaviour max_turn_rate={max_turn_rate!r}: must be in (0, 2 pi] rad/s"
            )
        self.rng, self.dt = rng, float(dt)
        self.max_turn_rate, self.walk_in_place = float(max_turn_rate), bool(walk_in_place)
        self.ray_offsets = np.asarray(ray_offsets, dtype=np.float64)
        b = self.batch_size = rng.batch_size
        p = self.population
        self._lo = np.array([getattr(p, f)[0] for f in RANGE_FIELDS])
        self._span = np.array([getattr(p, f)[1] - getattr(p, f)[0] for f in RANGE_FIELDS])
        #: each user's drawn values, by :data:`~vrloco_env.user.population.RANGE_FIELDS` name
        self.values = {f: np.zeros(b) for f in RANGE_FIELDS}
        self.mode = np.zeros(b, np.int64)  # GOAL, GLANCE, SCAN or HAND
        self._timer = np.zeros(b)  # s left of the glance
        self._scan_dir = np.zeros(b)  # gaze direction of the look, torso frame (rad)
        self._nod_left = np.zeros(b)  # s left of the nod bout
        self._elapsed = np.zeros(b)  # s since the episode started
        self._stride_hz = np.full(b, 0.5)  # the stride oscillation's frequency (Hz), held
        #: the head-on-torso yaw (rad) the gaze asked for at the last :meth:`intent`, (B,);
        #: the intent's ``head_yaw`` moves toward it (:meth:`_turn_head`)
        self.head_target = np.zeros(b)
        self._cmd = np.zeros(b)  # the head-on-torso yaw commanded (rad)
        self._cmd_rate = np.zeros(b)  # and its rate (rad/s)
        self._max_head = min(np.deg2rad(p.max_head_yaw_deg), MAX_HEAD_YAW)
        self._glance_cone = np.deg2rad(p.glance_cone_deg) + 1e-12
        self._walk_head = np.deg2rad(p.walking_head_deg)

    def reset(self, rows: ArrayLike | None = None) -> NDArray[np.float64]:
        """Start new episodes for ``rows`` (None: all): draw their values, look at the goal.

        Returns:
            The reset users' ``bob_scale`` (for :meth:`vrloco_env.user.UserMotion.scale_style`).
        """
        r = stream_rows(rows, self.batch_size)
        u = self.rng.uniform((len(RANGE_FIELDS),), rows=r)
        drawn = self._lo + u * self._span
        for k, f in enumerate(RANGE_FIELDS):
            self.values[f][r] = drawn[:, k]
        self.mode[r] = GOAL
        self._timer[r] = 0.0
        self._scan_dir[r] = 0.0
        self._nod_left[r] = 0.0
        self._elapsed[r] = 0.0
        self._stride_hz[r] = 0.5
        self.head_target[r] = 0.0
        self._cmd[r] = 0.0
        self._cmd_rate[r] = 0.0
        return self.values["bob_scale"][r].copy()

    def intent(
        self,
        intent: Intent,
        head_on_torso: NDArray[np.float64],
        goal_bearing: NDArray[np.float64],
        rays: NDArray[np.float64],
        interacting: NDArray[np.bool_],
    ) -> Intent:
        """The intent of this control step with the human's part filled in: the head's gaze,
        nods and stride oscillation, and the body's turning drift while stepping in place.

        Args:
            intent: what the action asks for (its head fields are replaced, its turn rate gets
                the drift; arrays (B, ...)).
            head_on_torso: the head's yaw on the torso now (rad), (B,).
            goal_bearing: the goal's direction relative to the view heading (rad), (B,).
            rays: ray ranges (m) in the view, (B, R), along :attr:`ray_offsets`.
            interacting: the user is using the hand (looks down at it), (B,) bool.
        """
        p, v, dt = self.population, self.values, self.dt
        b = self.batch_size
        u = self.rng.uniform((4,))  # glance onset, look onset or end, look size, nod onset
        h = np.asarray(head_on_torso, dtype=np.float64)
        interacting = np.asarray(interacting, dtype=bool)
        cadence = np.broadcast_to(np.asarray(intent.cadence, dtype=np.float64), (b,))
        stepping = cadence > 0.0
        on_path = np.abs(wrap_angle(self.ray_offsets[None, :] + h[:, None])) <= self._glance_cone
        ahead = np.where(on_path, rays, np.inf)
        nearest = np.argmin(ahead, axis=1)
        near = ahead[np.arange(b), nearest] < p.glance_range_m
        obstacle_dir = wrap_angle(self.ray_offsets[nearest] + h)
        goal_dir = wrap_angle(np.asarray(goal_bearing, dtype=np.float64) + h)

        # What to look at. A glance runs out or loses its object; a look ends at its hazard
        # (exponential holds) and, standing, goes on to another look of the same bout.
        self._timer = np.maximum(self._timer - dt, 0.0)
        end = -np.expm1(-dt / v["scan_s"])  # chance a look ends this step
        ends = (self.mode == SCAN) & (u[:, 1] < end)
        again = ends & ~stepping & ~interacting & (u[:, 1] < end * (1.0 - 1.0 / v["scan_looks"]))
        over = (
            ((self.mode == GLANCE) & ((self._timer <= _DONE) | ~near | ~stepping))
            | (ends & ~again)
            | (self.mode == HAND)
        )
        self.mode = np.where(over, GOAL, self.mode)
        free = (self.mode == GOAL) & ~interacting & ~ends
        glance = free & near & stepping & (u[:, 0] < -np.expm1(-v["glance_rate_hz"] * dt))
        scan = free & ~glance & (u[:, 1] < -np.expm1(-v["scan_rate_hz"] * dt))
        self._timer = np.where(glance, v["glance_s"], self._timer)
        # A new look shifts the gaze from where it is (the goal, or the bout's last look) by an
        # exponential size of mean scan_amplitude_deg, left or right with equal chance.
        side = 2.0 * u[:, 2] - 1.0
        size = -np.log1p(-np.minimum(np.abs(side), 1.0 - 1e-12))  # Exp(1)
        eye = np.deg2rad(v["eye_range_deg"])
        reach = self._max_head + eye  # a gaze farther out leaves the head at its limit
        look = np.where(again, self._scan_dir, goal_dir)
        look = look + np.where(side < 0.0, -1.0, 1.0) * np.deg2rad(v["scan_amplitude_deg"]) * size
        self._scan_dir = np.where(scan | again, np.clip(look, -reach, reach), self._scan_dir)
        self.mode = np.where(glance, GLANCE, np.where(scan, SCAN, self.mode))
        self.mode = np.where(interacting, HAND, self.mode)
        gaze = np.select(
            [self.mode == GLANCE, self.mode == SCAN, self.mode == HAND],
            [obstacle_dir, self._scan_dir, np.zeros(b)],
            goal_dir,
        )
        head = _hinge(gaze, eye, self._max_head)
        # Walking, a look or glance turns the head at most walking_head_deg from the goal's.
        at_goal = _hinge(goal_dir, eye, self._max_head)
        away = stepping & ((self.mode == GLANCE) | (self.mode == SCAN))
        head = np.where(
            away, np.clip(head, at_goal - self._walk_head, at_goal + self._walk_head), head
        )
        seen = self._elapsed >= v["gaze_onset_s"] - 1e-9
        self._elapsed += dt
        self.head_target = np.where(seen, head, 0.0) if p.gaze else np.zeros(b)
        head = (
            self._turn_head(self.head_target, np.deg2rad(v["head_accel_deg_s2"]))
            if p.gaze
            else np.zeros(b)
        )

        # Nod bouts.
        self._nod_left = np.maximum(self._nod_left - dt, 0.0)
        start = (self._nod_left <= _DONE) & (u[:, 3] < -np.expm1(-v["nod_rate_hz"] * dt))
        freq = np.maximum(v["nod_frequency_hz"], 0.2)
        self._nod_left = np.where(start, v["nod_cycles"] / freq, self._nod_left)
        amplitude = np.array(intent.gesture_amplitude, dtype=np.float64, copy=True)
        amplitude = np.broadcast_to(amplitude, (b, 3)).copy()
        frequency = np.broadcast_to(
            np.asarray(intent.gesture_frequency, dtype=np.float64), (b, 3)
        ).copy()
        nodding = self._nod_left > _DONE
        amplitude[:, 1] = np.where(nodding, np.deg2rad(v["nod_amplitude_deg"]), amplitude[:, 1])
        if p.nod_rate_hz[1] > 0.0:  # the user's own nodding rhythm, held so the phase is smooth
            frequency[:, 1] = freq
        # The head's yaw oscillation once per stride while stepping; its frequency is held after
        # the last step so that the phase stays smooth while the amplitude fades.
        if p.stride_yaw_deg[1] > 0.0:
            self._stride_hz = np.where(stepping, 0.5 * cadence, self._stride_hz)
            amplitude[:, 0] = np.where(stepping, np.deg2rad(v["stride_yaw_deg"]), amplitude[:, 0])
            frequency[:, 0] = self._stride_hz
        asked_lean = np.broadcast_to(np.asarray(intent.lean, dtype=np.float64), (b,))
        lean = np.where(interacting, np.deg2rad(v["look_down_deg"]), asked_lean)
        turn_rate = intent.turn_rate
        if self.walk_in_place and p.wip_turn_deg_per_step != (0.0, 0.0):
            drift = turning_drift(v["wip_turn_deg_per_step"], cadence)  # 0 standing
            turn_rate = np.clip(
                np.asarray(turn_rate, dtype=np.float64) + drift,
                -self.max_turn_rate,
                self.max_turn_rate,
            )
        return Intent(
            cadence=intent.cadence,
            turn_rate=turn_rate,
            hand_rates=intent.hand_rates,
            gesture_amplitude=amplitude,
            gesture_frequency=frequency,
            lean=lean,
            head_yaw=head,
        )

    def _turn_head(
        self, target: NDArray[np.float64], accel: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """The head-on-torso yaw commanded this step (rad), moved toward ``target`` with peak
        angular acceleration ``accel`` (rad/s^2): its rate changes by at most ``accel * dt`` per
        step, no faster than it can still stop on the target, so that a turn of amplitude A
        peaks at about sqrt(accel * A) and lasts about 2 sqrt(A / accel) (a time-optimal
        profile; a target that moves on mid-turn is followed from where the head is)."""
        dt, x, rate = self.dt, self._cmd, self._cmd_rate
        err = target - x
        # the fastest rate from which steps of falling rate (by accel * dt) stop within err
        brake = (
            np.sign(err) * accel * (np.sqrt(0.25 * dt * dt + 2.0 * np.abs(err) / accel) - 0.5 * dt)
        )
        rate = rate + np.clip(brake - rate, -accel * dt, accel * dt)
        step = rate * dt
        arrive = (np.abs(step) >= np.abs(err)) & (step * err >= 0.0)
        x = np.where(arrive, target, x + step)
        limited = np.abs(x) >= self._max_head
        self._cmd = np.clip(x, -self._max_head, self._max_head)
        self._cmd_rate = np.where(arrive | limited, 0.0, rate)
        return self._cmd.copy()

    @property
    def nodding(self) -> NDArray[np.bool_]:
        """Users in a nod bout (as of the last :meth:`intent`)."""
        return self._nod_left > _DONE
