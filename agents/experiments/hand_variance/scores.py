"""The scores of :mod:`agents.experiments.hand_variance`: the variance reduction of Yao
2023's Tables 1-4 on given orientation sequences (:func:`hand_variance_experiment`), and per
filter on a trial the pooled variance reduction and RMSE at rest (:func:`static_scores`) or the
RMSE and lag in motion (:func:`moving_scores`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from agents.experiments.hand_variance.settings import _FS, _WARMUP_FRAMES, PAPER_ANGLES_DEG
from agents.experiments.hand_variance.trials import HandTrial
from estimators.hand import (
    PAPER_AXIS_NAMES,
    HandParams,
    OrientationFilter,
    estimate_lag,
    unwrap_angles,
)
from estimators.rotations import angle_diff, quat_from_ypr

__all__ = ["HandVarianceResult", "hand_variance_experiment", "moving_scores", "static_scores"]


@dataclass
class HandVarianceResult:
    """Yao 2023 experiment 2 (Tables 1-4): variances of static hand angles, deg^2.

    Columns are our ``[yaw, pitch, roll]`` = the paper's *Roll, Pitch, Yaw* (see
    :data:`PAPER_AXIS_NAMES`).

    Attributes:
        var_raw: (A, 3) raw (eq 1/2) variance per static pose, mean over repeats, deg^2.
        var_kalman: (A, 3) after the Kalman filter, deg^2.
        var_filtered: (A, 3) after Kalman + median, deg^2.
        reduction_kalman: (3,) variance reduction of the Kalman filter, %, pooled over poses
            (``100 (1 - sum var_kalman / sum var_raw)``).
        reduction_filtered: (3,) variance reduction of Kalman + median, %, pooled.
    """

    var_raw: NDArray[np.float64]
    var_kalman: NDArray[np.float64]
    var_filtered: NDArray[np.float64]
    reduction_kalman: NDArray[np.float64]
    reduction_filtered: NDArray[np.float64]

    def table(self) -> str:
        """Yao 2023's Table 4 layout: reduction per paper axis name, Kalman and Kalman + median."""
        lines = ["axis (paper)  Kalman %  Kalman+median %"]
        for i, name in enumerate(PAPER_AXIS_NAMES):
            lines.append(
                f"{name:<13} {self.reduction_kalman[i]:8.1f}  {self.reduction_filtered[i]:15.1f}"
            )
        return "\n".join(lines)


def _pooled_variance(ypr: NDArray[np.float64], poses: int) -> NDArray[np.float64]:
    """(poses, 3) variance (deg^2) per pose, mean over its repeats, of (poses * R, M, 3) angles
    (rad; unwrapped along time first, so a pose at +-180 deg is not inflated)."""
    deg = np.rad2deg(unwrap_angles(ypr, axis=1))
    var = np.nanvar(deg, axis=1, ddof=1)
    return var.reshape(poses, -1, 3).mean(axis=1)


