"""Cadence (steps/s) from step events, streaming and batched.

At each control step that brings detected steps, the cadence is their count over the time since
the previous step (an instantaneous rate: the first step of a bout gives none, there is no
previous interval); without steps it decays exponentially with time constant ``tau_s``, so it
falls toward zero while the user stands. The estimate is capped at 4 steps/s, above any human
stepping rate (about 3.5 steps/s at most).

:data:`estimators.steps._kernel.cadence_kernel` is the one implementation (compiled;
``cadence_kernel.py_func`` is the readable reference); :class:`CadenceEstimator` holds its state
for B users.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers, stream_rows
from estimators.kernels import param_record, state_records
from estimators.steps._kernel import CADENCE_STATE, cadence_kernel

__all__ = ["CadenceEstimator"]


class CadenceEstimator(TakesUsers):
    """The cadence of B users from their detected steps per control step.

    Args:
        batch_size: B.
        tau_s: decay time constant (s) without steps. Default 1.5 s, about two step intervals
            of the slowest walking-in-place cadence (1.2 steps/s): the estimate halves within a
            second of the last step.
    """

    per_user_fields = ("_state",)
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int, tau_s: float = 1.5) -> None:
        if not (isinstance(tau_s, int | float) and math.isfinite(tau_s) and 0.05 <= tau_s <= 30):
            raise ValueError(f"tau_s={tau_s!r}: must be in [0.05, 30] s")
        self.batch_size = int(batch_size)
        self.tau_s = float(tau_s)
        self._prm = param_record(tau_s=self.tau_s)
        self._state = state_records(CADENCE_STATE, self.batch_size)
        self.reset()

    @property
    def cadence(self) -> NDArray[np.float64]:
        """The cadence (steps/s), (B,) (a copy)."""
        return self._state["cadence"].copy()

    @property
    def since_step(self) -> NDArray[np.float64]:
        """Time (s) since each user's last step, inf before any, (B,) (a copy)."""
        return self._state["since_step"].copy()

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the users ``rows`` (indices, a (B,) mask, or None: all)."""
        r = stream_rows(rows, self.batch_size, "rows")
        self._state["cadence"][r] = 0.0
        self._state["since_step"][r] = np.inf

    def update(self, steps: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
        """Advance by ``dt`` s with ``steps`` (B,) new steps; returns the cadence (B,) (a copy)."""
        cadence_kernel(self.batch_size)(
            np.asarray(steps, dtype=np.float64), float(dt), self._prm, self._state
        )
        return self._state["cadence"].copy()
