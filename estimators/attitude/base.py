"""The stage shell shared by the compiled quaternion filters (Madgwick, Mahony, gyro-only).

Each filter is a scalar kernel over its users (a :class:`~estimators.kernels.batch.BatchKernel`);
this base holds what is the same around it: the checks of the batch size, the rate and the
parameters, the per-user attitude and initialisation flag, ``reset(rows)``, and ``update``
checking the samples and handing them to the subclass's :meth:`QuaternionStage._run`.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers, stream_rows
from estimators.validation import check_batch_size, check_rate, check_samples

__all__ = ["QuaternionStage"]


class QuaternionStage(TakesUsers):
    """Base of an attitude stage whose state is a quaternion per user (``q`` (B, 4), in the
    filter's own earth frame) and a ``ready`` flag (initialised from a first sample).

    Subclasses set ``Params`` (the parameter dataclass), ``name``, optionally ``identity`` (the
    quaternion a reset stream holds) and implement :meth:`_run`; :meth:`_reset_rows` clears
    any further state, which :meth:`_allocate` creates (and lists in ``per_user_fields``, so
    that a batch can drop users: :class:`~estimators.batching.TakesUsers`).
    """

    per_user_fields: ClassVar[tuple[str, ...]] = ("q", "ready")
    batch_size_field = "batch_size"

    Params: ClassVar[type]
    name: ClassVar[str] = ""
    identity: ClassVar[tuple[float, float, float, float]] = (1.0, 0.0, 0.0, 0.0)

    def __init__(self, batch_size: int, fs: float, params: Any = None) -> None:
        who = type(self).__name__
        self.batch_size = check_batch_size(batch_size, who)
        self.fs = check_rate(fs, who=who)
        if params is None:
            params = self.Params()
        if not isinstance(params, self.Params):
            raise ValueError(f"{who}: params must be a {self.Params.__name__}, got {params!r}")
        self.params = params
        self.dt = 1.0 / self.fs
        self.q = np.zeros((self.batch_size, 4))
        self.ready = np.zeros(self.batch_size, dtype=bool)
        self._allocate()
        self.reset()

    def _allocate(self) -> None:
        """Create a subclass's further per-user state arrays (before the first reset)."""

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the streams ``rows`` (indices, a (B,) mask, or None for all): identity attitude,
        re-initialised by their next usable accelerometer sample. Other streams are untouched."""
        r = stream_rows(rows, self.batch_size, "rows", unique=False)
        self.q[r] = self.identity
        self.ready[r] = False
        self._reset_rows(r)

    def _reset_rows(self, rows: NDArray[np.intp]) -> None:
        """Clear a subclass's further per-user state of ``rows``."""

    def update(
        self, gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Consume (B, N, 3) gyro (rad/s), accelerometer (m/s^2) and magnetometer (any unit, or
        None) samples; return the (B, N, 4) attitude ``[w, x, y, z]`` (sensor -> ENU) after each."""
        g, a, m = check_samples(gyr, acc, mag, self.batch_size, type(self).__name__)
        if m is None:
            m = np.full(g.shape, np.nan)
        out = np.empty((g.shape[0], g.shape[1], 4))
        self._run(g, a, m, out)
        return out

    def _run(self, gyr: NDArray, acc: NDArray, mag: NDArray, out: NDArray) -> None:
        """Run the compiled kernel over checked samples, writing ``out`` (B, N, 4)."""
        raise NotImplementedError
