"""Gyro-only attitude: strapdown integration of the angular rate, no correction (the floor).

Each sample rotates the attitude by the sample's rotation vector, ``q <- q ⊗ exp(w dt)`` (the
exact update for a rate that is constant over the sample interval: the single-sample rotation
vector of P. G. Savage, "Strapdown inertial navigation integration algorithm design, part 1:
attitude algorithms", Journal of Guidance, Control, and Dynamics 21(1), 1998). Nothing corrects
it: the tilt drifts with the gyro bias and noise at ``|bias| t`` (rad), the heading likewise. It
is the floor any fusion filter must beat.

Start and dropouts (the convention of all the reference stages,
:mod:`estimators._attitude_helpers_numba`): the first sample of a (re)set stream whose
accelerometer reading is usable sets the attitude from the accelerometer (tilt) and, when that
sample's magnetometer reading is usable, the field (heading); its gyro reading is not integrated.
Until such a sample arrives the gyro is integrated from the identity. A non-finite gyro sample
holds the attitude.

The per-sample loop is the compiled kernel :data:`gyro_kernel` (one scalar implementation, loop
over users inside; ``gyro_kernel.py_func`` is its readable uncompiled source).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from estimators._attitude_helpers_numba import (
    quat_from_acc,
    quat_from_acc_mag,
    usable3,
)
from estimators._quaternion_stage import QuaternionStage
from estimators.kernels.batch import BatchKernel
from estimators.kernels.rotations import quat_from_rotvec, quat_mul
from estimators.validation import check_bool

__all__ = ["GyroOnly", "GyroOnlyParams", "gyro_kernel"]


@dataclass(frozen=True)
class GyroOnlyParams:
    """Parameters of :class:`GyroOnly`.

    Every field is validated on construction.
    """

    init_from_acc: bool = True
    """Set the attitude of a (re)set stream from its first usable accelerometer (+ magnetometer)
    sample (the convention shared by the reference stages). False: start at the identity and
    only integrate. Default True."""

    def __post_init__(self) -> None:
        check_bool(self, "init_from_acc")

    def build(self, batch_size: int, fs: float) -> GyroOnly:
        """The :class:`GyroOnly` stage with these parameters."""
        return GyroOnly(batch_size, fs, self)


def _gyro_run(q, ready, gyr, acc, mag, dt, init_from_acc, out):
    """Integrate the gyro of B streams over N samples (state ``q`` (B, 4), ``ready`` (B,)
    updated in place; ``out`` (B, N, 4) the attitude after each sample)."""
    for i in numba.prange(gyr.shape[0]):
        qw, qx, qy, qz = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        rdy = ready[i]
        for k in range(gyr.shape[1]):
            ax, ay, az = acc[i, k, 0], acc[i, k, 1], acc[i, k, 2]
            if not rdy and init_from_acc and usable3(ax, ay, az):
                mx, my, mz = mag[i, k, 0], mag[i, k, 1], mag[i, k, 2]
                if usable3(mx, my, mz):
                    qw, qx, qy, qz = quat_from_acc_mag(ax, ay, az, mx, my, mz)
                else:
                    qw, qx, qy, qz = quat_from_acc(ax, ay, az)
                rdy = True
            else:
                gx, gy, gz = gyr[i, k, 0], gyr[i, k, 1], gyr[i, k, 2]
                if math.isfinite(gx) and math.isfinite(gy) and math.isfinite(gz):
                    dw, dx, dy, dz = quat_from_rotvec(gx * dt, gy * dt, gz * dt)
                    qw, qx, qy, qz = quat_mul(qw, qx, qy, qz, dw, dx, dy, dz)
                    n = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
                    qw, qx, qy, qz = qw / n, qx / n, qy / n, qz / n
            out[i, k, 0], out[i, k, 1], out[i, k, 2], out[i, k, 3] = qw, qx, qy, qz
        q[i, 0], q[i, 1], q[i, 2], q[i, 3] = qw, qx, qy, qz
        ready[i] = rdy


#: The compiled kernel: ``gyro_kernel(B)(q, ready, gyr, acc, mag, dt, init_from_acc, out)``.
gyro_kernel = BatchKernel(_gyro_run)


class GyroOnly(QuaternionStage):
    """Gyro integration as an attitude stage (:class:`estimators.stages.AttitudeStage`).

    Args:
        batch_size: B streams (users).
        fs: IMU rate, Hz (one sample every ``1 / fs`` s).
        params: :class:`GyroOnlyParams` (defaults if None).
    """

    name = "gyro_only"
    Params = GyroOnlyParams
    per_user_fields = QuaternionStage.per_user_fields

    def _run(self, gyr: NDArray, acc: NDArray, mag: NDArray, out: NDArray) -> None:
        gyro_kernel(self.batch_size)(
            self.q, self.ready, gyr, acc, mag, self.dt, bool(self.params.init_from_acc), out
        )

    @property
    def quat(self) -> NDArray[np.float64]:
        """(B, 4) current attitude."""
        return self.q.copy()
