"""Steps from the world-vertical specific force, with peaks that head rotation can explain vetoed.

Zhang 2021's detector (:mod:`estimators.steps.zhang2021`) reads the norm ``|f|``: a heel strike
lifts it, but so does any head rotation, because the IMU sits some centimetres from the head's pivot
and turning the head accelerates it (centripetal ``w x (w x r)`` and tangential ``alpha x r``). A
nod of +-30 deg at 1 Hz lifts ``|f|`` by 2.7 m/s^2, four times the detector's gamma, and looking
around quickly (+-70 deg of yaw at 1 Hz) lifts it too. This detector uses the attitude estimate and
the gyro to separate the two:

1. **World vertical.** Each sample of specific force is rotated to the world with the attitude
   quaternion and its vertical component is kept: ``v = (R(q) f)_z``, gravity plus the IMU's
   vertical linear acceleration. Heel strikes are vertical jolts and keep their full height;
   yaw about the vertical (looking left and right) moves the IMU on a horizontal circle and adds
   nothing to ``v``, however fast.
2. **Peaks** of ``v`` exactly as Zhang 2021 finds them in ``|f|``: a mean filter of M samples, a
   running-mean baseline (which absorbs the accelerometer's offset along the vertical), a
   sample that is the maximum of its centred window of 2 h + 1 samples and exceeds the baseline by
   ``gamma``; then Zhang 2021's bout rule (``min_step_interval``, ``gamma_t``, the first peak of a
   bout held until a second confirms it) and still/walk state.
3. **Rotation veto.** Nods and head shakes (rotation about a horizontal axis) do move the IMU
   vertically. For an IMU at any point within ``lever_arm`` of the pivot, the vertical
   acceleration that a head rotation alone can cause is bounded, from ``alpha x r + w x (w x r)``
   with ``|r| <= L``, by

       rot = L (|alpha_h| + |w_h| (|w_h| + |w_z|))

   with ``w`` the angular rate and ``alpha`` the angular acceleration in the world frame, ``_h``
   their horizontal parts and ``w_z`` the vertical one (pure yaw gives 0). ``w`` is the gyro
   rotated to the world and averaged over the mean filter's M samples; ``alpha_h`` is the
   difference of the world rates across that window over its length (the world-frame derivative
   of ``R(q) w`` is ``R(q) dw/dt``). A candidate peak is accepted only if its excess over the
   baseline is larger than the largest ``rot`` in its window: a peak rotation could explain is
   not a step. The bound needs no head model beyond a length; a heel strike during a slow nod
   still counts when it rises above what the nod can add.

Chosen values. Everything of step 2 is :class:`estimators.steps.zhang2021.GaitParams`' defaults
(same reasons; a heel strike lifts ``v`` as much as ``|f|``), so walking is detected as Zhang 2021
detects it. ``lever_arm`` 0.20 m: a stated bound on the distance from the upper neck (the head's
pivot for nods) to a forehead or headset IMU, a little above the 15 cm of the simulated user (9 cm
ahead of and 12 cm above the pivot). It was checked, not fitted, on development seeds 0-2 of
``benchmarks/bench_step_stages.py --dev`` (8 users a trial, both IMU presets, EKF attitude): every
value from 0.15 to 0.4 m keeps walking in place at 1.2-2.2 steps/s, also while scanning the room, at
F1 1.000 and leaves no phantom step in the seven standing gestures; 0.10 m (below the true lever
arm, so the bound no longer holds) keeps about half the phantom steps of the plain world-vertical
detector (``lever_arm=0``), and 0.6 m starts to veto light steps (F1 0.986-0.995). The benchmark's
default run (seeds 1000-1002) and ``tests/test_estimators/steps/test_step_stages.py`` (seeds 2000
and up) report on seeds never used to choose anything.

Limits: the bound assumes the IMU turns about a pivot within ``lever_arm`` of it (a rigid head on
a still neck); a lean of the whole trunk pivots lower and is only partly covered. Attitude error
leaks horizontal acceleration into ``v`` (a 1 deg tilt error leaks 1.7 % of it). The bound is
conservative, so a step taken during a vigorous nod is vetoed with the nod: stepping at 1.7
steps/s while nodding +-30 deg at 1 Hz, the benchmark's held-out F1 is 0.12-0.14 (Zhang 2021's
0.91, which counts the nod's peaks among the steps); a gentle nod (+-15 deg at 0.5 Hz) while
stepping costs nothing (F1 1.000).

Latency: that of Zhang 2021 (``(h + (M - 1)/2) / fs``, 0.135 s at 100 Hz). Non-finite samples: a
specific-force sample or attitude that is not finite takes the previous ``v`` (gravity before
any); a gyro sample or attitude that is not finite takes the previous world rate (zero before
any). The per-sample loop is the compiled kernel
:data:`estimators.steps._kernel.nod_robust_kernel` (loop over streams inside;
``nod_robust_kernel.py_func`` is its readable uncompiled source).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from estimators.batching import TakesUsers, stream_rows
from estimators.kernels import param_record, state_records
from estimators.rotations import GRAVITY
from estimators.stages import GaitChunk
from estimators.steps._kernel import (
    NOD_ROBUST_STATE,
    empty_chunk,
    forget_streams,
    nod_robust_kernel,
)
from estimators.validation import check_chunk, check_in_range, check_stage_args

__all__ = ["NodRobustParams", "NodRobustSteps"]


@dataclass(frozen=True)
class NodRobustParams:
    """Parameters of :class:`NodRobustSteps` (see the module docstring for the choices).

    Every field is validated on construction. The first eight are those of
    :class:`estimators.steps.zhang2021.GaitParams`, applied to the world-vertical specific force.
    """

    gamma: float = 0.07 * GRAVITY
    """Excess (m/s^2) of the smoothed vertical specific force over its baseline a peak needs.
    Default 0.07 g = 0.686 m/s^2, Zhang 2021's gamma."""
    gamma_t: float = 1.2
    """Longest interval (s) between neighbouring steps of one walking bout; a peak with no
    neighbour within it is not a step. Default 1.2 s (Zhang 2021's gamma_t)."""
    min_step_interval: float = 1.0 / 3.5
    """Shortest interval (s) between two steps; closer peaks are ignored. Default 1/3.5 s: nobody
    steps faster than about 3.5 steps/s."""
    mean_window: float = 0.08
    """Length (s) of the mean filter on the vertical specific force and on the world angular rate
    (M = round(mean_window * fs) >= 1 samples). Default 0.08 s, Zhang 2021's."""
    peak_half_window: float = 0.10
    """Half-width (s) of the peak window (h = round(peak_half_window * fs) >= 1; 2 h + 1 samples),
    also the window over which the rotation bound is taken. Default 0.10 s, Zhang 2021's."""
    baseline_tau: float = 4.0
    """Time constant (s) of the running-mean baseline of the vertical specific force (a
    cumulative mean until that much data has been seen); 0 uses ``gravity``. Default 4 s."""
    baseline_limit: float = 0.1 * GRAVITY
    """Largest distance (m/s^2) of the baseline from ``gravity``. Default 0.1 g: covers any
    accelerometer offset (BMI160: +-40 mg typical)."""
    gravity: float = GRAVITY
    """Gravity (m/s^2), standard gravity by default (:data:`estimators.rotations.GRAVITY`)."""
    lever_arm: float = 0.20
    """Bound (m) on the distance from the head's pivot to the IMU, the L of the rotation bound;
    0 turns the veto off (a plain world-vertical detector). Default 0.20 m: see the module
    docstring."""

    def __post_init__(self) -> None:
        check_in_range(self, "gravity", 9.0, 10.5, allowed="in [9, 10.5] m/s^2")
        g = self.gravity
        check_in_range(self, "gamma", 0.0, 3.0 * g, lo_open=True, allowed="in (0, 3 g] m/s^2")
        check_in_range(self, "min_step_interval", 0.0, 2.0, allowed="in [0, 2] s")
        check_in_range(
            self,
            "gamma_t",
            self.min_step_interval,
            10.0,
            lo_open=True,
            allowed="in (min_step_interval, 10] s",
        )
        check_in_range(self, "mean_window", 0.0, 1.0, lo_open=True, allowed="in (0, 1] s")
        check_in_range(self, "peak_half_window", 0.0, 1.0, lo_open=True, allowed="in (0, 1] s")
        check_in_range(self, "baseline_tau", 0.0, 600.0, allowed="in [0, 600] s (0: fixed g)")
        check_in_range(self, "baseline_limit", 0.0, 0.5 * g, allowed="in [0, 0.5 g] m/s^2")
        check_in_range(self, "lever_arm", 0.0, 1.0, allowed="in [0, 1] m (0: no veto)")

    def samples(self, fs: float) -> tuple[int, int]:
        """Mean-filter length M and peak half-window h in samples at rate ``fs`` (Hz)."""
        return max(1, round(self.mean_window * fs)), max(1, round(self.peak_half_window * fs))

    def latency(self, fs: float) -> float:
        """Delay (s) from a heel strike to the sample that confirms it, at rate ``fs`` (Hz)."""
        m, h = self.samples(fs)
        return (h + 0.5 * (m - 1)) / fs

    def build(self, batch_size: int, fs: float) -> NodRobustSteps:
        """The :class:`NodRobustSteps` stage with these parameters."""
        return NodRobustSteps(batch_size, fs, self)


