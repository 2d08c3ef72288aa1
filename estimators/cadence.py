"""Cadence (steps/s) from step events, streaming and batched.

At each control step that brings detected steps, the cadence is their count over the time since
the previous step (an instantaneous rate: the first step of a bout gives none, there is no
previous interval); without steps it decays exponentially with time constant ``tau_s``, so it
falls toward zero while the user stands. The estimate is capped at 4 steps/s, above any human
stepping rate (about 3.5 steps/s at most).

:func:`cadence_kernel` is the one implementation (compiled; ``cadence_kernel.py_func`` is the
readable reference); :class:`CadenceEstimator` holds its state for B users.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import stream_rows

__all__ = ["MAX_CADENCE", "CadenceEstimator", "cadence_kernel"]

#: Largest cadence reported (steps/s).
MAX_CADENCE = 4.0


@numba.njit(cache=True)
def cadence_kernel(steps, dt, tau_s, since_step, cadence):  # pragma: no cover (compiled)
    """One update of length ``dt`` (s) with ``steps`` (B,) new steps: ``since_step`` (s since
    the last step, inf before any) and ``cadence`` (B,) are updated in place."""
    decay = math.exp(-dt / tau_s)
    for b in range(steps.shape[0]):
        s = steps[b]
        since = since_step[b] + dt
        if s > 0.0 and math.isfinite(since):
            c = s / max(since, dt)
        else:
            c = cadence[b] * decay
        cadence[b] = min(c, MAX_CADENCE)
        since_step[b] = 0.0 if s > 0.0 else since


class CadenceEstimator:
    """The cadence of B users from their detected steps per control step.

    Args:
        batch_size: B.
        tau_s: decay time constant (s) without steps. Default 1.5 s, about two step intervals
            of the slowest walking-in-place cadence (1.2 steps/s): the estimate halves within a
            second of the last step.
    """

    def __init__(self, batch_size: int, tau_s: float = 1.5) -> None:
        if not (isinstance(tau_s, int | float) and math.isfinite(tau_s) and 0.05 <= tau_s <= 30):
            raise ValueError(f"tau_s={tau_s!r}: must be in [0.05, 30] s")
        self.batch_size = int(batch_size)
        self.tau_s = float(tau_s)
        self.cadence = np.zeros(self.batch_size)
        self.since_step = np.full(self.batch_size, np.inf)

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the users ``rows`` (indices, a (B,) mask, or None: all)."""
        r = stream_rows(rows, self.batch_size, "rows")
        self.cadence[r] = 0.0
        self.since_step[r] = np.inf

    def update(self, steps: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
        """Advance by ``dt`` s with ``steps`` (B,) new steps; returns the cadence (B,) (a copy)."""
        cadence_kernel(np.asarray(steps, dtype=np.float64), float(dt), self.tau_s,
                       self.since_step, self.cadence)  # fmt: skip
        return self.cadence.copy()
