"""Seed 003's experiment 2 on the synthetic Kinect v2, plus what variance alone hides.

1. Static: the user holds the right hand still, turned about the forearm to each of the paper's 11
   angles (-90, 0, 90, -35, -50, -65, -75, 30, 45, 60, 75 deg), 10 repeats of 10 s at 30 Hz. The
   variance of the raw Euler angles (eq 1/2), of the Kalman output and of Kalman + median, and the
   pooled variance reduction per axis, as in Tables 1-4. A One Euro filter (Casiez et al. 2012) is
   the competitor.
2. Moving: the hand sweeps about the forearm at 90 deg/s between -75 and +75 deg. RMSE against the
   true orientation and lag behind it (ms), for raw, Kalman, Kalman + median and One Euro.

Everything runs through the real chain: motion model -> Kinect model (bystanders, ids, tracking
states, noise) -> :class:`estimators.hand.HandPipeline` (target selection, Holt smoothing, eq 1/2,
Kalman, median). Axis names are the paper's (see :mod:`estimators.hand`): its *roll, pitch, yaw*
are our ZYX ``[yaw, pitch, roll]`` columns of the wrist orientation in camera space.

The core of the static experiment on given orientation sequences is
:func:`hand_variance_experiment` (through :class:`estimators.hand.OrientationFilter` alone, with its
:class:`HandVarianceResult` and the Table 4 layout); :func:`static_variance`,
:func:`moving_accuracy` (1 and 2) and :func:`recording_jitter` (a real recording) are the
full-chain runs, and :func:`run_hand_variance` runs them all.

Run: ``vrloco experiment hand-variance --json out/hand_variance.json``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.hand import (
    PAPER_AXIS_NAMES,
    HandParams,
    HandPipeline,
    HoltSmoother,
    OneEuroFilter,
    OneEuroParams,
    OrientationFilter,
    estimate_lag,
    quat_to_euler_paper,
    unwrap_angles,
)
from estimators.io_kinect import read_kinect_csv
from estimators.rotations import angle_diff, quat_from_ypr
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.kinect import KinectSpec, KinectV2
from vrloco_env.user import Intent, MotionParams, MotionRecord, UserMotion

#: Seed 003's 11 static angles (deg), in the order of its Tables 1-3.
PAPER_ANGLES_DEG = (-90, 0, 90, -35, -50, -65, -75, 30, 45, 60, 75)
#: Seed 003 Table 4: variance reduction (%) per axis (roll, pitch, yaw).
PAPER_REDUCTION = {
    "kalman": {"roll": 54.0, "pitch": 40.0, "yaw": 54.0},
    "kalman_median": {"roll": 65.0, "pitch": 54.0, "yaw": 69.0},
}
ONE_EURO = OneEuroParams(rate_hz=30.0, min_cutoff=1.0, beta=1.0)
_WARMUP_FRAMES = 30  # filter start-up left out of the statistics (1 s)


@dataclass
class HandVarianceResult:
    """Seed 003 experiment 2 (Tables 1-4): variances of static hand angles, deg^2.

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
        """Seed 003's Table 4 layout: reduction per paper axis name, Kalman and Kalman + median."""
        lines = ["axis (paper)  Kalman %  Kalman+median %"]
        for i, name in enumerate(PAPER_AXIS_NAMES):
            lines.append(
                f"{name:<13} {self.reduction_kalman[i]:8.1f}  {self.reduction_filtered[i]:15.1f}"
            )
        return "\n".join(lines)


