"""Motion-adaptive Kalman filter on the hand pipeline's raw wrist angles: a hand stage
(``"adaptive_kalman"``).

Yao 2023's Kalman filter (:class:`estimators.hand.KalmanParams`: per angle a constant-rate model
whose process noise grows with the low-passed normalised innovation squared) without the median
behind it, and with its adaptation set for a moving hand as well as a still one: a higher
process noise at rest, an innovation average over one frame and a high cap, so that the filter
opens within a frame when the hand starts, stops or turns back. The median of Yao 2023 is left out
because on a steady rotation a causal median of 3 frames lags a frame (33 ms, 3 deg at 90 deg/s),
more than the whole raw error. The filter runs in the pipeline's own compiled kernel
(:class:`estimators.hand.OrientationFilter` over :data:`estimators.hand._kernel.filter_kernel`);
this module only feeds it the frames:

* the input is ``ypr_raw`` (eq 1/2, before Yao 2023's Kalman + median) where ``quat_valid``;
* a frame whose ``reselected`` is True (a new target user) restarts the stream before the frame,
  so one user's estimate never carries over to another;
* a dropout (``quat_valid`` False) is coasted then held, as Yao 2023's filter does
  (``max_coast_frames``);
* the output is NaN, with ``valid`` False, before the stream's first usable frame (after a reset
  or a reselection).

Parameters (:class:`AdaptiveKalmanHandParams`) were chosen on the synthetic Kinect v2 (the chain of
:mod:`agents.experiments.hand_variance`) on its development seeds only (static trials: seeds 1, 2,
the paper's 11 angles x 5 repeats x 10 s; moving: seeds 101, 102, 10 users sweeping about the
forearm at 90 deg/s for 10 s). Rule: the smallest mean, over the three axes and both kinds of trial,
of the RMSE against the true orientation relative to raw's, among the settings whose every ratio is
below 1 on every development seed; grid ``accel_psd`` in {0.3, 1, 3, 10} rad^2/s^3,
``max_accel_psd`` in {30, 100, 1000}, ``adapt_time`` in {1/30, 0.05, 0.1} s. Chosen: 1, 1000, 1/30 s
(development mean ratio 0.919; the runner-up settings differ by less than 0.001; ``python -m
agents.experiments.hand_variance --only adaptive_kalman``). The held-out figures are those of
``vrloco experiment hand-variance``; ``tests/test_estimators/hand/test_hand_stages.py`` checks on
other held-out seeds that the filter beats raw at rest and in motion on every axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers, stream_rows
from estimators.hand.orientation import OrientationFilter
from estimators.hand.params import HandParams, KalmanParams
from estimators.hand.pipeline import HandFrame, check_hand_frames
from estimators.validation import check_batch_size, check_in_range, check_rate

__all__ = ["AdaptiveKalmanHand", "AdaptiveKalmanHandParams"]


@dataclass(frozen=True)
class AdaptiveKalmanHandParams:
    """Parameters of :class:`AdaptiveKalmanHand` (the frame rate comes from the stage's ``fs``).

    Defaults: chosen on development seeds by the rule of the module docstring; the other fields of
    :class:`~estimators.hand.KalmanParams` keep their defaults.
    """

    accel_psd: float = 1.0
    """Spectral density of the angular acceleration at rest, rad^2/s^3, in (0, 1e4]. Default 1."""
    max_accel_psd: float = 1000.0
    """Cap of the adapted density, rad^2/s^3, in [accel_psd, 1e6]. Default 1000."""
    adapt_time: float = 1.0 / 30.0
    """Time constant of the innovation average that drives the adaptation, s, in (0, 10].
    Default one frame (1/30 s)."""
    measurement_std_deg: float = 2.0
    """Std of the raw angles, deg, in (0, 90]. Default 2 deg, as Yao 2023's filter (its raw
    static variances, Tables 1-3, are typically about 4 deg^2)."""

    def __post_init__(self) -> None:
        check_in_range(self, "accel_psd", 0.0, 1e4, "rad^2/s^3", lo_open=True)
        check_in_range(self, "max_accel_psd", self.accel_psd, 1e6, "rad^2/s^3 (>= accel_psd)")
        check_in_range(self, "adapt_time", 0.0, 10.0, "s", lo_open=True)
        check_in_range(self, "measurement_std_deg", 0.0, 90.0, "deg", lo_open=True)

    def hand_params(self, fs: float) -> HandParams:
        """The :class:`~estimators.hand.HandParams` of the filter at frame rate ``fs`` (Hz): this
        Kalman filter and no median (window 1)."""
        kalman = KalmanParams(
            rate_hz=float(fs),
            measurement_std=float(np.deg2rad(self.measurement_std_deg)),
            accel_psd=float(self.accel_psd),
            max_accel_psd=float(self.max_accel_psd),
            adapt_time=float(self.adapt_time),
        )
        return HandParams(kalman=kalman, median_window=1)

    def build(self, batch_size: int, fs: float) -> AdaptiveKalmanHand:
        """The :class:`AdaptiveKalmanHand` stage with these parameters."""
        return AdaptiveKalmanHand(batch_size, fs, self)


class AdaptiveKalmanHand(TakesUsers):
    """Motion-adaptive Kalman filter on the raw wrist angles, a hand stage (module docstring).

    Args:
        batch_size: B streams (users).
        fs: Kinect frame rate, Hz (one frame every ``1 / fs`` s).
        params: :class:`AdaptiveKalmanHandParams` (defaults if None).
    """

    name = "adaptive_kalman"
    per_user_fields = ("_mask",)
    per_user_parts = ("filter",)
    batch_size_field = "batch_size"

    def __init__(
        self, batch_size: int, fs: float = 30.0, params: AdaptiveKalmanHandParams | None = None
    ) -> None:
        self.batch_size = check_batch_size(batch_size, "AdaptiveKalmanHand")
        self.fs = check_rate(fs, who="AdaptiveKalmanHand")
        if params is None:
            params = AdaptiveKalmanHandParams()
        if not isinstance(params, AdaptiveKalmanHandParams):
            raise ValueError(
                f"AdaptiveKalmanHand: params must be an AdaptiveKalmanHandParams, got {params!r}"
            )
        self.params = params
        #: The compiled filter over (B, M) raw angles.
        self.filter = OrientationFilter(self.batch_size, params.hand_params(self.fs))
        self._mask = np.zeros(self.batch_size, dtype=bool)

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the streams ``rows`` (indices, a (B,) mask, or None for all): their output is
        NaN until their next usable frame."""
        r = stream_rows(rows, self.batch_size, "rows", unique=False)
        self._mask[:] = False
        self._mask[r] = True
        self.filter.reset(self._mask)

    def update(self, frames: HandFrame) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Filter the M frames of one step.

        Args:
            frames: :class:`estimators.hand.HandFrame` stacked over M frames ((B, M, ...)).

        Returns:
            (B, M, 3) filtered ``[yaw, pitch, roll]``, rad in (-pi, pi] (NaN before a stream's
            first usable frame), and (B, M) validity (an estimate exists).
        """
        check_hand_frames(frames, self.batch_size, "AdaptiveKalmanHand")
        out = self.filter.update_angles(frames.ypr_raw, frames.quat_valid, frames.reselected)
        return out.ypr, out.valid
