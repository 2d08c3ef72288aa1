"""Look-down-to-move: looking down past a threshold toggles an auto-walk at a fixed speed, as
mobile VR applications did for hands-free navigation (the technique Tregillus & Folmer, "VR-STEP:
Walking-in-place using inertial sensing for hands free navigation in mobile VR environments",
CHI 2016, compare walking in place against).

Per user and update, from the estimated head pitch ``p`` (rad, positive nose down) at the end of
the interval: when the toggle is armed and ``p >= threshold``, walking toggles (start or stop)
and the toggle disarms; it re-arms once ``p < rearm``. A walking user moves at ``speed`` along
the yaw halfway through the interval (the head's: the user walks where they look). There is no
stepping: the step counts are not read.

The per-update loop is the compiled kernel :data:`estimators.locomotion._kernel.look_down_kernel`
(its ``py_func`` is the readable reference).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from numpy.typing import ArrayLike

from estimators.kernels import param_record
from estimators.locomotion._kernel import look_down_kernel
from estimators.locomotion.gestures import LookDownToToggle
from estimators.locomotion.head_tilt import WALKING_SPEED_MPS, PitchDriven
from estimators.validation import check_in_range

__all__ = ["LookDownParams", "LookDownToMove"]


@dataclass(frozen=True)
class LookDownParams:
    """Parameters of :class:`LookDownToMove`; every field is validated on construction."""

    threshold_deg: float = 30.0
    """Pitch (deg, nose down) at or past which a look down toggles walking, in (0, 80]. A choice:
    mobile VR applications of the time toggled on a look towards the floor; 30 deg is past the
    pitch of looking at the floor a few metres ahead, so that walking looks do not toggle."""
    rearm_deg: float = 20.0
    """Pitch (deg) the head must come back above before the next toggle, in [0, threshold_deg).
    A choice: 10 deg of hysteresis, so that one look down toggles once."""
    speed_mps: float = WALKING_SPEED_MPS
    """Auto-walk speed (m/s), in (0, 5]; default the preferred walking speed
    (:data:`~estimators.locomotion.head_tilt.WALKING_SPEED_MPS`)."""

    def __post_init__(self) -> None:
        check_in_range(self, "threshold_deg", 0.0, 80.0, "deg", lo_open=True)
        check_in_range(self, "rearm_deg", 0.0, self.threshold_deg, "deg", hi_open=True)
        check_in_range(self, "speed_mps", 0.0, 5.0, "m/s", lo_open=True)

    @property
    def gesture(self) -> LookDownToToggle:
        """What the user does: look down past the threshold, and back up past the re-arm pitch."""
        return LookDownToToggle(math.radians(self.threshold_deg), math.radians(self.rearm_deg))

    def build(self, batch_size: int, step_length: ArrayLike = 0.7) -> LookDownToMove:
        """The :class:`LookDownToMove` model with these parameters (``step_length`` unused)."""
        return LookDownToMove(batch_size, step_length, self)


class LookDownToMove(PitchDriven):
    """A look down toggles walking at a fixed speed, for B users (module docstring).

    Args:
        batch_size: B >= 1.
        step_length: not used (the locomotion factory's second argument).
        params: :class:`LookDownParams` (defaults if None).
        position: initial positions (m), (B, 2) or (2,); zeros by default.
        heading: initial heading (rad), scalar or (B,); the first yaw if None.
    """

    name = "look_down_to_move"
    per_user_fields = ("_state",)
    _kernel = look_down_kernel

    def __init__(
        self,
        batch_size: int,
        step_length: ArrayLike = 0.7,
        params: LookDownParams | None = None,
        position: ArrayLike | None = None,
        heading: ArrayLike | None = None,
    ) -> None:
        self.params = LookDownParams() if params is None else params
        if not isinstance(self.params, LookDownParams):
            raise ValueError(f"params must be a LookDownParams, got {type(self.params).__name__}")
        self.gesture = self.params.gesture
        self._prm = param_record(
            threshold=math.radians(self.params.threshold_deg),
            rearm=math.radians(self.params.rearm_deg),
            speed=self.params.speed_mps,
        )
        super().__init__(batch_size, position, heading)

    @property
    def walking(self):
        """Whether each user's auto-walk is on, (B,) bool."""
        return self._state["moving"] != 0.0