def hand_variance_experiment(
    hand_orientation: ArrayLike, params: HandParams | None = None, warmup_frames: int = 30
) -> HandVarianceResult:
    """Core of seed 003's static-variance experiment (its experiment 2, Tables 1-4).

    The paper holds the hand still at 11 yaw angles (its yaw: our roll, the rotation about the
    bone) and repeats 10 times, comparing the variance of the raw, Kalman and Kalman + median
    angles. Here each trial is a sequence of wrist orientations of a static hand; all A x R trials
    run as one batch through :class:`~estimators.hand.OrientationFilter`, exactly as in the
    pipeline.

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
    flt = OrientationFilter(a * r, params)
    flat = q.reshape(a * r, m, 4)
    out = np.empty((3, a * r, m, 3))
    for t in range(m):
        fr = flt.update(flat[:, t])
        out[0, :, t], out[1, :, t], out[2, :, t] = fr.ypr_raw, fr.ypr_kalman, fr.ypr
    ang = np.rad2deg(unwrap_angles(out[:, :, warmup_frames:], axis=2))
    var = np.nanvar(ang, axis=2, ddof=1).reshape(3, a, r, 3).mean(axis=2)  # (3, A, 3)
    total = var.sum(axis=1)  # (3, 3)
    return HandVarianceResult(
        var_raw=var[0],
        var_kalman=var[1],
        var_filtered=var[2],
        reduction_kalman=100.0 * (1.0 - total[1] / total[0]),
        reduction_filtered=100.0 * (1.0 - total[2] / total[0]),
    )


@dataclass
class _Run:
    truth: np.ndarray  # (B, M, 3) true wrist orientation, our [yaw, pitch, roll] (rad)
    raw: np.ndarray  # (B, M, 3) pipeline output, same order, rad
    kalman: np.ndarray
    kalman_median: np.ndarray
    one_euro: np.ndarray


def _simulate(hand_roll: np.ndarray, roll_rate: np.ndarray | None, seconds: float,
              seed: int) -> _Run:  # fmt: skip
    """Users standing still, hand at ``hand_roll`` (rad, about the forearm), through the chain."""
    b = hand_roll.shape[0]
    params = MotionParams()
    rng = BatchRng([np.random.default_rng([seed, i]) for i in range(b)])
    motion = UserMotion(params, rng)
    motion.reset(hand_ypr=np.stack([np.zeros(b), np.zeros(b), hand_roll], axis=-1))
    kinect = KinectV2(KinectSpec(), rng)
    kinect.reset()
    chunks, frames = [], []
    steps = round(seconds * params.control_rate_hz)
    direction = np.ones(b)
    hand = hand_roll.copy()
    for _ in range(steps):
        rates = np.zeros((b, 3))
        if roll_rate is not None:  # sweep between +-75 deg
            direction = np.where(hand > np.deg2rad(75), -1.0, direction)
            direction = np.where(hand < np.deg2rad(-75), 1.0, direction)
            rates[:, 2] = direction * roll_rate
            hand = hand + rates[:, 2] / params.control_rate_hz
        chunk = motion.advance(Intent(hand_rates=rates))
        chunks.append(chunk)
        frames.append(kinect.capture(chunk.kinect.t, chunk.kinect.joints, chunk.kinect.hand_quat))
    rec = MotionRecord.concatenate(chunks)
    m = rec.kinect.t.size
    pipe = HandPipeline(b)
    euro = OneEuroFilter(b, (3,), ONE_EURO, angular=True)
    out = np.empty((4, b, m, 3))
    truth = np.empty((b, m, 3))
    k = 0
    for fr in frames:
        for j in range(fr.body_id.shape[1]):
            hf = pipe.update(fr.body_id[:, j], fr.body_tracked[:, j], fr.joints[:, j],
                             fr.joint_state[:, j], fr.hand_quat[:, j])  # fmt: skip
            out[0, :, k], out[1, :, k], out[2, :, k] = hf.ypr_raw, hf.ypr_kalman, hf.ypr
            out[3, :, k] = euro.update(hf.ypr_raw)
            truth[:, k] = quat_to_euler_paper(fr.truth.hand_quat[:, j])[..., ::-1]
            k += 1
    return _Run(truth, *out)


def static_variance(repeats: int = 10, seconds: float = 10.0, seed: int = 0) -> dict:
    """Tables 1-4 on the synthetic Kinect: variances (deg^2) and pooled reductions (%)."""
    angles = np.deg2rad(np.repeat(np.asarray(PAPER_ANGLES_DEG, float), repeats))
    run = _simulate(angles, None, seconds, seed)
    series = {"raw": run.raw, "kalman": run.kalman, "kalman_median": run.kalman_median,
              "one_euro": run.one_euro}  # fmt: skip
    var = {}
    for name, x in series.items():
        deg = np.rad2deg(unwrap_angles(x[:, _WARMUP_FRAMES:], axis=1))
        v = np.nanvar(deg, axis=1, ddof=1)  # (A * R, 3)
        var[name] = v.reshape(len(PAPER_ANGLES_DEG), repeats, 3).mean(axis=1)  # (A, 3)
    total = {name: v.sum(axis=0) for name, v in var.items()}
    result: dict = {"angles_deg": list(PAPER_ANGLES_DEG), "repeats": repeats, "seconds": seconds}
    for name in ("kalman", "kalman_median", "one_euro"):
        red = 100.0 * (1.0 - total[name] / total["raw"])
        result[name] = {PAPER_AXIS_NAMES[i]: float(red[i]) for i in range(3)}
    result["variance_deg2"] = {
        name: {PAPER_AXIS_NAMES[i]: [float(a) for a in v[:, i]] for i in range(3)}
        for name, v in var.items()
    }
    result["paper"] = PAPER_REDUCTION
    return result


def moving_accuracy(repeats: int = 10, seconds: float = 10.0, rate_deg_s: float = 90.0,
                    seed: int = 1) -> dict:  # fmt: skip
    """RMSE (deg) against the truth and lag (ms) while the hand sweeps at ``rate_deg_s``."""
    rng = np.random.default_rng(seed)
    start = np.deg2rad(rng.uniform(-60, 60, repeats))
    run = _simulate(start, np.full(repeats, np.deg2rad(rate_deg_s)), seconds, seed)
    truth = run.truth[:, _WARMUP_FRAMES:]
    out = {"rate_deg_s": rate_deg_s, "repeats": repeats}
    for name in ("raw", "kalman", "kalman_median", "one_euro"):
        est = getattr(run, name)[:, _WARMUP_FRAMES:]
        err = np.rad2deg(angle_diff(est, truth))
        rmse = np.sqrt(np.nanmean(err**2, axis=(0, 1)))
        # Lag on the swept axis (our roll column = the rotation about the forearm's frame axis
        # that moves most); measured per repeat on unwrapped angles, then averaged.
        axis = int(np.argmax(np.nanstd(truth, axis=(0, 1))))
        lags = [estimate_lag(unwrap_angles(est[i, :, axis], axis=0),
                             unwrap_angles(truth[i, :, axis], axis=0), 30.0, 0.5)
                for i in range(repeats)]  # fmt: skip
        out[name] = {
            "rmse_deg": {PAPER_AXIS_NAMES[i]: float(rmse[i]) for i in range(3)},
            "lag_ms": float(1e3 * np.mean(lags)),
        }
    return out


#: The real Kinect v2 recording beside the repository (see ../shared/data/README.md).
LABAN_CSV = Path(__file__).resolve().parents[3] / "shared/data/kinect_laban/Ges01_wavehand.csv"


def recording_jitter(path: Path = LABAN_CSV) -> dict | None:
    """Holt smoothing (SDK defaults + 5-frame average) on a real Kinect v2 recording.

    Jitter is the RMS second difference of a joint's path (mm per frame^2); lag the delay of the
    smoothed path behind the raw one. Returns None when the recording is absent.
    """
    if not path.is_file():
        return None
    rec = read_kinect_csv(path)
    holt = HoltSmoother(1, rec.joints.shape[1])
    smooth = np.array([holt.update(rec.joints[None, k], rec.state[None, k])[0]
                       for k in range(rec.t.size)])  # fmt: skip
    out = {"file": path.name, "frames": int(rec.t.size)}
    for name, j in (("wrist_right", 10), ("hand_right", 11)):
        raw, sm = rec.joints[:, j], smooth[:, j]
        jit = [float(np.sqrt(np.nanmean(np.sum(np.diff(a, 2, axis=0) ** 2, axis=-1)))) for a in
               (raw, sm)]  # fmt: skip
        lag = estimate_lag(sm, raw, rec.rate_hz)
        out[name] = {"jitter_raw_mm": 1e3 * jit[0], "jitter_smoothed_mm": 1e3 * jit[1],
                     "lag_ms": float(1e3 * np.max(lag))}  # fmt: skip
    return out


def run_hand_variance(json_path: Path | None = None, repeats: int = 10, seed: int = 0) -> dict:
    """Both experiments; print the table beside the paper's, optionally write JSON."""
    result = static_variance(repeats=repeats, seed=seed)
    result["moving"] = moving_accuracy(repeats=repeats, seed=seed + 1)
    result["real_recording"] = recording_jitter()
    print(format_table(result))
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(result, indent=2))
        print(f"wrote {json_path}")
    return result


