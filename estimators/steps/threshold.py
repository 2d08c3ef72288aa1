"""A naive step detector: every local maximum of the raw specific-force norm above g + threshold.

The baseline of :data:`estimators.stages.STEPS` (``"threshold"``): the simplest pedometer rule, a
step at each sample ``k - 1`` where the unfiltered norm ``x = |f|`` has a local maximum,

    x[k-2] < x[k-1] >= x[k]   and   x[k-1] > gravity + threshold,

unless it comes less than ``refractory`` seconds after the previous step. Nothing else: no
smoothing, no peak window, no baseline (a fixed g, so an accelerometer offset along gravity shifts
the threshold), no rule that a step needs a neighbour, and no use of the gyro or the attitude.

Values (a stated rule, not tuned): ``threshold`` is Zhang 2021's gamma (0.07 g) and ``refractory``
its shortest step interval (1/3.5 s, about the fastest human stepping), so that this detector
differs from :class:`estimators.steps.zhang2021.Zhang2021Steps` only by what it leaves out. A step
is confirmed one sample after its peak (``latency = 1 / fs``) and carries the peak's time.
Still/walk: walk while the last step is at most ``hold`` seconds old (Zhang 2021's gamma_t, 1.2 s),
still otherwise.

A non-finite sample takes the previous sample's norm (gravity before any). The per-sample loop is
the compiled kernel :data:`estimators.steps._kernel.threshold_kernel` (loop over streams inside;
``threshold_kernel.py_func`` is its readable uncompiled source).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from estimators.batching import TakesUsers, stream_rows
from estimators.kernels import param_record, state_records
from estimators.rotations import GRAVITY
from estimators.stages import GaitChunk
from estimators.steps._kernel import THRESHOLD_STATE, empty_chunk, threshold_kernel
from estimators.validation import check_chunk, check_in_range, check_stage_args

__all__ = [
    "ThresholdParams",
    "ThresholdSteps",
]


@dataclass(frozen=True)
class ThresholdParams:
    """Parameters of :class:`ThresholdSteps` (see the module docstring for the rule).

    Every field is validated on construction.
    """

    threshold: float = 0.07 * GRAVITY
    """Excess of the raw norm over ``gravity`` (m/s^2) a peak needs. Default 0.07 g = 0.686
    m/s^2, Zhang 2021's gamma (:class:`estimators.steps.zhang2021.GaitParams`)."""
    refractory: float = 1.0 / 3.5
    """Shortest interval (s) between two steps; a peak sooner after the last step is ignored.
    Default 1/3.5 s: nobody steps faster than about 3.5 steps/s (Zhang 2021's min_step_interval)."""
    hold: float = 1.2
    """How long (s) the state stays 'walk' after a step. Default 1.2 s, Zhang 2021's gamma_t (20 %
    above the slowest in-place step interval, 1 s)."""
    gravity: float = GRAVITY
    """Gravity (m/s^2), standard gravity by default (:data:`estimators.rotations.GRAVITY`)."""

    def __post_init__(self) -> None:
        check_in_range(self, "gravity", 9.0, 10.5, allowed="in [9, 10.5] m/s^2")
        check_in_range(
            self, "threshold", 0.0, 3.0 * self.gravity, lo_open=True, allowed="in (0, 3 g] m/s^2"
        )
        check_in_range(self, "refractory", 0.0, 2.0, allowed="in [0, 2] s")
        check_in_range(self, "hold", 0.0, 10.0, lo_open=True, allowed="in (0, 10] s")

    def build(self, batch_size: int, fs: float) -> ThresholdSteps:
        """The :class:`ThresholdSteps` stage with these parameters."""
        return ThresholdSteps(batch_size, fs, self)


class ThresholdSteps(TakesUsers):
    """Streaming, batched naive peak picker on ``|f|`` (see the module docstring).

    Args:
        batch_size: B, the number of streams (users), >= 1.
        fs: sample rate (Hz) of the IMU, in [10, 2000].
        params: :class:`ThresholdParams` (defaults if None).

    :meth:`update` consumes chunks of any length (chunking does not change the result); ``gyr``
    and ``quat`` are not read.
    """

    per_user_fields = ("_clock", "_state")
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int, fs: float, params: ThresholdParams | None = None) -> None:
        self.batch_size, self.fs = check_stage_args(batch_size, fs, "ThresholdSteps")
        self.params = ThresholdParams() if params is None else params
        if not isinstance(self.params, ThresholdParams):
            raise ValueError(
                f"ThresholdSteps: params must be a ThresholdParams, got {type(params).__name__}"
            )
        p = self.params
        self._prm = param_record(p, fs=self.fs, level=p.gravity + p.threshold)
        self.latency = 1.0 / self.fs
        self.report_delay_s = self.latency  # every peak is reported one sample after it
        """Delay (s) from a peak to the sample that confirms its step."""
        self.samples_seen = 0
        self._clock = np.zeros(self.batch_size, np.int64)  # samples since each stream's reset
        self._state = state_records(THRESHOLD_STATE, self.batch_size)
        self.reset()

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the streams ``rows`` (indices, a (B,) bool mask, or None: all); their clocks
        restart, so their peak times count from the reset."""
        sel = stream_rows(rows, self.batch_size, "rows")
        self._clock[sel] = 0
        st = self._state
        st["prev2"][sel] = self.params.gravity
        st["prev1"][sel] = self.params.gravity
        st["last_step"][sel] = -np.inf
        st["n_seen"][sel] = 0.0

    def update(self, acc: ArrayLike, gyr: ArrayLike, quat: ArrayLike) -> GaitChunk:
        """Consume (B, N, 3) specific force (m/s^2), (B, N, 3) angular rate and (B, N, 4)
        attitude; return the :class:`estimators.stages.GaitChunk` of the N samples."""
        a, _, _ = check_chunk(acc, gyr, quat, self.batch_size, "ThresholdSteps")
        n = a.shape[1]
        out = empty_chunk(self.batch_size, n)
        threshold_kernel(self.batch_size)(a, self._clock, self._prm, self._state, out)
        state, steps, peak_t = out
        t = (self.samples_seen + np.arange(n)) / self.fs
        self.samples_seen += n
        self._clock += n
        return GaitChunk(state=state, steps=steps, peak_time=peak_t, sample_time=t)
