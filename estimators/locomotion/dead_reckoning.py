"""Virtual trajectory by step-and-heading dead reckoning: Zhang 2021, eq (17).

At each detected peak t, Zhang, Chen & Gao 2021 (section 3) updates the 2D virtual
position

    P_t = P_{t-1}                                   if still
    P_t = P_{t-1} + SL [cos psi_t, sin psi_t]       if walk

with SL a fixed step length and psi_t the estimated heading (yaw, rad, ENU: counter-clockwise from
+x east, as in :mod:`estimators.rotations`). The position jumps one step length at each step event
and stays put between them; :class:`estimators.locomotion.SmoothLocomotion` is the continuous
alternative with the same interface.

Decisions:

* A "step event" is what the gait detector reports
  (:class:`estimators.steps.zhang2021.StepDetector`): only accepted walking steps, so "still" needs
  no separate input — a sample without a step leaves P unchanged, as eq (17)'s still branch does.
  The detector may confirm two steps at one sample (the first step of a bout is released with the
  second), so ``steps`` is a count, not a flag.
* psi_t is the heading given with the update that carries the step; in streaming use that is the
  yaw estimate when the step is *confirmed* (the detector's latency after the heel strike), the
  best a causal system has.
* Extension (the paper's future work): each step may carry a ``bearing`` (rad) relative to the
  heading: 0 forward (eq 17), pi backward, +pi/2 a side step to the left. The step then moves
  ``SL [cos(psi + bearing), sin(psi + bearing)]``.
* Default step length 0.7 m: a typical adult walking step (about 0.41-0.45 x body height for
  a 1.6-1.75 m adult; e.g. the 0.7 m commonly used in pedestrian dead reckoning).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers
from estimators.validation import (
    check_locomotion_update,
    check_mask,
    check_per_user,
    check_positions,
    check_step_length,
)

__all__ = ["DeadReckoning", "dead_reckon"]


class DeadReckoning(TakesUsers):
    """Eq (17) for B users: the position jumps ``step_length`` along the heading at each step.

    Args:
        batch_size: B >= 1.
        step_length: SL (m), a scalar or (B,), in [0, 3].
        position: initial positions (m), (B, 2) or (2,); zeros by default.
        heading: initial heading (rad), scalar or (B,); 0 (east) by default.

    Same interface as :class:`estimators.locomotion.SmoothLocomotion` (the
    :class:`estimators.stages.Locomotion` protocol): :meth:`update`, :meth:`reset`,
    :attr:`position`, :attr:`heading`, :attr:`distance`.
    """

    per_user_fields = ("step_length", "_pos", "_heading", "_distance")
    batch_size_field = "batch_size"

    def __init__(
        self,
        batch_size: int,
        step_length: ArrayLike = 0.7,
        position: ArrayLike | None = None,
        heading: ArrayLike | None = None,
    ) -> None:
        if not isinstance(batch_size, int | np.integer) or batch_size < 1:
            raise ValueError(f"batch_size must be an integer >= 1, got {batch_size!r}")
        self.batch_size = int(batch_size)
        self.step_length = check_step_length(step_length, (self.batch_size,))
        self._pos = np.zeros((self.batch_size, 2))
        self._heading = np.zeros(self.batch_size)
        self._distance = np.zeros(self.batch_size)
        self.reset(position=position, heading=heading)

    @property
    def position(self) -> NDArray[np.float64]:
        """Virtual positions (m), (B, 2)."""
        return self._pos.copy()

    @property
    def heading(self) -> NDArray[np.float64]:
        """Heading (rad) used for the last update, (B,)."""
        return self._heading.copy()

    @property
    def distance(self) -> NDArray[np.float64]:
        """Path length travelled since the last reset (m), (B,)."""
        return self._distance.copy()

    def reset(
        self,
        mask: ArrayLike | None = None,
        position: ArrayLike | None = None,
        heading: ArrayLike | None = None,
    ) -> None:
        """Put the users selected by ``mask`` (B,) bool (all if None) at ``position`` (m) facing
        ``heading`` (rad), with zero travelled distance."""
        sel = check_mask(mask, self.batch_size)
        pos = check_positions(position, self.batch_size)
        self._pos[sel] = pos[sel]
        self._heading[sel] = check_per_user(heading, self.batch_size, "heading", 0.0, "rad")[sel]
        self._distance[sel] = 0.0

    def update(
        self,
        steps: ArrayLike,
        yaw: ArrayLike,
        dt: float,
        bearing: ArrayLike | None = None,
    ) -> NDArray[np.float64]:
        """Apply the step events of one interval.

        Args:
            steps: steps detected in this interval per user, (B,) counts >= 0 (or bool).
            yaw: estimated heading psi (rad), (B,) or scalar.
            dt: length of the interval (s), > 0; eq (17) does not use it (kept for the common
                interface).
            bearing: step direction relative to the heading (rad), (B,) or scalar; 0 forward.

        Returns:
            The new positions (m), (B, 2).
        """
        st, y, _, br = check_locomotion_update(steps, yaw, dt, bearing, self.batch_size)
        d = st * self.step_length
        ang = y + br
        self._pos[:, 0] += d * np.cos(ang)
        self._pos[:, 1] += d * np.sin(ang)
        self._distance += d
        self._heading = y
        return self._pos.copy()


def dead_reckon(
    steps: ArrayLike,
    yaw: ArrayLike,
    step_length: ArrayLike = 0.7,
    bearing: ArrayLike | None = None,
    start: ArrayLike = (0.0, 0.0),
) -> NDArray[np.float64]:
    """Offline eq (17): the virtual path at every sample.

    Args:
        steps: a 1-D *integer* array is read as the sample indices at which a step happened
            (an index may repeat for two steps at one sample; needs 1-D ``yaw``); anything else
            is a per-sample mask (bool) or step count (numbers >= 0) of ``yaw``'s shape
            (..., N). Pass 1-D counts as float (``counts.astype(float)``) or bool.
        yaw: heading at each sample (rad), (..., N).
        step_length: SL (m), scalar or broadcastable to the leading shape of ``yaw``.
        bearing: step direction relative to the heading (rad), broadcastable to ``yaw``.
        start: position before the first sample (m), broadcastable to (..., 2).

    Returns:
        Positions (m) after each sample, (..., N, 2).
    """
    y = np.asarray(yaw, dtype=np.float64)
    if y.ndim < 1 or y.shape[-1] == 0:
        raise ValueError(f"yaw must have shape (..., N) with N >= 1, got {y.shape}")
    if not np.all(np.isfinite(y)):
        raise ValueError("yaw contains NaN or infinite values (rad)")
    s = np.asarray(steps)
    if s.dtype.kind in "iu" and s.ndim == 1:
        # Sample indices.
        if y.ndim != 1:
            raise ValueError("step indices need a 1-D yaw (N,)")
        if s.size and (s.min() < 0 or s.max() >= y.size):
            raise ValueError(f"step indices must be in [0, {y.size - 1}]")
        count = np.bincount(s, minlength=y.size).astype(np.float64)
    else:
        count = np.asarray(s, dtype=np.float64)
        if count.shape != y.shape:
            raise ValueError(
                f"steps must have the shape of yaw {y.shape} (per-sample mask or counts) or be "
                f"1-D integer indices, got {count.shape}"
            )
        if not np.all(np.isfinite(count)) or np.any(count < 0.0):
            raise ValueError("steps must be finite step counts >= 0")
    sl = check_step_length(step_length, y.shape[:-1])[..., None]
    br = np.zeros_like(y) if bearing is None else np.asarray(bearing, dtype=np.float64)
    try:
        br = np.broadcast_to(br, y.shape)
    except ValueError:
        raise ValueError(f"bearing must broadcast to yaw's shape {y.shape}") from None
    if not np.all(np.isfinite(br)):
        raise ValueError("bearing contains NaN or infinite values (rad)")
    try:
        p0 = np.broadcast_to(np.asarray(start, dtype=np.float64), (*y.shape[:-1], 2))
    except ValueError:
        raise ValueError(f"start must broadcast to shape {(*y.shape[:-1], 2)} (m)") from None
    d = count * sl
    step = np.stack([d * np.cos(y + br), d * np.sin(y + br)], axis=-1)
    return p0[..., None, :] + np.cumsum(step, axis=-2)
