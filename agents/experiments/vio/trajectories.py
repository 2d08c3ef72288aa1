"""The trajectories of the helmet-tracking paper's experiment (static, rotation, walk: one user each
at 1 kHz, :func:`simulate`, :class:`Trajectory`) with the IMU record of the run's unit, and the
IMU-only strapdown from the true initial pose (:func:`imu_only`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from agents.experiments.vio.metrics import error_series
from agents.experiments.vio.mismatch import Mismatch, Setup, make_setup
from agents.experiments.vio.settings import (
    IMU_RATE_HZ,
    ROTATION_RATE_DEG_S,
    WALK_CADENCE,
    WALK_RADIUS_M,
)
from estimators.head_pose.strapdown import Strapdown
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.imu import HeadImu
from vrloco_env.user import Intent, MotionParams, MotionRecord, UserMotion

__all__ = ["Trajectory", "imu_only", "simulate"]

_STILL_START_S = {"rotation": 2.0, "walk": 1.0}
STRIDE_M = MotionParams().stride_m  # 0.65 m per step overground


@dataclass(frozen=True)
class Trajectory:
    """One user's true head motion and IMU record at 1 kHz (N samples).

    Attributes:
        kind: "static", "rotation" or "walk".
        t: (N,) sample times, s. pos: (N, 3) IMU position, m. quat: (N, 4) body -> world.
        omega: (N, 3) body rate, rad/s. gyr, acc: (N, 3) IMU samples (rad/s, m/s^2), the
            setup's axis error matrices applied.
        gyro_bias, accel_bias: (3,) the turntable calibration: the unit's biases right after its
            reset, as they appear in the samples (through the axis error matrices).
    """

    kind: str
    t: NDArray[np.float64]
    pos: NDArray[np.float64]
    quat: NDArray[np.float64]
    omega: NDArray[np.float64]
    gyr: NDArray[np.float64]
    acc: NDArray[np.float64]
    gyro_bias: NDArray[np.float64]
    accel_bias: NDArray[np.float64]


def _intent(kind: str, t0: float) -> Intent:
    still = t0 < _STILL_START_S.get(kind, 0.0) - 1e-9
    if kind == "static" or still:
        return Intent()
    if kind == "rotation":
        return Intent(turn_rate=np.array([math.radians(ROTATION_RATE_DEG_S)]))
    speed = STRIDE_M * WALK_CADENCE
    return Intent(
        cadence=np.array([WALK_CADENCE]),
        turn_rate=np.array([speed / WALK_RADIUS_M]),
        gesture_amplitude=np.array([[0.15, 0.08, 0.0]]),
        gesture_frequency=np.array([[0.3, 0.5, 0.5]]),
    )


def simulate(kind: str, duration: float, seed: int, setup: Setup | None = None) -> Trajectory:
    """Simulate one trajectory (package docstring) and the IMU record of the setup's unit.

    Args:
        kind: "static", "rotation" or "walk".
        duration: s, in [0.1, 600], rounded to the 0.1 s control step.
        seed: random seed (the motion and the IMU draw from their own streams of it).
        setup: the unit's errors (:func:`make_setup`); None: the datasheet unit without axis
            errors (:meth:`Mismatch.none`).
    """
    kinds = ("static", "rotation", "walk")
    if kind not in kinds:
        raise ValueError(f"kind must be one of {kinds}, got {kind!r}")
    if not (0.1 <= float(duration) <= 600.0):
        raise ValueError(f"duration must be in [0.1, 600] s, got {duration!r}")
    if setup is None:
        setup = make_setup(seed, Mismatch.none())
    key = kinds.index(kind)
    params = MotionParams(imu_rate_hz=IMU_RATE_HZ, overground=(kind == "walk"))
    steps = round(duration * params.control_rate_hz)
    motion = UserMotion(params, BatchRng([np.random.default_rng([seed, key, 0])]))
    base = (0.0, -WALK_RADIUS_M) if kind == "walk" else (0.0, 0.0)
    motion.reset(yaw=0.0, base=base)
    imu = HeadImu(setup.imu_spec, BatchRng([np.random.default_rng([seed, key, 1])]), IMU_RATE_HZ)
    calib = imu.bias
    chunks, gyr, acc = [], [], []
    for k in range(steps):
        chunk = motion.advance(_intent(kind, k / params.control_rate_hz))
        s = imu.sample(chunk.quat, chunk.omega, chunk.acc, chunk.pos)
        chunks.append(chunk)
        gyr.append(s.gyr[0])
        acc.append(s.acc[0])
    rec = MotionRecord.concatenate(chunks)
    mg, ma = setup.gyro_matrix, setup.accel_matrix
    return Trajectory(
        kind=kind,
        t=rec.t,
        pos=rec.pos[0],
        quat=rec.quat[0],
        omega=rec.omega[0],
        gyr=np.concatenate(gyr) @ mg.T,
        acc=np.concatenate(acc) @ ma.T,
        gyro_bias=mg @ calib.gyr[0],
        accel_bias=ma @ calib.acc[0],
    )


def _start_velocity(traj: Trajectory) -> NDArray:
    return (traj.pos[1] - traj.pos[0]) * IMU_RATE_HZ  # ~0: every trajectory starts standing


def imu_only(traj: Trajectory) -> dict:
    """Strapdown from the true initial pose with calibrated samples; drift statistics.

    Returns:
        ``pos_m`` / ``att_deg``: the largest errors over the run; ``pos_end_m`` / ``att_end_deg``
        the final ones; ``pos_at_m`` / ``att_at_deg`` at ``t_at_s`` (each quarter of the run).
    """
    nav = Strapdown(1, IMU_RATE_HZ)
    nav.reset(traj.pos[0], _start_velocity(traj), traj.quat[0], gyr=traj.gyr[0], acc=traj.acc[0])
    out = nav.propagate(
        traj.gyr[None, 1:], traj.acc[None, 1:], gyro_bias=traj.gyro_bias, accel_bias=traj.accel_bias
    )
    p = np.concatenate([traj.pos[:1], out.p[0]])
    q = np.concatenate([traj.quat[:1], out.q[0]])
    ep, ea = error_series(p, q, traj.pos, traj.quat)
    n = traj.t.size
    at = [max(round(n * f) - 1, 0) for f in (0.25, 0.5, 0.75, 1.0)]
    return {
        "pos_m": float(ep.max()),
        "att_deg": float(ea.max()),
        "pos_end_m": float(ep[-1]),
        "att_end_deg": float(ea[-1]),
        "t_at_s": [float(traj.t[i]) for i in at],
        "pos_at_m": [float(ep[i]) for i in at],
        "att_at_deg": [float(ea[i]) for i in at],
        "calibration": {
            "gyro_bias_deg_s": np.rad2deg(traj.gyro_bias).tolist(),
            "accel_bias_m_s2": traj.accel_bias.tolist(),
        },
        "_series": (ep, ea),
    }
