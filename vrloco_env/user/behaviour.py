"""What a simulated human does with their head on top of what they mean to do: gaze and nods.

:class:`GazeBehaviour` belongs to the simulated human, not to the action: each control step the env
hands it the intent the action asks for and what the user perceives (the goal's bearing and the
ray ranges in the view the headset shows, the head's yaw on the torso that proprioception gives,
whether the hand is being used), and it returns the intent with the head's part filled in:

* **Gaze** (population ``gaze``). The user looks at one thing at a time, as a direction relative
  to the torso:

  - the goal, by default (walkers look where they are going: Hollands, Patla & Vickers, Exp.
    Brain Res. 143, 2002, find the head turning toward a new travel direction before the body);
  - a *glance* at the nearest thing the rays see within ``glance_range_m`` and within
    +-``glance_cone_deg`` of the torso's direction (the travel path), started at
    ``glance_rate_hz`` (a Poisson process) and held ``glance_s`` or until nothing is near;
  - an idle *scan*: a direction drawn within +-``scan_amplitude_deg``, started at
    ``scan_rate_hz`` and held ``scan_s``;
  - the hand, while interacting (in the goal region of a task with a hand target): straight
    ahead, pitched down by ``look_down_deg`` (the intent's ``lean``).

  The eyes take the first ``eye_range_deg`` of any gaze offset and the head the rest (a hinge,
  :mod:`vrloco_env.user.population`), clipped to +-``max_head_yaw_deg``; that is the intent's
  ``head_yaw`` target, which the motion model follows with its head-movement dynamics. For the
  first ``gaze_onset_s`` of an episode the head stays straight (the time to see the scene).
* **Nods** (population ``nod_rate_hz``): bouts of ``nod_cycles`` cycles at the user's
  ``nod_frequency_hz``, peak ``nod_amplitude_deg``, started at ``nod_rate_hz``, as the intent's
  pitch gesture (whose amplitude the motion model ramps with ``MotionParams.gesture_lag_s``).

Each user's values are drawn from the population's ranges at every episode start, and every
control step draws the same four uniform numbers per user (glance onset, scan onset, scan
direction, nod onset), used or not — all from the user's own stream of the env's
:class:`~vrloco_env.batch_rng.BatchRng`, so a batch of B users reproduces B single runs bit for
bit.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers, stream_rows
from estimators.rotations import wrap_angle
from vrloco_env.batch_rng import BatchRng
from vrloco_env.user.motion import MAX_HEAD_YAW, Intent
from vrloco_env.user.population import RANGE_FIELDS, Population, get_population

__all__ = ["GLANCE", "GOAL", "HAND", "SCAN", "GazeBehaviour"]

#: What a user looks at (:attr:`GazeBehaviour.mode`).
GOAL, GLANCE, SCAN, HAND = 0, 1, 2, 3
_DONE = 1e-9  # s: a timer this close to 0 has run out (sums of dt carry rounding)


class GazeBehaviour(TakesUsers):
    """Gaze and nods of B simulated users drawn from one population (see the module docstring).

    Args:
        population: a registered name or a :class:`~vrloco_env.user.population.Population`.
        rng: one stream per user (the env's :class:`~vrloco_env.batch_rng.BatchRng`).
        dt: control period (s).
        ray_offsets: ray directions relative to the view heading (rad), (R,).

    Call :meth:`reset` for new episodes, then :meth:`intent` once per control step.
    """

    # each user's drawn behaviour and gaze state (the random streams belong to the core)
    per_user_fields = ("values", "mode", "_timer", "_scan_dir", "_nod_left", "_elapsed")
    batch_size_field = "batch_size"

    def __init__(
        self, population: str | Population, rng: BatchRng, dt: float, ray_offsets: ArrayLike
    ) -> None:
        self.population = get_population(population)
        if not isinstance(rng, BatchRng):
            raise TypeError(f"rng must be a BatchRng, got {type(rng).__name__}")
        if not (isinstance(dt, int | float) and 0.0 < dt <= 10.0):
            raise ValueError(f"GazeBehaviour dt={dt!r}: must be in (0, 10] s")
        self.rng, self.dt = rng, float(dt)
        self.ray_offsets = np.asarray(ray_offsets, dtype=np.float64)
        b = self.batch_size = rng.batch_size
        p = self.population
        self._lo = np.array([getattr(p, f)[0] for f in RANGE_FIELDS])
        self._span = np.array([getattr(p, f)[1] - getattr(p, f)[0] for f in RANGE_FIELDS])
        #: each user's drawn values, by :data:`~vrloco_env.user.population.RANGE_FIELDS` name
        self.values = {f: np.zeros(b) for f in RANGE_FIELDS}
        self.mode = np.zeros(b, np.int64)  # GOAL, GLANCE, SCAN or HAND
        self._timer = np.zeros(b)  # s left of the glance or scan
        self._scan_dir = np.zeros(b)  # gaze direction of the scan, torso frame (rad)
        self._nod_left = np.zeros(b)  # s left of the nod bout
        self._elapsed = np.zeros(b)  # s since the episode started
        self._max_head = min(np.deg2rad(p.max_head_yaw_deg), MAX_HEAD_YAW)
        self._glance_cone = np.deg2rad(p.glance_cone_deg) + 1e-12

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
        return self.values["bob_scale"][r].copy()

    def intent(
        self,
        intent: Intent,
        head_on_torso: NDArray[np.float64],
        goal_bearing: NDArray[np.float64],
        rays: NDArray[np.float64],
        interacting: NDArray[np.bool_],
    ) -> Intent:
        """The intent of this control step with the head's gaze and nods filled in.

        Args:
            intent: what the action asks for (its head fields are replaced; arrays (B, ...)).
            head_on_torso: the head's yaw on the torso now (rad), (B,).
            goal_bearing: the goal's direction relative to the view heading (rad), (B,).
            rays: ray ranges (m) in the view, (B, R), along :attr:`ray_offsets`.
            interacting: the user is using the hand (looks down at it), (B,) bool.
        """
        p, v, dt = self.population, self.values, self.dt
        b = self.batch_size
        u = self.rng.uniform((4,))  # glance onset, scan onset, scan direction, nod onset
        h = np.asarray(head_on_torso, dtype=np.float64)
        interacting = np.asarray(interacting, dtype=bool)
        on_path = np.abs(wrap_angle(self.ray_offsets[None, :] + h[:, None])) <= self._glance_cone
        ahead = np.where(on_path, rays, np.inf)
        nearest = np.argmin(ahead, axis=1)
        near = ahead[np.arange(b), nearest] < p.glance_range_m
        obstacle_dir = wrap_angle(self.ray_offsets[nearest] + h)
        goal_dir = wrap_angle(np.asarray(goal_bearing, dtype=np.float64) + h)

        # What to look at: a glance or scan runs out, or a glance loses its object.
        self._timer = np.maximum(self._timer - dt, 0.0)
        over = (self._timer <= _DONE) | ((self.mode == GLANCE) & ~near) | (self.mode == HAND)
        self.mode = np.where(over, GOAL, self.mode)
        free = (self.mode == GOAL) & ~interacting
        glance = free & near & (u[:, 0] < -np.expm1(-v["glance_rate_hz"] * dt))
        scan = free & ~glance & (u[:, 1] < -np.expm1(-v["scan_rate_hz"] * dt))
        self._timer = np.where(glance, v["glance_s"], np.where(scan, v["scan_s"], self._timer))
        self._scan_dir = np.where(
            scan, np.deg2rad(v["scan_amplitude_deg"]) * (2.0 * u[:, 2] - 1.0), self._scan_dir
        )
        self.mode = np.where(glance, GLANCE, np.where(scan, SCAN, self.mode))
        self.mode = np.where(interacting, HAND, self.mode)
        gaze = np.select(
            [self.mode == GLANCE, self.mode == SCAN, self.mode == HAND],
            [obstacle_dir, self._scan_dir, np.zeros(b)],
            goal_dir,
        )
        eye = np.deg2rad(v["eye_range_deg"])
        head = np.sign(gaze) * np.maximum(np.abs(gaze) - eye, 0.0)
        seen = self._elapsed >= v["gaze_onset_s"] - 1e-9
        self._elapsed += dt
        head = np.where(seen, np.clip(head, -self._max_head, self._max_head), 0.0)
        head = head if p.gaze else np.zeros(b)

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
        asked_lean = np.broadcast_to(np.asarray(intent.lean, dtype=np.float64), (b,))
        lean = np.where(interacting, np.deg2rad(v["look_down_deg"]), asked_lean)
        return Intent(
            cadence=intent.cadence,
            turn_rate=intent.turn_rate,
            hand_rates=intent.hand_rates,
            gesture_amplitude=amplitude,
            gesture_frequency=frequency,
            lean=lean,
            head_yaw=head,
        )

    @property
    def nodding(self) -> NDArray[np.bool_]:
        """Users in a nod bout (as of the last :meth:`intent`)."""
        return self._nod_left > _DONE
