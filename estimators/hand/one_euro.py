"""One Euro filter on the hand pipeline's raw wrist angles: a hand stage (``"one_euro"``).

Source: G. Casiez, N. Roussel, D. Vogel, "1 € Filter: A Simple Speed-based Low-pass Filter for
Noisy Input in Interactive Systems", CHI 2012. A first-order low-pass whose cut-off rises with the
signal's speed, ``fc = min_cutoff + beta |dx_hat|``: strong smoothing at rest, little lag in fast
motion. The filter itself is :class:`estimators.hand.joint_smoothing.OneEuroFilter` in angular mode
(differences wrapped to (-pi, pi], so crossing +-180 deg gives no jump), one filter per angle of
``[yaw, pitch, roll]``; this module only feeds it the pipeline's frames:

* the input is ``ypr_raw`` (eq 1/2, before Yao 2023's Kalman + median);
* a frame whose ``reselected`` is True (a new target user) restarts the stream before the frame,
  so one user's estimate never carries over to another;
* a frame whose ``quat_valid`` is False (a dropout) is not fed: the output holds its last value;
  the first usable frame after the gap is filtered as if one frame had passed (a gap makes the
  speed estimate jump, the cut-off opens and the output catches up quickly);
* the output is NaN, with ``valid`` False, before the stream's first usable frame (after a reset
  or a reselection); ``valid`` is True wherever the stream holds an estimate.

Parameters (:class:`OneEuroHandParams`) were chosen on the synthetic Kinect v2 (the chain of
:mod:`agents.experiments.hand_variance`: motion model -> :class:`vrloco_env.sensors.kinect.KinectV2`
-> :class:`estimators.hand.HandPipeline`) on the experiment's development seeds only, with two
criteria against the raw angles:

* rest: pooled variance reduction per axis, hand held still at Yao 2023's 11 angles about the
  forearm, 5 repeats of 10 s (first 1 s left out), seeds 1 and 2;
* motion: RMSE against the true orientation per axis while the hand sweeps about the forearm at
  90 deg/s between +-75 deg (10 users x 10 s), seeds 101 and 102.

Rule: the largest worst-axis rest reduction (mean of the two seeds) such that the swept axis's
RMSE stays below 0.97 x raw on every development seed (a 3 % margin so that other seeds still
beat raw), over the grid min_cutoff in {0.3, 0.5, 0.7, 1, 1.5, 2, 3, 4, 5, 6} Hz, beta in
{0.5, 1, 2, 5, 10, 15, 20, 25, 30, 40} Hz per rad/s, d_cutoff in {0.15, 0.25, 0.35, 0.5, 1, 2} Hz.
Chosen: min_cutoff 5 Hz, beta 15, d_cutoff 0.25 Hz (development: rest reduction 49.6 / 11.2 /
10.0 % on ``[yaw, pitch, roll]``, swept-axis RMSE at most 0.968 x raw;
``python -m agents.experiments.hand_variance --only one_euro``). The worst axis is a
bending one: the Kinect model's noise about those axes is 95 % slow (correlated over 0.5 s), which
no filter that follows the hand removes; about the forearm, whose noise is mostly white, half of
the variance goes.

Held-out figures (rest and motion, beside Yao 2023's filters and the motion-adaptive Kalman filter
of :mod:`estimators.hand.adaptive`) are those of ``vrloco experiment hand-variance`` (seeds 0 and
1); ``tests/test_estimators/hand/test_hand_stages.py`` checks on other held-out seeds that the
filter beats raw at rest and in motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers, stream_rows
from estimators.hand.joint_smoothing import OneEuroFilter, OneEuroParams
from estimators.hand.pipeline import HandFrame, check_hand_frames
from estimators.validation import check_batch_size, check_in_range, check_rate

__all__ = ["OneEuroHand", "OneEuroHandParams"]


@dataclass(frozen=True)
class OneEuroHandParams:
    """Parameters of :class:`OneEuroHand` (the frame rate comes from the stage's ``fs``).

    Defaults: chosen on development seeds by the rule of the module docstring.
    """

    min_cutoff: float = 5.0
    """Cut-off at rest, Hz, in (0, 30]. Default 5 Hz (module docstring: the tuning rule)."""
    beta: float = 15.0
    """Cut-off rise per unit of filtered speed, Hz per rad/s, in [0, 1000] (15 Hz per rad/s is
    0.26 Hz per deg/s: about 29 Hz at 90 deg/s, where the filter nearly passes the raw angle).
    Default 15 (module docstring)."""
    d_cutoff: float = 0.25
    """Cut-off of the speed estimate's low-pass, Hz, in (0, 30]. Default 0.25 Hz (module
    docstring; lower than the paper's 1 Hz, so that the noise of a still hand opens the
    filter less)."""

    def __post_init__(self) -> None:
        for name, lo, hi, open_lo, unit in (
            ("min_cutoff", 0.0, 30.0, True, "Hz"),
            ("beta", 0.0, 1000.0, False, "Hz per rad/s"),
            ("d_cutoff", 0.0, 30.0, True, "Hz"),
        ):
            check_in_range(self, name, lo, hi, unit, lo_open=open_lo)

    def filter_params(self, fs: float) -> OneEuroParams:
        """The :class:`OneEuroParams` of these parameters at frame rate ``fs`` (Hz)."""
        return OneEuroParams(
            rate_hz=float(fs),
            min_cutoff=float(self.min_cutoff),
            beta=float(self.beta),
            d_cutoff=float(self.d_cutoff),
        )

    def build(self, batch_size: int, fs: float) -> OneEuroHand:
        """The :class:`OneEuroHand` stage with these parameters."""
        return OneEuroHand(batch_size, fs, self)


class OneEuroHand(TakesUsers):
    """One Euro filter on the raw wrist angles, a hand stage (see the module docstring).

    Args:
        batch_size: B streams (users).
        fs: Kinect frame rate, Hz (one frame every ``1 / fs`` s).
        params: :class:`OneEuroHandParams` (defaults if None).
    """

    name = "one_euro"
    per_user_fields = ("_mask",)
    per_user_parts = ("filter",)
    batch_size_field = "batch_size"

    def __init__(
        self, batch_size: int, fs: float = 30.0, params: OneEuroHandParams | None = None
    ) -> None:
        self.batch_size = check_batch_size(batch_size, "OneEuroHand")
        self.fs = check_rate(fs, who="OneEuroHand")
        if params is None:
            params = OneEuroHandParams()
        if not isinstance(params, OneEuroHandParams):
            raise ValueError(f"OneEuroHand: params must be a OneEuroHandParams, got {params!r}")
        self.params = params
        #: The batched filter, (B, 3) angles in angular mode.
        self.filter = OneEuroFilter(
            self.batch_size, (3,), params.filter_params(self.fs), angular=True
        )
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
        m = check_hand_frames(frames, self.batch_size, "OneEuroHand")
        raw = np.asarray(frames.ypr_raw, dtype=np.float64)
        usable = np.asarray(frames.quat_valid, dtype=bool) & np.isfinite(raw).all(axis=-1)
        reselected = np.asarray(frames.reselected, dtype=bool)
        out = np.empty((self.batch_size, m, 3))
        f = self.filter
        for t in range(m):  # frames in order; every user at once
            if reselected[:, t].any():
                f.reset(reselected[:, t])
            x = np.where(usable[:, t, None], raw[:, t], np.nan)
            out[:, t] = f.update(x)
        return out, np.isfinite(out).all(axis=-1)
