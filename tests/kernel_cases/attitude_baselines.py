"""Madgwick, Mahony and gyro integration on a short stream with rests, motion, gaps and NaN."""

import numpy as np

from estimators.stages import ATTITUDE


def _stream(seed: int, b: int = 3, n: int = 120):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    gyr = rng.normal(0.0, 0.3, (b, n, 3))
    acc = np.array([0.0, 0.0, 9.81]) + rng.normal(0.0, 0.4, (b, n, 3))
    mag = np.array([20.0, 0.0, -40.0]) + rng.normal(0.0, 1.0, (b, n, 3))
    gyr[0, 40:60] = 0.0  # a rest
    acc[1, 30] = np.nan  # a missing accelerometer sample
    mag[2, 70:80] = np.nan  # the magnetometer drops out
    return t, gyr, acc, mag


def _run(name: str):
    def play():
        t, gyr, acc, mag = _stream(len(name))
        stage = ATTITUDE.build(name, gyr.shape[0], 100.0)
        out = [
            stage.update(gyr[:, i : i + 10], acc[:, i : i + 10], mag[:, i : i + 10])
            for i in range(0, t.size, 10)
        ]
        return np.concatenate([np.asarray(o, dtype=np.float64).ravel() for o in out])

    return play


CASES = {f"attitude_{name}": _run(name) for name in ("madgwick", "mahony", "gyro_only")}
