"""Step detectors, the cadence estimator and cadence-driven locomotion on short streams.

Each stream steps in bouts (a bout's first step held, then released with the second), stands,
misses samples (NaN specific force, gyro and attitude) and is reset part-way; the chunks have
different lengths.
"""

import numpy as np

from estimators.locomotion.cadence_speed import CadenceSpeed, CadenceSpeedParams
from estimators.rotations import GRAVITY, quat_from_ypr
from estimators.steps import CadenceEstimator, NodRobustSteps, StepDetector, ThresholdSteps

FS = 100.0
CHUNKS = ((0, 1), (1, 130), (130, 260), (260, 420))


def imu_stream(b: int = 3, n: int = 420, seed: int = 5):
    """Specific force (b, n, 3) m/s^2, gyro (b, n, 3) rad/s and attitude (b, n, 4): heel-strike
    bumps at 1.7 steps/s with a pause (two bouts), user 2 nodding, missing samples."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    bump = 3.0 * np.cos(np.pi * 1.7 * t) ** 16
    bump[(t > 1.3) & (t < 2.7)] = 0.0  # stand: the next step starts a new bout
    acc = np.zeros((b, n, 3))
    acc[..., 2] = GRAVITY + bump + rng.normal(0.0, 0.05, (b, n))
    acc[1, :, 2] -= bump * (t > 3.0)  # user 1 stops for good
    gyr = rng.normal(0.0, 0.05, (b, n, 3))
    ypr = np.zeros((b, n, 3))
    ypr[2, :, 1] = 0.5 * np.sin(2.0 * np.pi * 1.0 * t)  # a vigorous nod
    gyr[2, :, 1] += 0.5 * 2.0 * np.pi * np.cos(2.0 * np.pi * 1.0 * t)
    quat = quat_from_ypr(ypr)
    quat[2] *= 1.5  # not unit: normalised by the detector
    acc[0, 50] = np.nan
    gyr[0, 60, 1] = np.nan
    quat[1, 70] = np.nan
    return acc, gyr, quat


def _stage(make):
    def play():
        acc, gyr, quat = imu_stream()
        stage = make(acc.shape[0], FS)
        out = {}
        for k, (a, b) in enumerate(CHUNKS):
            if k == 3:
                stage.reset([1])
            chunk = stage.update(acc[:, a:b], gyr[:, a:b], quat[:, a:b])
            out |= {
                f"state_{k}": chunk.state,
                f"steps_{k}": chunk.steps,
                f"peak_time_{k}": chunk.peak_time,
            }
        return out

    return play


def _zhang2021():
    acc, _, _ = imu_stream()
    det = StepDetector(acc.shape[0], FS)
    out = {}
    for k, (a, b) in enumerate(CHUNKS):
        if k == 3:
            det.reset(np.array([False, True, False]))
        if k % 2:
            chunk = det.update(acc[:, a:b])
        else:  # the norms of the same samples
            chunk = det.update_norm(np.linalg.norm(acc[:, a:b], axis=-1))
        out |= {
            f"state_{k}": chunk.state,
            f"steps_{k}": chunk.steps,
            f"peak_time_{k}": chunk.peak_time,
            f"baseline_{k}": det.baseline,
        }
    return out


def step_counts(n: int = 160, b: int = 3, seed: int = 7):
    """Steps per control step (n, b): bursts, double releases, a long stop and a restart."""
    rng = np.random.default_rng(seed)
    counts = (rng.random((n, b)) < 0.15).astype(float)
    counts[20] = 2.0
    counts[60:110, 1] = 0.0
    return counts


def _cadence():
    counts = step_counts()
    est = CadenceEstimator(counts.shape[1])
    rows = []
    for k, c in enumerate(counts):
        if k == 80:
            est.reset([2])
        rows.append(est.update(c, 0.1))
    return np.stack(rows)


def _cadence_speed():
    counts = step_counts()
    n, b = counts.shape
    yaw = np.cumsum(np.random.default_rng(8).normal(0.0, 0.05, (n, b)), axis=0)
    params = CadenceSpeedParams(cadence_window=3, stop_factor=1.5, ramp_time=0.3)
    loco = CadenceSpeed(b, [0.7, 0.6, 0.8], params, heading=[0.1, 0.0, -2.0])
    out = {"position": [], "speed": [], "cadence": []}
    for k in range(n):
        if k == 100:
            loco.reset(np.array([False, False, True]), position=[1.0, 2.0])
        out["position"].append(loco.update(counts[k], yaw[k], 0.1, np.array([0.0, np.pi, 0.3])))
        out["speed"].append(loco.speed)
        out["cadence"].append(loco.cadence)
    return {k: np.stack(v) for k, v in out.items()}


def _lee2018():
    from estimators import rotations as rot
    from estimators.steps import Lee2018Params, Lee2018Steps

    n, b = 400, 3
    t = np.arange(n)[:, None] / 100.0
    cad = np.array([1.5, 2.0, 0.0])[None, :]
    z = 1.55 - 0.0125 * (1.0 - np.cos(2 * np.pi * cad * t))
    pitch = np.deg2rad(20.0) * np.sin(2 * np.pi * 0.6 * t + np.arange(b))
    q = rot.quat_from_ypr(np.stack([np.zeros((n, b)), pitch, np.zeros((n, b))], -1))
    pos = np.stack([np.zeros((n, b)), np.zeros((n, b)), z], -1) + rot.quat_rotate(
        q, np.array([0.09, 0.0, 0.12])
    )
    pos = pos + np.random.default_rng(4).normal(0.0, 5e-4, pos.shape)
    det = Lee2018Steps(b, 100.0, Lee2018Params(dip_m=0.004))
    acc = np.zeros((b, 20, 3))
    rows = {"state": [], "steps": [], "peak_time": []}
    for k in range(0, n, 20):
        if k == 200:
            det.reset([1])
        out = det.update(
            acc, acc, q[k : k + 20].transpose(1, 0, 2), position=pos[k : k + 20].transpose(1, 0, 2)
        )
        rows["state"].append(out.state)
        rows["steps"].append(out.steps)
        rows["peak_time"].append(np.nan_to_num(out.peak_time, nan=-1.0))
    return {key: np.concatenate(v, axis=1) for key, v in rows.items()}


CASES = {
    "steps_lee2018": _lee2018,
    "steps_threshold": _stage(ThresholdSteps),
    "steps_nod_robust": _stage(NodRobustSteps),
    "steps_zhang2021": _zhang2021,
    "cadence_estimator": _cadence,
    "cadence_speed": _cadence_speed,
}
