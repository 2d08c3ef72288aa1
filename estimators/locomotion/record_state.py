"""The kinematics shared by the locomotion models whose per-user state is one record array
(the compiled ones: cadence speed, head tilt, the look-down toggle): position, heading, distance
and speed read from it, and a restart of the selected users."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers
from estimators.kernels import state_records
from estimators.rotations import wrap_angle
from estimators.validation import check_mask, check_per_user, check_positions

__all__ = ["RecordLocomotion"]


class RecordLocomotion(TakesUsers):
    """B users whose state is a (B,) record array ``_state`` with at least the fields ``pos``
    (2,) (m), ``yaw`` (rad) and ``yaw_known`` (0 / 1), ``dist`` (m) and ``speed`` (m/s).

    Args:
        batch_size: B >= 1.
        fields: the record's fields (:func:`estimators.kernels.state_records`).
    """

    per_user_fields = ("_state",)
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int, fields: Mapping[str, tuple[int, ...]]) -> None:
        if isinstance(batch_size, bool) or not isinstance(batch_size, int | np.integer):
            raise ValueError(f"batch_size must be an integer >= 1, got {batch_size!r}")
        if batch_size < 1:
            raise ValueError(f"batch_size must be an integer >= 1, got {batch_size!r}")
        self.batch_size = int(batch_size)
        self._state = state_records(fields, self.batch_size)

    @property
    def position(self) -> NDArray[np.float64]:
        """Virtual positions (m), (B, 2)."""
        return self._state["pos"].copy()

    @property
    def heading(self) -> NDArray[np.float64]:
        """Yaw of the last update (or the reset heading), rad in (-pi, pi], (B,)."""
        return wrap_angle(self._state["yaw"])

    @property
    def distance(self) -> NDArray[np.float64]:
        """Path length travelled since reset (m), (B,)."""
        return self._state["dist"].copy()

    @property
    def speed(self) -> NDArray[np.float64]:
        """Speed at the end of the last update (m/s), (B,)."""
        return self._state["speed"].copy()

    def _restart(
        self, mask: ArrayLike | None, position: ArrayLike | None, heading: ArrayLike | None
    ) -> NDArray[np.bool_]:
        """Zero the state of the users selected by ``mask`` (B,) bool (all if None), put them
        at ``position`` (m) and, if given, on ``heading`` (rad); returns the selection."""
        b = self.batch_size
        sel = check_mask(mask, b)
        st = self._state
        st[sel] = 0.0
        st["pos"][sel] = check_positions(position, b)[sel]
        if heading is not None:
            st["yaw"][sel] = wrap_angle(check_per_user(heading, b, "heading", 0.0, "rad"))[sel]
            st["yaw_known"][sel] = 1.0
        return sel
