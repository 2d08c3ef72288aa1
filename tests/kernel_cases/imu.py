"""The head IMU on short streams: every bias recursion, dipoles (at and inside min_distance, one
moving), saturation, quantisation, empty chunks and a reset of one user."""

import dataclasses

import numpy as np

from estimators.rotations import quat_from_ypr
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.imu import HeadImu, MagneticDisturbance, get_imu_spec

_DIPOLES = (
    MagneticDisturbance.with_field_at((1.0, 0.5, 1.5), 20.0, 0.8),
    MagneticDisturbance((0.3, 0.0, 1.6), (0.0, 0.0, 5.0), min_distance=0.2),
    MagneticDisturbance(
        (-1.0, 0.5, 1.0), (0.0, 0.0, 40.0), velocity=(1.0, 0.2, 0.0), moving=(0.02, 0.05)
    ),  # wheeled past during the stream
)
_CHUNKS = (6, 0, 1, 9)


def _specs():
    cm = get_imu_spec("consumer_mems")
    return {
        "ig500n": get_imu_spec("ig500n"),
        # Constant biases (tau = inf) on the accelerometer, random walks on gyro and magnetometer.
        "walks": dataclasses.replace(
            cm,
            accel=dataclasses.replace(cm.accel, bias_tau=float("inf")),
            gyro=dataclasses.replace(cm.gyro, bias_walk=0.01),
            mag=dataclasses.replace(cm.mag, bias_walk=0.2, resolution=0.0),
        ),
        "noiseless_quantised": cm.noiseless(keep_resolution=True),
    }


def _inputs(b: int, n: int):
    t = (np.arange(n) * 0.01)[None, :, None] * (1.0 + 0.3 * np.arange(b))[:, None, None]
    q = quat_from_ypr(np.concatenate([np.sin(t), 0.3 * np.cos(t), -0.2 * t], -1))
    q = q * np.array([1.0, 2.5, 0.3])[:b, None, None]  # not unit: normalised inside
    w = np.concatenate([0.5 * np.cos(t), 0.2 + 0 * t, np.sin(3 * t)], -1)
    w[1, 2:4, 2] = 50.0  # saturates the gyro
    a = np.concatenate([np.cos(t), np.sin(t), 0 * t], -1)
    a[2, 8:10, 0] = -200.0  # saturates the accelerometer
    pos = np.concatenate([0.3 * t, 0 * t, 1.6 + 0 * t], -1)
    pos[0, 3] = _DIPOLES[1].position  # exactly at a dipole
    pos[1, 4] = np.add(_DIPOLES[1].position, [0.05, -0.02, 0.0])  # inside min_distance
    return q, w, a, pos


def _run(spec, dipoles: bool):
    def play():
        b = 3
        imu = HeadImu(
            spec,
            BatchRng.from_seeds([11, 22, 33][:b]),
            rate_hz=250.0,
            disturbances=_DIPOLES if dipoles else (),
        )
        q, w, a, pos = _inputs(b, sum(_CHUNKS))
        out, start = {}, 0
        for i, c in enumerate(_CHUNKS):
            s = slice(start, start + c)
            got = imu.sample(q[:, s], w[:, s], a[:, s], pos[:, s] if dipoles else None)
            for name, x, bias in zip(("acc", "gyr", "mag"), got, imu.last_bias, strict=True):
                out[f"{name}_{i}"] = x
                out[f"bias_{name}_{i}"] = bias
            start += c
            if i == 1:  # a new episode for user 1
                imu.rng.reseed(1, np.random.default_rng(123))
                imu.reset(users=[1])
        out.update(zip(("bias_acc", "bias_gyr", "bias_mag"), imu.bias, strict=True))
        out["soft_iron"] = imu.soft_iron
        return out

    return play


CASES = {f"imu_{name}": _run(spec, dipoles=True) for name, spec in _specs().items()}
CASES["imu_consumer_mems_no_pos"] = _run(get_imu_spec("consumer_mems"), dipoles=False)
