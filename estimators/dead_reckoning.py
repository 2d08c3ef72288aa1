"""Virtual trajectory by step-and-heading dead reckoning: seed 000, eq (17).

At each detected peak t, seed 000 (Zhang, Chen, Gao 2021, section 3) updates the 2D virtual
position

    P_t = P_{t-1}                                   if still
    P_t = P_{t-1} + SL [cos psi_t, sin psi_t]       if walk

with SL a fixed step length and psi_t the estimated heading (yaw, rad, ENU: counter-clockwise from
+x east, as in :mod:`estimators.rotations`). The position jumps one step length at each step event
and stays put between them; :class:`estimators.locomotion.SmoothLocomotion` is the continuous
alternative with the same interface.

Decisions:

* A "step event" is what the gait detector reports (:class:`estimators.gait.StepDetector`): only
  accepted walking steps, so "still" needs no separate input — a sample without a step leaves P
  unchanged, as eq (17)'s still branch does. The detector may confirm two steps at one sample
  (the first step of a bout is released with the second), so ``steps`` is a count, not a flag.
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

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers
from estimators.validation import check_in_range

__all__ = ["DeadReckoning", "check_step_intervals", "dead_reckon"]


def check_step_intervals(params: object) -> None:
    """The step-interval fields a step-driven locomotion filter's parameters share:
    ``min_step_interval`` in [0.05, 2] s, ``max_step_interval`` from it to 10 s, and
    ``default_step_interval`` between the two (a ValueError naming the field otherwise)."""
    check_in_range(params, "min_step_interval", 0.05, 2.0, "s")
    lo = float(params.min_step_interval)
    check_in_range(params, "max_step_interval", lo, 10.0,
                   allowed=f"in [min_step_interval={lo:g}, 10] s")  # fmt: skip
    hi = float(params.max_step_interval)
    between = f"in [min_step_interval={lo:g}, max_step_interval={hi:g}] s"
    check_in_range(params, "default_step_interval", lo, hi, allowed=between)


def _check_step_length(step_length: ArrayLike, shape: tuple[int, ...]) -> NDArray[np.float64]:
    try:
        sl = np.asarray(step_length, dtype=np.float64)
        sl = np.broadcast_to(sl, shape).copy()
    except (TypeError, ValueError):
        raise ValueError(
            f"step_length must be a number or broadcast to shape {shape} (m)"
        ) from None
    if not np.all(np.isfinite(sl)) or np.any(sl < 0.0) or np.any(sl > 3.0):
        raise ValueError("step_length must be finite and in [0, 3] m")
    return sl


def _check_batch(value: ArrayLike | None, b: int, name: str, default: float,
                 unit: str) -> NDArray[np.float64]:  # fmt: skip
    """A (B,) float array from a scalar or (B,) input; NaN/inf rejected."""
    if value is None:
        return np.full(b, default)
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number or a ({b},) array ({unit})") from None
    if a.shape not in ((), (b,)):
        raise ValueError(f"{name} must have shape ({b},) or be a scalar, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or infinite values ({unit})")
    return np.broadcast_to(a, (b,)).astype(np.float64)


def check_update_inputs(
    steps: ArrayLike, yaw: ArrayLike, dt: float, bearing: ArrayLike | None, b: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, NDArray[np.float64]]:
    """Validate the arguments of a locomotion ``update`` for B users (shared by both models).

    Returns:
        steps (B,) float (counts >= 0), yaw (B,) rad, dt s, bearing (B,) rad.

    Raises:
        ValueError: a wrong shape, a NaN or infinite value, a negative step count or dt <= 0.
    """
    if (
        bearing is None
        and type(steps) is np.ndarray
        and type(yaw) is np.ndarray
        and steps.dtype == np.float64
        and yaw.dtype == np.float64
        and steps.shape == yaw.shape == (b,)
        and isinstance(dt, float)
        and 0.0 < dt <= 10.0
        and np.isfinite(yaw).all()
        and np.isfinite(steps).all()
        and (steps >= 0.0).all()
    ):  # the common call (an env step), valid: the same checks in a few microseconds
        return steps, yaw, dt, np.zeros(b)
    st = np.asarray(steps)
    if st.dtype == np.bool_:
        st = st.astype(np.float64)
    try:
        st = np.asarray(st, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"steps must be a ({b},) array of step counts") from None
    if st.shape != (b,):
        raise ValueError(f"steps must have shape ({b},) (step counts per user), got {st.shape}")
    if not np.all(np.isfinite(st)) or np.any(st < 0.0):
        raise ValueError("steps must be finite step counts >= 0")
    y = _check_batch(yaw, b, "yaw", 0.0, "rad")
    try:
        dtf = float(dt)
    except (TypeError, ValueError):
        raise ValueError(f"dt must be a number > 0 s, got {dt!r}") from None
    if not (math.isfinite(dtf) and 0.0 < dtf <= 10.0):
        raise ValueError(f"dt must be in (0, 10] s, got {dt!r}")
    br = _check_batch(bearing, b, "bearing", 0.0, "rad")
    return st, y, dtf, br


class DeadReckoning(TakesUsers):
    """Eq (17) for B users: the position jumps ``step_length`` along the heading at each step.

    Args:
        batch_size: B >= 1.
        step_length: SL (m), a scalar or (B,), in [0, 3].
        position: initial positions (m), (B, 2) or (2,); zeros by default.
        heading: initial heading (rad), scalar or (B,); 0 (east) by default.

    Same interface as :class:`estimators.locomotion.SmoothLocomotion` (the
    :class:`estimators.locomotion.Locomotion` protocol): :meth:`update`, :meth:`reset`,
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
        self.step_length = _check_step_length(step_length, (self.batch_size,))
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
        sel = _mask(mask, self.batch_size)
        pos = _positions(position, self.batch_size)
        self._pos[sel] = pos[sel]
        self._heading[sel] = _check_batch(heading, self.batch_size, "heading", 0.0, "rad")[sel]
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
        st, y, _, br = check_update_inputs(steps, yaw, dt, bearing, self.batch_size)
        d = st * self.step_length
        ang = y + br
        self._pos[:, 0] += d * np.cos(ang)
        self._pos[:, 1] += d * np.sin(ang)
        self._distance += d
        self._heading = y
        return self._pos.copy()


def _mask(mask: ArrayLike | None, b: int) -> NDArray[np.bool_]:
    if mask is None:
        return np.ones(b, dtype=bool)
    m = np.asarray(mask)
    if m.shape != (b,) or m.dtype != np.bool_:
        raise ValueError(f"mask must be a bool array of shape ({b},), got {m.dtype} {m.shape}")
    return m


def _positions(position: ArrayLike | None, b: int) -> NDArray[np.float64]:
    if position is None:
        return np.zeros((b, 2))
    try:
        p = np.asarray(position, dtype=np.float64)
        p = np.broadcast_to(p, (b, 2)).copy()
    except (TypeError, ValueError):
        raise ValueError(f"position must broadcast to shape ({b}, 2) (m)") from None
    if not np.all(np.isfinite(p)):
        raise ValueError("position contains NaN or infinite values (m)")
    return p


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
    sl = _check_step_length(step_length, y.shape[:-1])[..., None]
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