def hand_variance_experiment(
    hand_orientation: ArrayLike, params: HandParams | None = None, warmup_frames: int = 30
) -> HandVarianceResult:
    """Core of Yao 2023's static-variance experiment (its experiment 2, Tables 1-4).

    The paper holds the hand still at 11 yaw angles (its yaw: our roll, the rotation about the
    bone) and repeats 10 times, comparing the variance of the raw, Kalman and Kalman + median
    angles. Here each trial is a sequence of wrist orientations of a static hand; all A x R trials
    run as one batch through :class:`~estimators.hand.OrientationFilter`, the pipeline's compiled
    stage 3.

    How the paper pools its 11 angles into Table 4 is not stated; the pooled ratio
    ``1 - sum(var_filtered) / sum(var_raw)`` reproduces its Roll figure from Table 1 (65 %), so
    we use it. Variances use unwrapped angles, so a pose at +-180 deg is not inflated.

    Args:
        hand_orientation: (A, R, M, 4) wrist quaternions ``[w, x, y, z]``, or (A, R, M, 3) raw
            ``[yaw, pitch, roll]`` in rad (converted to quaternions first): A static poses x R
            repeats x M frames at ``params.kalman.rate_hz``.
        params: :class:`~estimators.hand.HandParams`.
        warmup_frames: first frames of each trial left out of the variances (filter start-up).

    Returns:
        :class:`HandVarianceResult`.
    """
    q = np.asarray(hand_orientation, dtype=np.float64)
    if q.ndim != 4 or q.shape[-1] not in (3, 4):
        raise ValueError(
            f"hand_orientation must have shape (A, R, M, 4) or (A, R, M, 3), got {q.shape}"
        )
    if q.shape[-1] == 3:
        q = quat_from_ypr(q)
    a, r, m, _ = q.shape
    if not 0 <= warmup_frames < m - 1:
        raise ValueError(f"warmup_frames must be in [0, {m - 1}), got {warmup_frames}")
    out = OrientationFilter(a * r, params).update_frames(q.reshape(a * r, m, 4))
    var = [
        _pooled_variance(x[:, warmup_frames:], a) for x in (out.ypr_raw, out.ypr_kalman, out.ypr)
    ]
    total = [v.sum(axis=0) for v in var]
    return HandVarianceResult(
        var_raw=var[0],
        var_kalman=var[1],
        var_filtered=var[2],
        reduction_kalman=100.0 * (1.0 - total[1] / total[0]),
        reduction_filtered=100.0 * (1.0 - total[2] / total[0]),
    )


def _rmse_deg(est: NDArray, truth: NDArray) -> NDArray[np.float64]:
    """(3,) RMSE (deg) over users and frames after the warm-up."""
    err = np.rad2deg(angle_diff(est[:, _WARMUP_FRAMES:], truth[:, _WARMUP_FRAMES:]))
    return np.sqrt(np.nanmean(err**2, axis=(0, 1)))


def static_scores(trial: HandTrial, outputs: dict[str, NDArray]) -> dict:
    """Pooled variance reduction (%) and RMSE at rest (deg) per filter; variances per pose."""
    poses = len(PAPER_ANGLES_DEG)
    var = {n: _pooled_variance(x[:, _WARMUP_FRAMES:], poses) for n, x in outputs.items()}
    total = {n: v.sum(axis=0) for n, v in var.items()}
    res: dict = {"reduction_pct": {}, "rmse_deg": {}}
    for name, x in outputs.items():
        red = 100.0 * (1.0 - total[name] / total["raw"])
        rmse = _rmse_deg(x, trial.truth)
        res["reduction_pct"][name] = {PAPER_AXIS_NAMES[i]: float(red[i]) for i in range(3)}
        res["rmse_deg"][name] = {PAPER_AXIS_NAMES[i]: float(rmse[i]) for i in range(3)}
    res["variance_deg2"] = {
        name: {PAPER_AXIS_NAMES[i]: [float(a) for a in v[:, i]] for i in range(3)}
        for name, v in var.items()
    }
    return res


def moving_scores(trial: HandTrial, outputs: dict[str, NDArray]) -> dict:
    """RMSE (deg) per axis and lag (ms) on the swept axis, per filter."""
    truth = trial.truth[:, _WARMUP_FRAMES:]
    axis = int(np.argmax(np.nanstd(truth, axis=(0, 1))))  # the swept one (paper's roll)
    res: dict = {"swept_axis": PAPER_AXIS_NAMES[axis]}
    for name, x in outputs.items():
        rmse = _rmse_deg(x, trial.truth)
        est = x[:, _WARMUP_FRAMES:]
        lags = [
            estimate_lag(
                unwrap_angles(est[i, :, axis], axis=0),
                unwrap_angles(truth[i, :, axis], axis=0),
                _FS,
                0.5,
            )
            for i in range(est.shape[0])
        ]  # a loop over users of a metric
        res[name] = {
            "rmse_deg": {PAPER_AXIS_NAMES[i]: float(rmse[i]) for i in range(3)},
            "lag_ms": float(1e3 * np.mean(lags)),
        }
    return res
