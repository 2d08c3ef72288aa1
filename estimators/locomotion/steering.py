"""Steering: which yaw turns a walking-in-place user's walking direction.

Zhang 2021 walks where the head points (:class:`HeadSteering`): the estimated head yaw is both the
view and the walking direction, so a user who looks at an obstacle while walking past it walks
into it ("gaze-directed steering"). :class:`HandSteering` walks where the hand points (the torso
yaw plus the estimated hand yaw on the torso). :class:`TorsoSteering` walks where the torso points
instead: the shoulder line of the Kinect v2 skeleton (the body's left-right axis; the torso faces
90 deg to its right), which leaves the head free to look around. While the Kinect has lost the
torso (the user turned away from it, or left its view) it falls back on the head yaw.

Both take the two yaws in one frame — the virtual room's, as the environment passes them (rad,
counter-clockwise) — and return the walking yaw in that frame. ``uses_torso`` tells a caller
whether the torso yaw is read at all (so it need not be computed for head steering).

:func:`torso_yaw` is the estimate of the torso's heading from two shoulder positions.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers
from estimators.locomotion.gestures import PointToSteer
from estimators.rotations import wrap_angle

__all__ = ["HandSteering", "HeadSteering", "TorsoSteering", "torso_yaw"]


def torso_yaw(
    shoulder_left: ArrayLike, shoulder_right: ArrayLike, min_width_m: float = 0.15
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Torso heading from the shoulders, in the world frame (z up).

    Args:
        shoulder_left, shoulder_right: (B, 3) positions (m), world frame; NaN where untracked.
        min_width_m: shoulder lines shorter than this in the horizontal plane (m) give no heading
            (a user seen edge-on, or a skeleton folded by bad tracking). Default 0.15 m, under
            half of an adult's biacromial breadth (about 0.35-0.40 m).

    Returns:
        yaw (B,) rad — 90 deg clockwise from the right-to-left shoulder direction — and (B,)
        validity; yaw is 0 where not valid.
    """
    left = np.asarray(shoulder_left, dtype=np.float64)
    right = np.asarray(shoulder_right, dtype=np.float64)
    if left.shape != right.shape or left.ndim != 2 or left.shape[1] != 3:
        raise ValueError(
            f"shoulders must both have shape (B, 3), got {left.shape} and {right.shape}"
        )
    d = left[:, :2] - right[:, :2]
    width = np.hypot(d[:, 0], d[:, 1])
    valid = np.isfinite(width) & (width >= min_width_m)
    return np.where(valid, wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - np.pi / 2.0), 0.0), valid


class _StatelessSteering(TakesUsers):
    """A steering rule with no state: built for B users, nothing to reset (dropping users
    changes only B)."""

    per_user_fields = ()
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int) -> None:
        self.batch_size = int(batch_size)

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Stateless: nothing to forget."""


class HeadSteering(_StatelessSteering):
    """Walk where the head points (Zhang 2021): the steering yaw is the estimated head yaw."""

    name = "head"
    uses_torso = False
    per_user_fields = ()

    def update(
        self,
        head_yaw: NDArray[np.float64],
        torso_yaw: NDArray[np.float64],
        torso_valid: NDArray[np.bool_],
    ) -> NDArray[np.float64]:
        return head_yaw


class TorsoSteering(_StatelessSteering):
    """Walk where the torso points: the Kinect's torso yaw, the head yaw while it has none."""

    name = "torso"
    uses_torso = True
    per_user_fields = ()

    def update(
        self,
        head_yaw: NDArray[np.float64],
        torso_yaw: NDArray[np.float64],
        torso_valid: NDArray[np.bool_],
    ) -> NDArray[np.float64]:
        return np.where(torso_valid, torso_yaw, head_yaw)


class HandSteering(_StatelessSteering):
    """Walk where the hand points: the torso yaw plus the estimated hand yaw on the torso
    (hand-directed steering, as Lai et al. 2020 compare with gaze-directed steering; the hand's
    orientation from the Kinect through the hand stage, Yao 2023's pipeline by default, so hand
    estimation errors reach the walking direction). Without a hand estimate it walks where the
    torso points, and without a torso where the head points (as :class:`TorsoSteering`).

    ``uses_torso = True`` and ``uses_hand = True``: the environment computes the torso yaw and
    passes ``hand_yaw=`` (the (B,) estimated hand yaw relative to the torso, rad, NaN without an
    estimate) to :meth:`update`. ``gesture``: the users point the hand where they want to walk.
    """

    name = "hand"
    uses_torso = True
    uses_hand = True
    gesture = PointToSteer()
    per_user_fields = ()

    def update(
        self,
        head_yaw: NDArray[np.float64],
        torso_yaw: NDArray[np.float64],
        torso_valid: NDArray[np.bool_],
        hand_yaw: ArrayLike | None = None,
    ) -> NDArray[np.float64]:
        if hand_yaw is None:
            raise ValueError("HandSteering.update needs hand_yaw= (the hand's yaw on the torso)")
        hand = np.asarray(hand_yaw, dtype=np.float64)
        if hand.shape != np.shape(head_yaw):
            raise ValueError(f"hand_yaw must have shape {np.shape(head_yaw)}, got {hand.shape}")
        pointed = wrap_angle(torso_yaw + np.where(np.isfinite(hand), hand, 0.0))
        return np.where(torso_valid, pointed, head_yaw)
