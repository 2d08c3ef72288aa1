"""The action space: what a simulated user can do in one control step, as numbers in [-1, 1].

``action = [walk, turn, hand_yaw_rate, hand_pitch_rate, hand_roll_rate]``, a float32 Box(-1, 1):

* ``walk``: stepping cadence. ``walk <= 0`` stands still; ``walk in (0, 1]`` steps in place at
  ``lo + walk * (hi - lo)`` steps/s with ``(lo, hi) = MotionParams.cadence_range_hz``.
* ``turn``: body yaw rate, ``turn * max_turn_rate`` (counter-clockwise positive).
* hand rates: ``rate * max_hand_rate`` about the hand's yaw, pitch and roll axes.

Out-of-range actions follow the Gymnasium convention for Box spaces: finite values outside
[-1, 1] are clipped to the box (as stable-baselines3 clips policy outputs); NaN or infinite
values raise a ValueError naming the offending entry, and so do a wrong shape and values that
are not real numbers (booleans, complex numbers, strings).
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vrloco_env.user import Intent, MotionParams

__all__ = ["ACTION_NAMES", "ACTION_SIZE", "action_to_intent", "check_action", "check_actions"]

ACTION_NAMES = ("walk", "turn", "hand_yaw_rate", "hand_pitch_rate", "hand_roll_rate")
ACTION_SIZE = len(ACTION_NAMES)


def check_actions(actions: ArrayLike, batch_size: int) -> NDArray[np.float64]:
    """Validate a (B, 5) batch of actions and clip finite values to [-1, 1].

    Real numbers of any dtype are taken (ints, floats, objects such as ``Fraction``); booleans,
    complex numbers, strings and other objects are not actions.

    Raises:
        ValueError: not an array of real numbers, wrong shape, or a NaN/infinite entry (named
            by user and action).
    """
    a = _as_numbers(actions, batch_size)
    if a.shape != (batch_size, ACTION_SIZE):
        raise ValueError(
            f"action must have shape ({batch_size}, {ACTION_SIZE}) "
            f"[{', '.join(ACTION_NAMES)}], got {a.shape}"
        )
    if not np.isfinite(a).all():
        user, k = np.argwhere(~np.isfinite(a))[0]
        where = f"action[{k}] ({ACTION_NAMES[k]})"
        if batch_size > 1:
            where = f"action of sub-env {user}: {where}"
        raise ValueError(f"{where} is {a[user, k]}; actions must be finite, in [-1, 1]")
    return np.minimum(np.maximum(a, -1.0), 1.0)  # np.clip, without its ~5 us of overhead


def check_action(action: ArrayLike) -> NDArray[np.float64]:
    """One user's action ``(5,)`` as float64: real numbers only (as :func:`check_actions`), the
    right shape; its range and finiteness are checked with the batch."""
    a = _as_numbers(action, None)
    if a.shape != (ACTION_SIZE,):
        raise ValueError(
            f"action must have shape ({ACTION_SIZE},) [{', '.join(ACTION_NAMES)}], got {a.shape}"
        )
    return a


def _as_numbers(actions: ArrayLike, batch_size: int | None) -> NDArray[np.float64]:
    """``actions`` as a float64 array, or a ValueError saying what an action is."""
    try:
        a = np.asarray(actions)
        ok = a.dtype.kind in "iuf" or (
            a.dtype.kind == "O"
            and not any(
                isinstance(x, bool | complex | str | bytes | np.bool_ | np.complexfloating)
                for x in a.flat
            )
        )
        if ok:
            return a.astype(np.float64, copy=False)
    except (TypeError, ValueError, OverflowError):
        pass
    shown = " ".join(repr(actions).split())  # one line
    shown = shown if len(shown) <= 60 else shown[:57] + "..."
    shape = f"({ACTION_SIZE},)" if batch_size is None else f"({batch_size}, {ACTION_SIZE})"
    raise ValueError(
        f"action must be an array of shape {shape} of real numbers "
        f"[{', '.join(ACTION_NAMES)}], got {type(actions).__name__} {shown}"
    )


def action_to_intent(actions: NDArray[np.float64], params: MotionParams) -> Intent:
    """Map checked actions (B, 5) in [-1, 1] to the motion model's :class:`Intent`."""
    lo, hi = params.cadence_range_hz
    walk = actions[:, 0]
    cadence = np.where(walk > 0.0, lo + walk * (hi - lo), 0.0)
    still_amplitude, still_frequency, upright, straight = _no_gestures(actions.shape[0])
    return Intent(
        cadence=cadence,
        turn_rate=actions[:, 1] * params.max_turn_rate,
        hand_rates=actions[:, 2:5] * params.max_hand_rate,
        gesture_amplitude=still_amplitude,
        gesture_frequency=still_frequency,
        lean=upright,
        head_yaw=straight,
    )


@functools.cache
def _no_gestures(b: int) -> tuple[NDArray[np.float64], ...]:
    """The intent fields the actions leave at rest (no head gestures, no lean, the head straight
    on the torso), built once per batch size and read-only (the motion model only reads its
    intents; :mod:`vrloco_env.user.behaviour` builds new arrays for a population's head)."""
    arrays = (np.zeros((b, 3)), np.full((b, 3), 0.5), np.zeros(b), np.zeros(b))
    for x in arrays:
        x.flags.writeable = False
    return arrays
