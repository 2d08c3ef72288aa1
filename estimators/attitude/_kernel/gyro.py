"""The gyro-only reference stage's compiled kernel (:mod:`estimators.attitude.gyro`): the
gyro integrated from the start convention of :mod:`~estimators.attitude._kernel.start`, one
scalar loop over users inside, built by :class:`~estimators.kernels.batch.BatchKernel`
(``numba.njit(cache=True)``); ``gyro_kernel.py_func`` is the readable uncompiled source.
"""

from __future__ import annotations

import math

import numba

from estimators.attitude._kernel.start import start_quat, usable3
from estimators.kernels.batch import BatchKernel
from estimators.kernels.rotations import quat_from_rotvec, quat_mul

__all__ = ["gyro_kernel"]


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
                qw, qx, qy, qz = start_quat(ax, ay, az, mx, my, mz, usable3(mx, my, mz))
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
