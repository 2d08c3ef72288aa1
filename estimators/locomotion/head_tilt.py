"""Head-tilt locomotion: the user tilts the head forward to walk (Tregillus, Al Zayer & Folmer,
"Handsfree omnidirectional VR navigation using head tilt", CHI 2017).

Per user and update, from the estimated head pitch ``p`` (rad, positive nose down) at the end of
the interval::

    speed = max_speed * clip((p - dead_zone) / (full_speed_pitch - dead_zone), 0, 1)

along the yaw halfway through the interval. There is no stepping: the step counts are not read.
Looking down at anything past the dead zone moves the user, as with the published technique.
Tregillus 2017 tilts in every direction (pitch forward and back, roll sideways); this model
tilts forward only (the environment's actions walk forward and turn), so backward tilt does not
move the user.

The per-update loop is the compiled kernel :data:`estimators.locomotion._kernel.head_tilt_kernel`
(its ``py_func`` is the readable reference).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.kernels import param_record
from estimators.locomotion._kernel import PITCH_DRIVEN_STATE, head_tilt_kernel
from estimators.locomotion.gestures import TiltToMove
from estimators.locomotion.record_state import RecordLocomotion
from estimators.validation import (
    check_in_range,
    check_locomotion_update,
    check_per_user,
)

__all__ = ["HeadTilt", "HeadTiltParams", "PitchDriven"]

#: Preferred walking speed of adults (m/s): about 1.4 m/s (R. W. Bohannon, "Comfortable and
#: maximum walking speed of adults aged 20-79 years", Age and Ageing 26(1), 1997: 1.27-1.46 m/s
#: across the age groups). The full speed of the pitch-driven techniques, so that they compare
#: with walking in place at a human pace rather than at a speed chosen to win.
WALKING_SPEED_MPS = 1.4


@dataclass(frozen=True)
class HeadTiltParams:
    """Parameters of :class:`HeadTilt`; every field is validated on construction."""

    dead_zone_deg: float = 10.0
    """Pitch (deg, nose down) below which the tilt does not move the user, in [0, 40]. A choice:
    Tregillus 2017 uses a dead zone whose size its abstract does not give; 10 deg keeps the head's
    resting pitch and small nods still while a deliberate tilt moves."""
    full_speed_deg: float = 30.0
    """Pitch (deg) from which the user walks at full speed, in (dead_zone_deg, 45]. A choice:
    20 deg of range past the dead zone, well inside the neck's comfortable flexion."""
    max_speed_mps: float = WALKING_SPEED_MPS
    """Full speed (m/s), in (0, 5]; default :data:`WALKING_SPEED_MPS`."""

    def __post_init__(self) -> None:
        check_in_range(self, "dead_zone_deg", 0.0, 40.0, "deg")
        check_in_range(self, "full_speed_deg", self.dead_zone_deg, 45.0, "deg", lo_open=True)
        check_in_range(self, "max_speed_mps", 0.0, 5.0, "m/s", lo_open=True)

    @property
    def gesture(self) -> TiltToMove:
        """What the user does: tilt past the dead zone, up to full speed."""
        return TiltToMove(math.radians(self.dead_zone_deg), math.radians(self.full_speed_deg))

    def build(self, batch_size: int, step_length: ArrayLike = 0.7) -> HeadTilt:
        """The :class:`HeadTilt` model with these parameters (``step_length`` is not used)."""
        return HeadTilt(batch_size, step_length, self)


class PitchDriven(RecordLocomotion):
    """A locomotion model driven by the estimated head pitch (shared by head tilt and the
    look-down toggle): B users' positions, distances and speeds in the kernel state
    :data:`~estimators.locomotion._kernel.PITCH_DRIVEN_STATE`.

    ``uses_pitch = True``: the environment passes ``pitch=`` (the (B,) estimated head pitch,
    rad, positive nose down) to :meth:`update`.
    """

    uses_pitch = True
    per_user_fields = ("_state",)

    def __init__(
        self, batch_size: int, position: ArrayLike | None = None, heading: ArrayLike | None = None
    ) -> None:
        super().__init__(batch_size, PITCH_DRIVEN_STATE)
        self.reset(position=position, heading=heading)

    def reset(
        self,
        mask: ArrayLike | None = None,
        position: ArrayLike | None = None,
        heading: ArrayLike | None = None,
    ) -> None:
        """Stop the users selected by ``mask`` (B,) bool (all if None) at ``position`` (m),
        with the look-down toggle armed; their heading is ``heading`` (rad) if given, else the
        next yaw."""
        sel = self._restart(mask, position, heading)
        self._state["armed"][sel] = 1.0

    def update(
        self,
        steps: ArrayLike,
        yaw: ArrayLike,
        dt: float,
        bearing: ArrayLike | None = None,
        pitch: ArrayLike | None = None,
    ) -> NDArray[np.float64]:
        """Advance every user by ``dt`` seconds.

        Args:
            steps: steps detected during the interval, (B,); checked, not used.
            yaw: walking direction at the end of the interval (rad), (B,) or scalar.
            dt: length of the interval (s), in (0, 10].
            bearing: not used (must be None or 0).
            pitch: estimated head pitch at the end of the interval (rad, positive nose down),
                (B,) or scalar, in [-pi/2, pi/2].

        Returns:
            The new positions (m), (B, 2).
        """
        _, y, dtf, br = check_locomotion_update(steps, yaw, dt, bearing, self.batch_size)
        if np.any(br != 0.0):
            raise ValueError(f"{type(self).__name__} walks along the yaw: bearing must be 0")
        if pitch is None:
            raise ValueError(
                f"{type(self).__name__}.update needs pitch= (the estimated head pitch, rad)"
            )
        half_turn = math.pi / 2 + 1e-9
        p = check_per_user(
            pitch, self.batch_size, "pitch", 0.0, "rad", (-half_turn, half_turn), "[-pi/2, pi/2]"
        )
        self._kernel(self.batch_size)(
            np.ascontiguousarray(p), np.ascontiguousarray(y), dtf, self._prm, self._state
        )
        return self._state["pos"].copy()


class HeadTilt(PitchDriven):
    """Walk at a speed set by the head's forward tilt, for B users (module docstring).

    Args:
        batch_size: B >= 1.
        step_length: not used (the locomotion factory's second argument).
        params: :class:`HeadTiltParams` (defaults if None).
        position: initial positions (m), (B, 2) or (2,); zeros by default.
        heading: initial heading (rad), scalar or (B,); the first yaw if None.
    """

    name = "head_tilt"
    per_user_fields = ("_state",)
    _kernel = head_tilt_kernel

    def __init__(
        self,
        batch_size: int,
        step_length: ArrayLike = 0.7,
        params: HeadTiltParams | None = None,
        position: ArrayLike | None = None,
        heading: ArrayLike | None = None,
    ) -> None:
        self.params = HeadTiltParams() if params is None else params
        if not isinstance(self.params, HeadTiltParams):
            raise ValueError(f"params must be a HeadTiltParams, got {type(self.params).__name__}")
        self.gesture = self.params.gesture
        self._prm = param_record(
            dead_zone=math.radians(self.params.dead_zone_deg),
            full_speed_pitch=math.radians(self.params.full_speed_deg),
            max_speed=self.params.max_speed_mps,
        )
        super().__init__(batch_size, position, heading)