def format_table(result: dict) -> str:
    axes = PAPER_AXIS_NAMES
    lines = [
        "Seed 003 experiment 2 on the synthetic Kinect v2 "
        f"({len(result['angles_deg'])} angles x {result['repeats']} repeats x "
        f"{result['seconds']:.0f} s)",
        "variance reduction vs raw (%)   " + "".join(f"{a:>8}" for a in axes),
    ]
    for name, label in (("kalman", "Kalman"), ("kalman_median", "Kalman + median"),
                        ("one_euro", "One Euro")):  # fmt: skip
        ours = "".join(f"{result[name][a]:8.1f}" for a in axes)
        lines.append(f"  {label:<29}{ours}")
        if name in result["paper"]:
            paper = "".join(f"{result['paper'][name][a]:8.1f}" for a in axes)
            lines.append(f"  {'  paper: ' + label:<29}{paper}")
    raw = result["variance_deg2"]["raw"]
    mean_raw = "".join(f"{np.mean(raw[a]):8.2f}" for a in axes)
    lines.append("  raw variance, deg^2 (mean)   " + mean_raw)
    mv = result["moving"]
    lines.append(f"hand sweeping at {mv['rate_deg_s']:.0f} deg/s: RMSE vs truth (deg), lag (ms)")
    for name, label in (("raw", "raw"), ("kalman", "Kalman"), ("kalman_median", "Kalman + median"),
                        ("one_euro", "One Euro")):  # fmt: skip
        r = mv[name]
        lines.append(f"  {label:<29}" + "".join(f"{r['rmse_deg'][a]:8.2f}" for a in axes)
                     + f"   lag {r['lag_ms']:6.0f} ms")  # fmt: skip
    real = result.get("real_recording")
    if real is None:
        lines.append("real Kinect v2 recording (kinect_laban): not found, skipped")
    else:
        lines.append(f"real Kinect v2 recording {real['file']} ({real['frames']} frames), Holt "
                     "smoothing: jitter = RMS 2nd difference")  # fmt: skip
        for name in ("wrist_right", "hand_right"):
            r = real[name]
            lines.append(f"  {name:<12} {r['jitter_raw_mm']:6.1f} -> {r['jitter_smoothed_mm']:5.1f}"
                         f" mm   lag {r['lag_ms']:4.0f} ms")  # fmt: skip
    return "\n".join(lines)
