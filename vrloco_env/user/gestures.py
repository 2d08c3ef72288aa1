"""The body gesture a technique asks of its users, performed by the simulated users: from their
intent (walk, turn, hand) to the intent of the motion model.

A technique's locomotion or steering stage declares its gesture
(:mod:`estimators.locomotion.gestures`); :func:`gesture_performer` builds the performer the env
applies to every intent, after the population's head behaviour (so that a user who glances down
at the floor still glances, on top of the gesture). The action keeps its meaning: ``walk`` is how
fast the user wants to go, ``turn`` turns the body, the hand rates move the hand.

* Step in place (walking-in-place techniques) and point to steer (hand-directed steering): the
  intent as it is. Pointing is the hand's yaw on the torso, which the hand rates already move.
* :class:`TiltPerformer` — no stepping; the head pitches forward (the intent's ``lean``) to
  ``dead_zone + f (full_speed - dead_zone)`` with ``f = cadence / cadence_max``: the technique's
  speed is the same fraction of its full speed as the walk's cadence is of the top cadence
  (:func:`~vrloco_env.actions.action_to_intent`), so ``walk = 1`` is full speed under both. (The
  speeds themselves differ where the full speeds do: head tilt's 1.4 m/s against eq 17's step
  length times the top cadence.)
* :class:`LookDownPerformer` — no stepping; when what the user wants (walk > 0) differs from what
  they see (the auto-walk moving them in the last step, or pushing them against what blocks them),
  they look down towards ``LOOK_MARGIN_DEG`` past the threshold until their head is past the
  threshold by half that margin (they feel and see how far they look; at most ``MAX_LOOK_S``), look
  back up, and wait ``SETTLE_S`` to see the effect before looking down again.

The head follows the lean with the motion model's critically damped lag
(:attr:`~vrloco_env.user.motion_params.MotionParams.gesture_lag_s`), so a tilt or a look down
takes a moment, as a neck does. The lean stays inside the motion model's +-45 deg.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers, stream_rows
from estimators.locomotion.gestures import LookDownToToggle, TiltToMove
from vrloco_env.user.intent import Intent
from vrloco_env.user.motion_params import MotionParams

__all__ = [
    "LOOK_MARGIN_DEG",
    "MAX_LOOK_S",
    "SETTLE_S",
    "LookDownPerformer",
    "TiltPerformer",
    "gesture_performer",
]

#: How far past the threshold (deg) a user looks down to toggle. A choice: a deliberate look at
#: the floor, not a glance that grazes the threshold.
LOOK_MARGIN_DEG = 10.0
#: The longest (s) a user holds a look down that does not get past the threshold. A choice: a
#: person who cannot look further gives up and looks up again.
MAX_LOOK_S = 2.0
#: How long (s) a user waits after a look down before judging whether it toggled. A choice: a
#: few frames of seeing themselves move or stop.
SETTLE_S = 0.5

_MAX_LEAN = float(np.deg2rad(45.0))


def _lean_sum(intent: Intent, extra: NDArray[np.float64], b: int) -> NDArray[np.float64]:
    """The intent's lean plus ``extra``, inside the motion model's +-45 deg."""
    lean = np.broadcast_to(np.asarray(intent.lean, dtype=np.float64), (b,))
    return np.clip(lean + extra, -_MAX_LEAN, _MAX_LEAN)


class TiltPerformer(TakesUsers):
    """B users who tilt the head forward to walk (module docstring); stateless."""

    per_user_fields = ()
    batch_size_field = "batch_size"

    def __init__(self, gesture: TiltToMove, batch_size: int, motion: MotionParams) -> None:
        self.gesture = gesture
        self.batch_size = int(batch_size)
        self._cadence_max = float(motion.cadence_range_hz[1])

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Stateless: nothing to forget."""

    def intent(
        self, intent: Intent, moving: NDArray[np.bool_], head_pitch: NDArray[np.float64]
    ) -> Intent:
        """The motion model's intent for ``intent`` (``moving`` and ``head_pitch`` not read)."""
        b, g = self.batch_size, self.gesture
        cadence = np.broadcast_to(np.asarray(intent.cadence, dtype=np.float64), (b,))
        fraction = np.minimum(cadence / self._cadence_max, 1.0)
        tilt = np.where(
            cadence > 0.0, g.dead_zone_rad + fraction * (g.full_speed_rad - g.dead_zone_rad), 0.0
        )
        return replace(intent, cadence=np.zeros(b), lean=_lean_sum(intent, tilt, b))


class LookDownPerformer(TakesUsers):
    """B users who look down to start or stop walking (module docstring).

    Per user: the seconds spent in the current look down (``_looking``, -1 when not looking) and
    left of the wait after it (``_settling``).
    """

    per_user_fields = ("_looking", "_settling")
    batch_size_field = "batch_size"

    def __init__(self, gesture: LookDownToToggle, batch_size: int, dt: float) -> None:
        self.gesture = gesture
        self.batch_size = b = int(batch_size)
        self.dt = float(dt)
        self._looking = np.full(b, -1.0)
        self._settling = np.zeros(b)
        margin = np.deg2rad(LOOK_MARGIN_DEG)
        self._down = gesture.threshold_rad + margin
        self._far_enough = gesture.threshold_rad + 0.5 * margin

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Users ``rows`` (indices or a (B,) mask; None: all) are not looking down."""
        which = stream_rows(rows, self.batch_size)
        self._looking[which] = -1.0
        self._settling[which] = 0.0

    def intent(
        self, intent: Intent, moving: NDArray[np.bool_], head_pitch: NDArray[np.float64]
    ) -> Intent:
        """The motion model's intent for ``intent``, given whether each user saw themselves
        ``moving`` (B,) in the last step and their head's true pitch (B,) rad at its end."""
        b = self.batch_size
        cadence = np.broadcast_to(np.asarray(intent.cadence, dtype=np.float64), (b,))
        looking = self._looking >= 0.0
        done = looking & ((head_pitch >= self._far_enough) | (self._looking >= MAX_LOOK_S))
        self._settling = np.where(done, SETTLE_S, np.maximum(self._settling - self.dt, 0.0))
        looking &= ~done
        idle = ~looking & (self._settling <= 0.0)
        looking |= idle & ((cadence > 0.0) != np.asarray(moving, bool))
        self._looking = np.where(looking, np.maximum(self._looking, 0.0) + self.dt, -1.0)
        down = np.where(looking, self._down, 0.0)
        return replace(intent, cadence=np.zeros(b), lean=_lean_sum(intent, down, b))


def gesture_performer(stages: Any, batch_size: int, dt: float, motion: MotionParams) -> Any:
    """The performer of the gesture the ``stages`` declare (their locomotion's, else their
    steering's ``gesture``), or None where the users step in place or point the hand (the
    intent as it is)."""
    gesture = getattr(stages.locomotion, "gesture", None)
    if gesture is None:
        gesture = getattr(stages.steering, "gesture", None)
    if isinstance(gesture, TiltToMove):
        return TiltPerformer(gesture, batch_size, motion)
    if isinstance(gesture, LookDownToToggle):
        return LookDownPerformer(gesture, batch_size, dt)
    return None
