"""Zhang 2021's attitude EKF on three short streams that visit every stage of the kernel.

Stream 0 starts without accelerometer (gyro integration before the initialisation), loses its
gyro for 0.1 s and sees a lasting field change that is rejected, then adopted. Stream 1 starts
upside down (the degenerate tilt initialisation), loses accelerometer and magnetometer, has a gyro
glitch (unit-guard counter) and is reset halfway. Stream 2 is 6D and starts at rest (zero-rate
updates). The three models run (the printed one sees its wrapped roll residual upside down in
stream 1); the streaming and batch entry points both play.
"""

import numpy as np

from estimators.attitude import AttitudeEKF, AttitudeParams, estimate_attitude
from estimators.rotations import (
    GRAVITY,
    quat_conjugate,
    quat_from_ypr,
    quat_multiply,
    quat_rotate_inverse,
    quat_to_rotvec,
)

FS = 100.0
N = 300
BIAS = np.array([0.02, -0.015, 0.01])


def _streams():
    rng = np.random.default_rng(0)
    t = np.arange(N) / FS
    ypr = np.stack(
        [
            np.stack([1.0 + 0.6 * np.sin(1.3 * t), 0.3 * np.sin(1.9 * t), 0.2 * np.sin(t)], -1),
            np.stack([0.5 * t, 0.1 * np.sin(0.6 * t), 0.1 * np.cos(0.8 * t)], -1),
            np.stack([-2.0 + 0.4 * np.sin(t), 0.2 * np.sin(2.0 * t), 0.1 * np.sin(t)], -1),
        ]
    )
    q = quat_from_ypr(ypr)
    w = np.zeros(ypr.shape)
    w[:, 1:] = quat_to_rotvec(quat_multiply(quat_conjugate(q[:, :-1]), q[:, 1:])) * FS
    dip = np.radians(60.0)
    field = 50.0 * np.array([0.0, np.cos(dip), -np.sin(dip)])
    gyr = w + BIAS + rng.normal(0.0, 0.002, w.shape)
    acc = quat_rotate_inverse(q, [0.0, 0.0, GRAVITY]) + rng.normal(0.0, 0.05, w.shape)
    mag = quat_rotate_inverse(q, field) + rng.normal(0.0, 0.3, w.shape)
    acc[0, :3] = np.nan
    gyr[0, 100:110] = np.nan
    mag[0, 150:] *= 1.5
    acc[1, 0] = [0.0, 0.0, -GRAVITY]
    acc[1, 60:80] = np.nan
    mag[1, 90:120] = np.nan
    gyr[1, 200] = 100.0
    mag[2] = np.nan
    gyr[2, :120] = BIAS + rng.normal(0.0, 0.002, (120, 3))
    acc[2, :120] = np.array([0.0, 0.0, GRAVITY]) + rng.normal(0.0, 0.02, (120, 3))
    return gyr, acc, mag


def _ekf(model: str):
    def play():
        gyr, acc, mag = _streams()
        params = AttitudeParams(
            model=model, mag_learn_time=0.2, mag_ok_time=0.1, mag_new_time=1.0, rest_time=0.5
        )
        ekf = AttitudeEKF(3, FS, params)
        out = [ekf.update_batch(gyr[:, :150], acc[:, :150], mag[:, :150])]
        ekf.reset([1])
        out += [ekf.update(gyr[:, k], acc[:, k], mag[:, k])[:, None] for k in range(150, 160)]
        out.append(ekf.update_batch(gyr[:, 160:], acc[:, 160:], mag[:, 160:]))
        state = {name: np.asarray(ekf.state[name]) for name in ekf.state.dtype.names}
        return {"q": np.concatenate(out, axis=1), **state}

    return play


def _offline_6d():
    gyr, acc, _ = _streams()
    return estimate_attitude(gyr[:, :150], acc[:, :150], None, FS, declination=0.2)


CASES = {
    "attitude_ekf_trawny": _ekf("trawny"),
    "attitude_ekf_f_zero": _ekf("f_zero"),
    "attitude_ekf_paper_literal": _ekf("paper_literal"),
    "attitude_ekf_offline_6d": _offline_6d,
}
