"""The hand pipeline's own outputs as hand stages (:data:`estimators.stages.HAND`): ``yao2023``
(its Kalman + median angles) and ``raw`` (its unfiltered eq (1)/(2) angles).

:class:`~estimators.hand.pipeline.HandPipeline` already runs Yao 2023's filter for the
environment, and its state is the pipeline's: these stages report one of its outputs unchanged
and hold no state, so ``reset`` only checks its argument (the pipeline's own reset forgets the
filter).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers, stream_rows
from estimators.hand.params import KINECT_RATE_HZ
from estimators.hand.pipeline import HandFrame, check_hand_frames
from estimators.registry import renamed_attributes
from estimators.validation import check_batch_size, check_rate

__all__ = ["RawHand", "Yao2023Hand"]


class _PipelineOutputHand(TakesUsers):
    """A stateless hand stage that reports one of the pipeline's outputs (a subclass's
    :meth:`update`); its constructor checks the factory's ``(batch_size, fs)`` and takes no
    parameters."""

    per_user_fields = ()  # stateless: dropping users changes only B
    batch_size_field = "batch_size"
    #: What the error for a ``params`` argument adds after "takes no params".
    params_note: ClassVar[str] = ""

    def __init__(self, batch_size: int, fs: float = KINECT_RATE_HZ, params: None = None) -> None:
        who = type(self).__name__
        self.batch_size = check_batch_size(batch_size, who)
        self.fs = check_rate(fs, who=who)
        if params is not None:
            raise ValueError(f"{who}: takes no params{self.params_note}, got {params!r}")

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Nothing to forget (the pipeline holds the filter); ``rows`` is checked."""
        stream_rows(rows, self.batch_size, "rows", unique=False)


class Yao2023Hand(_PipelineOutputHand):
    """Yao 2023's Kalman + median output as a hand stage (:class:`estimators.stages.HandStage`).

    :class:`~estimators.hand.pipeline.HandPipeline` already runs the filter (its state is the
    pipeline's); this stage reports the frames' ``ypr`` and ``valid`` unchanged (copies, bit for
    bit). It holds no state, so :meth:`reset` only checks its argument: the pipeline's own reset
    forgets the filter.

    Args:
        batch_size: B streams (users).
        fs: Kinect frame rate, Hz (checked, not used: the pipeline's
            :class:`~estimators.hand.params.KalmanParams` carry the rate of its filter).
        params: unused; accepted for the factory signature ``(batch_size, fs)`` of
            :data:`estimators.stages.HAND`.
    """

    name = "yao2023"
    per_user_fields = _PipelineOutputHand.per_user_fields  # declared: TakesUsers asks each class
    params_note = " (the pipeline's HandParams)"

    def update(self, frames: HandFrame) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """(B, M, 3) ``frames.ypr`` and (B, M) ``frames.valid``, copied."""
        check_hand_frames(frames, self.batch_size, "Yao2023Hand")
        return np.array(frames.ypr, dtype=np.float64), np.array(frames.valid, dtype=bool)


class RawHand(_PipelineOutputHand):
    """The unfiltered eq (1)/(2) angles as a hand stage: the floor any filter must beat.

    Returns the frames' ``ypr_raw``: this frame's angles where its quaternion was usable, the last
    usable ones held through a dropout (``quat_valid`` False), NaN between a (re)selection and the
    new target's first usable quaternion. ``valid`` is True where a raw estimate of the current
    target exists (the angles are finite): it stays True through a dropout, as the Yao 2023
    stage's does. Stateless; :meth:`reset` only checks its argument.

    Args:
        batch_size: B streams (users).
        fs: Kinect frame rate, Hz (checked, not used).
        params: unused; accepted for the factory signature.
    """

    name = "raw"
    per_user_fields = _PipelineOutputHand.per_user_fields  # declared: TakesUsers asks each class

    def update(self, frames: HandFrame) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """(B, M, 3) ``frames.ypr_raw`` (copied) and (B, M) validity (all three angles finite)."""
        check_hand_frames(frames, self.batch_size, "RawHand")
        ypr = np.array(frames.ypr_raw, dtype=np.float64)
        return ypr, np.isfinite(ypr).all(axis=-1)


#: The earlier name, importable for one release with a deprecation warning.
__getattr__ = renamed_attributes(globals(), {"Seed003Hand": "Yao2023Hand"})
