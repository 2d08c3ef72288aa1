"""Stage 3 of Yao 2023's hand pipeline on its own: eq (1)/(2), then a Kalman filter per angle,
then a median over consecutive Kalman outputs (section 1.4), for B streams of wrist quaternions or
raw angles (:class:`OrientationFilter`). The model and its parameters are
:class:`~estimators.hand.params.KalmanParams`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers
from estimators.hand._kernel import filter_kernel, new_filter_state
from estimators.hand.angles import paper_angles
from estimators.hand.params import HandParams, kernel_params
from estimators.validation import check_batch_size

__all__ = ["OrientationFilter", "OrientationFrame"]


@dataclass
class OrientationFrame:
    """Output of :class:`OrientationFilter`; angles ``[yaw, pitch, roll]`` in rad.

    Arrays are (B, ...) for :meth:`OrientationFilter.update`, (B, M, ...) for the M-frame calls.

    Attributes:
        ypr_raw: (B, 3) eq (1)/(2) of this frame's quaternion; the last valid value is held on a
            dropout (NaN before the first).
        ypr_kalman: (B, 3) Kalman output, wrapped to (-pi, pi].
        ypr: (B, 3) Kalman + median output (the pipeline's estimate), wrapped.
        quat_valid: (B,) bool, this frame's quaternion (or angles) was used (False: dropout,
            value held).
        singular: (B,) bool, eq (2) was used (|wy - zx| > threshold).
        valid: (B,) bool, the outputs hold an estimate (False before the first valid frame).
    """

    ypr_raw: NDArray[np.float64]
    ypr_kalman: NDArray[np.float64]
    ypr: NDArray[np.float64]
    quat_valid: NDArray[np.bool_]
    singular: NDArray[np.bool_]
    valid: NDArray[np.bool_]


class OrientationFilter(TakesUsers):
    """Eq (1)/(2), then the Kalman filter, then the median, for B streams of wrist quaternions.

    Stage 3 of :class:`HandPipeline` without target selection and joint smoothing, run by the same
    compiled code (:data:`estimators.hand._kernel.filter_kernel` after
    :data:`estimators.hand._kernel.angles_kernel`): fed the target's wrist quaternions, it gives the
    pipeline's ``ypr_raw``, ``ypr_kalman`` and ``ypr`` bit for bit. For recorded or simulated
    orientation sequences (the static-variance experiment of Yao 2023) and for hand stages that
    filter the pipeline's raw angles again with other parameters (:meth:`update_angles`).

    Dropouts -- a NaN or zero-norm quaternion, NaN angles, or ``valid`` False -- are never
    propagated as NaN: the raw angles hold their last value, the Kalman filter coasts (then holds,
    see :class:`KalmanParams`), the median is not fed, and ``quat_valid`` is False. Infinite
    entries are a ValueError. The median runs on the Kalman filter's unwrapped angles, so its
    window never straddles a +-180 deg wrap.

    Args:
        batch_size: number of streams B.
        params: :class:`HandParams` (only ``kalman``, ``median_window`` and
            ``singularity_threshold`` are used here).
    """

    per_user_fields = ("_state", "_pending")  # the kernel's (user, window) state, resets due
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int, params: HandParams | None = None) -> None:
        self.batch_size = check_batch_size(batch_size, "OrientationFilter")
        self.params = params if params is not None else HandParams()
        if not isinstance(self.params, HandParams):
            raise ValueError(f"OrientationFilter: params must be a HandParams, got {self.params!r}")
        self._prm, self._axes = kernel_params(self.params)
        self._state = new_filter_state(self.batch_size, self.params.median_window)
        self._pending = np.zeros(self.batch_size, bool)  # streams to forget before next frame

    @property
    def active(self) -> NDArray[np.bool_]:
        """(B,) bool: the stream's Kalman filter holds an estimate (updated or coasted)."""
        return (self._state[0]["active"] != 0.0) & ~self._pending

    def reset(self, mask: ArrayLike | None = None) -> None:
        """Forget the streams where ``mask`` (B,) is True (all if None), before their next frame."""
        m = np.ones(self.batch_size, bool) if mask is None else np.asarray(mask, dtype=bool)
        if m.shape != (self.batch_size,):
            raise ValueError(f"mask must have shape ({self.batch_size},), got {m.shape}")
        self._pending |= m

    def _flags(self, name: str, value: ArrayLike | None, m: int, default: bool) -> NDArray:
        if value is None:
            return np.full((self.batch_size, m), default)
        v = np.asarray(value, dtype=bool)
        if v.shape != (self.batch_size, m):
            raise ValueError(f"{name} must have shape ({self.batch_size}, {m}), got {v.shape}")
        return v

    def _frames(self, name: str, x: ArrayLike, width: int) -> NDArray[np.float64]:
        """``x`` as (B, M, width) float64 frames (M >= 1, no inf; NaN is a dropout), or a
        ValueError naming ``name``."""
        a = np.asarray(x, dtype=np.float64)
        if a.ndim != 3 or a.shape[0] != self.batch_size or a.shape[2] != width or a.shape[1] < 1:
            raise ValueError(
                f"{name} must have shape ({self.batch_size}, M, {width}) with M >= 1, got {a.shape}"
            )
        if np.isinf(a).any():
            raise ValueError(f"{name} contains infinite entries; use NaN for a dropout")
        return a

    def update_angles(
        self, ypr: ArrayLike, usable: ArrayLike | None = None, restart: ArrayLike | None = None
    ) -> OrientationFrame:
        """Filter M frames of raw angles (the Kalman filter and the median only).

        Args:
            ypr: (B, M, 3) raw ``[yaw, pitch, roll]``, rad (NaN = dropout).
            usable: (B, M) bool, False marks a dropout; None = every frame with finite angles.
            restart: (B, M) bool, forget the stream before that frame (e.g. a new target user).

        Returns:
            :class:`OrientationFrame` of (B, M, ...) arrays; ``singular`` is all False (the
            angles carry no quaternion).
        """
        z = self._frames("ypr", ypr, 3)
        m = z.shape[1]
        ok = self._flags("usable", usable, m, True) & np.isfinite(z).all(axis=-1)
        return self._run(z, ok, self._flags("restart", restart, m, False), np.zeros_like(ok))

    def update_frames(
        self, q: ArrayLike, valid: ArrayLike | None = None, reset: ArrayLike | None = None
    ) -> OrientationFrame:
        """Filter M frames of wrist quaternions: the same numbers as M :meth:`update` calls.

        Args:
            q: (B, M, 4) quaternions ``[w, x, y, z]`` (any norm > 1e-6; NaN or zero = dropout).
            valid: (B, M) bool, False marks a dropout (e.g. no target user); None = all valid.
            reset: (B, M) bool, streams to forget before that frame (e.g. a new target user).

        Returns:
            :class:`OrientationFrame` of (B, M, ...) arrays.
        """
        qa = self._frames("hand_quat", q, 4)
        m = qa.shape[1]
        ypr, usable, singular = paper_angles(qa, self.params.singularity_threshold)
        ok = usable & self._flags("valid", valid, m, True)
        return self._run(ypr, ok, self._flags("reset", reset, m, False), singular & ok)

    def update(
        self, q: ArrayLike, valid: ArrayLike | None = None, reset: ArrayLike | None = None
    ) -> OrientationFrame:
        """Filter one frame of wrist quaternions.

        Args:
            q: (B, 4) quaternions ``[w, x, y, z]`` (any norm > 1e-6; NaN or zero = dropout).
            valid: (B,) bool, False marks a dropout (e.g. no target user); None = all valid.
            reset: (B,) bool, streams to forget before this frame (e.g. a new target user).

        Returns:
            :class:`OrientationFrame` of (B, ...) arrays.
        """
        qa = np.asarray(q, dtype=np.float64)
        if qa.shape != (self.batch_size, 4):
            raise ValueError(f"hand_quat must have shape ({self.batch_size}, 4), got {qa.shape}")
        flags = [None if f is None else np.asarray(f, dtype=bool) for f in (valid, reset)]
        for name, f in zip(("valid", "reset"), flags, strict=True):
            if f is not None and f.shape != (self.batch_size,):
                raise ValueError(f"{name} must have shape ({self.batch_size},), got {f.shape}")
        out = self.update_frames(qa[:, None], *(None if f is None else f[:, None] for f in flags))
        return OrientationFrame(*(getattr(out, f.name)[:, 0] for f in fields(OrientationFrame)))

    def _run(
        self, z: NDArray, ok: NDArray, restart: NDArray, singular: NDArray
    ) -> OrientationFrame:
        """The kernel over (B, M) frames, the pending resets applied before the first."""
        b, m = ok.shape
        restart = restart.copy()
        restart[:, 0] |= self._pending
        self._pending[:] = False
        rows = b * m
        raw, kalman, ypr = np.empty((rows, 3)), np.empty((rows, 3)), np.empty((rows, 3))
        valid = np.empty(rows, bool)
        filter_kernel(b)(
            np.ascontiguousarray(z.reshape(rows, 3)),
            ok.reshape(rows),
            restart.reshape(rows),
            m,
            self._prm,
            self._axes,
            self._state,
            (raw, kalman, ypr, valid),
        )
        return OrientationFrame(
            ypr_raw=raw.reshape(b, m, 3),
            ypr_kalman=kalman.reshape(b, m, 3),
            ypr=ypr.reshape(b, m, 3),
            quat_valid=ok,
            singular=singular,
            valid=valid.reshape(b, m),
        )
