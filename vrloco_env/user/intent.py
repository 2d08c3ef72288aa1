"""What B simulated users want to do during one control step (:class:`Intent`), the input of
:meth:`vrloco_env.user.motion.UserMotion.advance`, and the head-on-torso yaw limit
(:data:`MAX_HEAD_YAW`)."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["MAX_HEAD_YAW", "Intent"]


@dataclass
class Intent:
    """What B users want to do during one control step (arrays broadcast to the batch).

    Attributes:
        cadence: stepping cadence (steps/s), 0 to stand still, otherwise within
            ``MotionParams.cadence_range_hz``. Shape (B,).
        turn_rate: body yaw rate (rad/s, counter-clockwise positive), |.| <= max_turn_rate. (B,)
        hand_rates: hand [yaw, pitch, roll] rates (rad/s) relative to the torso. (B, 3)
        gesture_amplitude: head [yaw, pitch, roll] oscillation amplitudes (rad) about the body
            heading: serpentine, nod and shake of Zhang 2021. (B, 3)
        gesture_frequency: frequencies (Hz) of those oscillations. (B, 3)
        lean: head pitch offset (rad; negative leans back / looks up). (B,)
        head_yaw: head-on-torso yaw target (rad, counter-clockwise positive, |.| <= 80 deg):
            where the user turns the head relative to the body, followed with the critically
            damped lag ``MotionParams.head_turn_lag_s``. 0 keeps the head straight on the torso
            (apart from the gestures). (B,)
    """

    cadence: ArrayLike = 0.0
    turn_rate: ArrayLike = 0.0
    hand_rates: ArrayLike = (0.0, 0.0, 0.0)
    gesture_amplitude: ArrayLike = (0.0, 0.0, 0.0)
    gesture_frequency: ArrayLike = (0.5, 0.5, 0.5)
    lean: ArrayLike = 0.0
    head_yaw: ArrayLike = 0.0


#: Largest head-on-torso yaw target (rad): the active range of cervical axial rotation of
#: adults, about 70-80 deg each way (Ferrario et al., J. Orthop. Res. 20(1), 2002).
MAX_HEAD_YAW = float(np.deg2rad(80.0))

_INTENT_FIELDS = tuple(f.name for f in fields(Intent))


def _intent_arrays(intent: Intent) -> dict[str, NDArray[np.float64]]:
    """The intent's fields as float arrays, unchecked (see ``UserMotion.advance``)."""
    return {name: np.asarray(getattr(intent, name), dtype=np.float64) for name in _INTENT_FIELDS}
