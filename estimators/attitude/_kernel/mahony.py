"""Mahony's filter, compiled (:mod:`estimators.attitude.mahony`): the loop over users and
samples, started by the convention of :mod:`~estimators.attitude._kernel.start`, built by
:class:`~estimators.kernels.batch.BatchKernel` (``numba.njit(cache=True)``);
``mahony_kernel.py_func`` is the readable uncompiled source.
"""

from __future__ import annotations

import math

import numba

from estimators.attitude._kernel.start import start_quat, usable3
from estimators.kernels.batch import BatchKernel
from estimators.kernels.rotations import quat_mul, quat_rotate

__all__ = ["mahony_kernel"]


def _mahony_run(q, bias, ready, gyr, acc, mag, dt, kp, ki, out):
    """Run Mahony's filter on B streams over N samples (state ``q`` (B, 4), ``bias`` (B, 3),
    ``ready`` (B,) updated in place; ``out`` (B, N, 4) the attitude after each sample)."""
    for i in numba.prange(gyr.shape[0]):
        qw, qx, qy, qz = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        bx, by, bz = bias[i, 0], bias[i, 1], bias[i, 2]
        rdy = ready[i]
        for k in range(gyr.shape[1]):
            ax, ay, az = acc[i, k, 0], acc[i, k, 1], acc[i, k, 2]
            mx, my, mz = mag[i, k, 0], mag[i, k, 1], mag[i, k, 2]
            acc_ok = usable3(ax, ay, az)
            mag_ok = usable3(mx, my, mz)
            if not rdy and acc_ok:  # start: the attitude of this sample, no filter step
                qw, qx, qy, qz = start_quat(ax, ay, az, mx, my, mz, mag_ok)
                rdy = True
                out[i, k, 0], out[i, k, 1], out[i, k, 2], out[i, k, 3] = qw, qx, qy, qz
                continue
            gx, gy, gz = gyr[i, k, 0], gyr[i, k, 1], gyr[i, k, 2]
            if not (math.isfinite(gx) and math.isfinite(gy) and math.isfinite(gz)):
                gx, gy, gz = 0.0, 0.0, 0.0
            if acc_ok:
                na = math.sqrt(ax * ax + ay * ay + az * az)
                ax, ay, az = ax / na, ay / na, az / na
                # predicted gravity direction in the sensor frame, R(q)^T [0, 0, 1]
                vx, vy, vz = quat_rotate(qw, -qx, -qy, -qz, 0.0, 0.0, 1.0)
                ex, ey, ez = ay * vz - az * vy, az * vx - ax * vz, ax * vy - ay * vx
                if mag_ok:
                    nm = math.sqrt(mx * mx + my * my + mz * mz)
                    mx, my, mz = mx / nm, my / nm, mz / nm
                    hx, hy, hz = quat_rotate(qw, qx, qy, qz, mx, my, mz)  # R(q) m
                    hn = math.sqrt(hx * hx + hy * hy)  # field reference: horizontal on north
                    ux, uy, uz = quat_rotate(qw, -qx, -qy, -qz, 0.0, hn, hz)
                    nu = math.sqrt(ux * ux + uy * uy + uz * uz)
                    ux, uy, uz = ux / nu, uy / nu, uz / nu
                    ex += my * uz - mz * uy
                    ey += mz * ux - mx * uz
                    ez += mx * uy - my * ux
                bx -= ki * ex * dt
                by -= ki * ey * dt
                bz -= ki * ez * dt
                wx, wy, wz = gx - bx + kp * ex, gy - by + kp * ey, gz - bz + kp * ez
            else:
                wx, wy, wz = gx - bx, gy - by, gz - bz
            dw, dx, dy, dz = quat_mul(qw, qx, qy, qz, 0.0, wx, wy, wz)
            qw, qx, qy, qz = (
                qw + 0.5 * dw * dt,
                qx + 0.5 * dx * dt,
                qy + 0.5 * dy * dt,
                qz + 0.5 * dz * dt,
            )
            n = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
            qw, qx, qy, qz = qw / n, qx / n, qy / n, qz / n
            out[i, k, 0], out[i, k, 1], out[i, k, 2], out[i, k, 3] = qw, qx, qy, qz
        q[i, 0], q[i, 1], q[i, 2], q[i, 3] = qw, qx, qy, qz
        bias[i, 0], bias[i, 1], bias[i, 2] = bx, by, bz
        ready[i] = rdy


#: The compiled kernel: ``mahony_kernel(B)(q, bias, ready, gyr, acc, mag, dt, kp, ki, out)``.
mahony_kernel = BatchKernel(_mahony_run)