class NodRobustSteps(TakesUsers):
    """Streaming, batched step detector on the world-vertical specific force with a rotation
    veto (see the module docstring).

    Args:
        batch_size: B, the number of streams (users), >= 1.
        fs: sample rate (Hz) of the IMU, in [10, 2000].
        params: :class:`NodRobustParams` (defaults if None).

    :meth:`update` consumes chunks of any length; chunking does not change the result.
    """

    per_user_fields = ("_clock", "_v", "_sm", "_rot", "_w", "_state")  # clocks, rings, state
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int, fs: float, params: NodRobustParams | None = None) -> None:
        self.batch_size, self.fs = check_stage_args(batch_size, fs, "NodRobustSteps")
        self.params = NodRobustParams() if params is None else params
        if not isinstance(self.params, NodRobustParams):
            raise ValueError(
                f"NodRobustSteps: params must be a NodRobustParams, got {type(params).__name__}"
            )
        p = self.params
        self.m, self.h = p.samples(self.fs)
        self.latency = p.latency(self.fs)
        self.report_delay_s = p.gamma_t + self.latency  # a bout's first step waits for the second
        """Delay (s) from a heel strike to the sample that confirms its step."""
        self._prm = param_record(
            p, fs=self.fs, latency=self.latency, base_n=p.baseline_tau * self.fs
        )
        self.samples_seen = 0
        b, w = self.batch_size, 2 * self.h + 1
        self._clock = np.zeros(b, np.int64)  # samples since each stream's reset
        self._v = np.zeros((b, self.m))
        self._sm = np.zeros((b, w))
        self._rot = np.zeros((b, w))
        self._w = np.zeros((b, self.m + 1, 3))
        self._state = state_records(NOD_ROBUST_STATE, b)
        self.reset()

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the streams ``rows`` (indices, a (B,) bool mask, or None: all); their clocks
        restart, so their peak times count from the reset."""
        sel = stream_rows(rows, self.batch_size, "rows")
        forget_streams(self._state, self._clock, sel, self.params.gravity)

    def update(self, acc: ArrayLike, gyr: ArrayLike, quat: ArrayLike) -> GaitChunk:
        """Consume (B, N, 3) specific force (m/s^2), (B, N, 3) angular rate (rad/s) and (B, N, 4)
        attitude ``[w, x, y, z]`` sensor -> ENU; return the
        :class:`estimators.stages.GaitChunk` of the N samples."""
        a, g, q = check_chunk(acc, gyr, quat, self.batch_size, "NodRobustSteps")
        n = a.shape[1]
        out = empty_chunk(self.batch_size, n)
        nod_robust_kernel(self.batch_size)(
            a, g, q, self._clock, self._prm, self._state, self._v, self._sm, self._rot, self._w, out
        )
        state, steps, peak_t = out
        t = (self.samples_seen + np.arange(n)) / self.fs
        self.samples_seen += n
        self._clock += n
        return GaitChunk(state=state, steps=steps, peak_time=peak_t, sample_time=t)
