"""A Lee-2018-style step detector: steps from the dips of the headset's tracked height.

Lee, Ahn & Hwang ("A walking-in-place method for virtual reality using position and orientation
tracking", Sensors 18(9), 2832, 2018) detect walking in place from the position and orientation
tracking of a PC headset instead of its IMU: each step lowers the head, and the head's pitch,
which also moves the headset up and down, is compensated with the orientation. They report 99.32 %
of steps detected whatever the head's tilt. This detector follows that recipe; its thresholds are
choices stated below, not the paper's (whose full text was not read here).

Per stream, per sample: the neck pivot's height is the headset's height less the headset's
offset from the pivot turned by the attitude (so that tilting the head does not move it); a
baseline follows it with a time constant of ``baseline_s``. A dip starts when the pivot is
``dip_m`` below the baseline and ends when it is back within ``dip_m / 2``; its deepest point is a
step (the step's time), unless it comes less than ``min_interval_s`` after the last step. The
state is 'walk' while the last step is at most ``hold_s`` old: the hold after each step that
walking-in-place drivers keep moving for.

``uses_position = True``: the environment passes ``position=`` (the (B, N, 3) tracked headset
position, m, z up) to :meth:`Lee2018Steps.update`. The accelerometer and gyro are not read.

The per-sample loop is the compiled kernel :data:`estimators.steps._kernel.lee2018_kernel` (its
``py_func`` is the readable reference).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from estimators.batching import TakesUsers, stream_rows
from estimators.kernels import param_record, state_records
from estimators.stages import GaitChunk
from estimators.steps._kernel import LEE2018_STATE, empty_chunk, lee2018_kernel
from estimators.validation import check_chunk, check_in_range, check_numbers, check_stage_args

__all__ = ["Lee2018Params", "Lee2018Steps"]


@dataclass(frozen=True)
class Lee2018Params:
    """Parameters of :class:`Lee2018Steps`; every field is validated on construction."""

    dip_m: float = 0.005
    """How far (m) the neck pivot must drop below its baseline to start a step, in (0, 0.2].
    A choice: a quarter of the 2-3 cm peak-to-peak head bob of stepping in place (the motion
    model's, from the impact-driven bob), well above the tracking noise (sub-millimetre)."""
    baseline_s: float = 1.0
    """Time constant (s) of the standing baseline, in [0.1, 30]. A choice: two strides, so that
    it follows a slow squat or a change of posture but not a step."""
    min_interval_s: float = 1.0 / 3.5
    """Shortest interval (s) between two steps, in [0, 2]: a valid step interval, as Zhang
    2021's (nobody steps faster than about 3.5 steps/s)."""
    hold_s: float = 0.28
    """How long (s) the state stays 'walk' after a step, in (0, 5]. Default 0.28 s: the hold after
    each step of a Lee-2018-style implementation in OpenVR-WalkInPlace, as its maintainer reports
    it (a practitioner's figure)."""
    neck_to_headset_m: tuple[float, float, float] = (0.0805, 0.0, 0.075)
    """The headset's offset from the neck pivot in the head frame (x forward, y left, z up; m).
    Default: the Oculus SDK's default neck model (eyes 0.0805 m ahead of and 0.075 m above the
    pivot), what an implementation that knows no user's neck would use."""

    def __post_init__(self) -> None:
        check_in_range(self, "dip_m", 0.0, 0.2, "m", lo_open=True)
        check_in_range(self, "baseline_s", 0.1, 30.0, "s")
        check_in_range(self, "min_interval_s", 0.0, 2.0, "s")
        check_in_range(self, "hold_s", 0.0, 5.0, "s", lo_open=True)
        check_numbers(self, "neck_to_headset_m", -0.5, 0.5, "m", length=3)

    def build(self, batch_size: int, fs: float) -> Lee2018Steps:
        """The :class:`Lee2018Steps` stage with these parameters."""
        return Lee2018Steps(batch_size, fs, self)


class Lee2018Steps(TakesUsers):
    """Streaming, batched steps from the headset's tracked height (see the module docstring).

    Args:
        batch_size: B, the number of streams (users), >= 1.
        fs: sample rate (Hz) of the tracking, in [10, 2000].
        params: :class:`Lee2018Params` (defaults if None).
    """

    name = "lee2018"
    uses_position = True
    per_user_fields = ("_clock", "_state")
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int, fs: float, params: Lee2018Params | None = None) -> None:
        self.batch_size, self.fs = check_stage_args(batch_size, fs, "Lee2018Steps")
        self.params = Lee2018Params() if params is None else params
        if not isinstance(self.params, Lee2018Params):
            raise ValueError(
                f"Lee2018Steps: params must be a Lee2018Params, got {type(params).__name__}"
            )
        p = self.params
        ox, oy, oz = p.neck_to_headset_m
        self._prm = param_record(p, fs=self.fs, off_x=ox, off_y=oy, off_z=oz)
        self.samples_seen = 0
        self._clock = np.zeros(self.batch_size, np.int64)
        self._state = state_records(LEE2018_STATE, self.batch_size)
        self.report_delay_s = 0.5
        """The longest delay (s) from a dip's deepest point to the sample that ends the dip and
        reports its step: the rise back, under half a step interval of the slowest stepping."""
        self.reset()

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the streams ``rows`` (indices, a (B,) bool mask, or None: all)."""
        sel = stream_rows(rows, self.batch_size, "rows")
        self._clock[sel] = 0
        st = self._state
        st[sel] = 0.0
        st["last_step"][sel] = -np.inf

    def update(
        self, acc: ArrayLike, gyr: ArrayLike, quat: ArrayLike, position: ArrayLike | None = None
    ) -> GaitChunk:
        """Consume (B, N, 3) specific force and angular rate (not read), (B, N, 4) attitude and
        ``position`` (B, N, 3), the tracked headset position (m, z up); return the
        :class:`estimators.stages.GaitChunk` of the N samples."""
        _, _, q = check_chunk(acc, gyr, quat, self.batch_size, "Lee2018Steps")
        if position is None:
            raise ValueError("Lee2018Steps.update needs position= (the tracked headset position)")
        pos = np.ascontiguousarray(position, dtype=np.float64)
        if pos.shape != (*q.shape[:2], 3):
            raise ValueError(
                f"Lee2018Steps.update: position must have shape {(*q.shape[:2], 3)}, got "
                f"{pos.shape}"
            )
        n = q.shape[1]
        out = empty_chunk(self.batch_size, n)
        lee2018_kernel(self.batch_size)(pos, q, self._clock, self._prm, self._state, out)
        state, steps, peak_t = out
        t = (self.samples_seen + np.arange(n)) / self.fs
        self.samples_seen += n
        self._clock += n
        return GaitChunk(state=state, steps=steps, peak_time=peak_t, sample_time=t)
