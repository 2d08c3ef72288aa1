"""What a technique asks its users to do with their body to move: the gesture a locomotion or
steering stage reads (its ``gesture`` attribute).

A description, not a model of a person: :mod:`vrloco_env.user.gestures` turns a simulated user's
intent (walk, turn, hand) into the body motion of the gesture, and the stage reads the sensors
that motion drives. A stage without a ``gesture`` reads walking in place (:data:`STEP_IN_PLACE`).

* :class:`StepInPlace` — step in place to walk (Zhang 2021 and every walking-in-place technique).
* :class:`TiltToMove` — tilt the head forward past a dead zone to walk, further to go faster.
* :class:`LookDownToToggle` — look down past a threshold and back up to start or stop walking.
* :class:`PointToSteer` — step in place, and point the hand where to walk.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["STEP_IN_PLACE", "LookDownToToggle", "PointToSteer", "StepInPlace", "TiltToMove"]


@dataclass(frozen=True)
class StepInPlace:
    """Step in place to walk; the walking direction is the steering stage's."""


@dataclass(frozen=True)
class TiltToMove:
    """Tilt the head forward (nose down) to walk.

    Attributes:
        dead_zone_rad: pitch (rad) below which the head's tilt does not move the user.
        full_speed_rad: pitch (rad) from which the user walks at full speed.
    """

    dead_zone_rad: float
    full_speed_rad: float


@dataclass(frozen=True)
class LookDownToToggle:
    """Look down to start walking, look down again to stop.

    Attributes:
        threshold_rad: pitch (rad, nose down) at or past which a look down toggles walking.
        rearm_rad: pitch (rad) the head must come back above before the next toggle.
    """

    threshold_rad: float
    rearm_rad: float


@dataclass(frozen=True)
class PointToSteer:
    """Step in place to walk, and point the hand (its yaw on the torso) where to walk."""


#: The gesture of a stage that declares none.
STEP_IN_PLACE = StepInPlace()
