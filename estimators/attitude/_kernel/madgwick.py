"""Madgwick's filter, compiled (:mod:`estimators.attitude.madgwick`): the gradient of the
misfit of one reference direction (:func:`_misfit_gradient`) and the loop over users and
samples, started by the convention of :mod:`~estimators.attitude._kernel.start`;
``madgwick_kernel.py_func`` is the readable uncompiled source.
"""

from __future__ import annotations

import math

import numba

from estimators.attitude._kernel.start import start_quat, usable3
from estimators.kernels.batch import BatchKernel
from estimators.kernels.rotations import quat_mul, quat_rotate

__all__ = ["madgwick_kernel"]


@numba.njit(cache=True)
def _misfit_gradient(qw, qx, qy, qz, dx, dy, dz, sx, sy, sz):
    """``J^T f`` (tuple of 4) for one reference: ``f = R(q)^T d - s`` and its Jacobian as in
    Madgwick 2010, for a general world direction ``d`` and a unit ``q``."""
    f1 = (
        2.0 * dx * (0.5 - qy * qy - qz * qz)
        + 2.0 * dy * (qw * qz + qx * qy)
        + 2.0 * dz * (qx * qz - qw * qy)
        - sx
    )
    f2 = (
        2.0 * dx * (qx * qy - qw * qz)
        + 2.0 * dy * (0.5 - qx * qx - qz * qz)
        + 2.0 * dz * (qw * qx + qy * qz)
        - sy
    )
    f3 = (
        2.0 * dx * (qw * qy + qx * qz)
        + 2.0 * dy * (qy * qz - qw * qx)
        + 2.0 * dz * (0.5 - qx * qx - qy * qy)
        - sz
    )
    # Rows of J: derivatives of f1, f2, f3 with respect to (qw, qx, qy, qz).
    gw = (
        (2.0 * dy * qz - 2.0 * dz * qy) * f1
        + (-2.0 * dx * qz + 2.0 * dz * qx) * f2
        + (2.0 * dx * qy - 2.0 * dy * qx) * f3
    )
    gx = (
        (2.0 * dy * qy + 2.0 * dz * qz) * f1
        + (2.0 * dx * qy - 4.0 * dy * qx + 2.0 * dz * qw) * f2
        + (2.0 * dx * qz - 2.0 * dy * qw - 4.0 * dz * qx) * f3
    )
    gy = (
        (-4.0 * dx * qy + 2.0 * dy * qx - 2.0 * dz * qw) * f1
        + (2.0 * dx * qx + 2.0 * dz * qz) * f2
        + (2.0 * dx * qw + 2.0 * dy * qz - 4.0 * dz * qy) * f3
    )
    gz = (
        (-4.0 * dx * qz + 2.0 * dy * qw + 2.0 * dz * qx) * f1
        + (-2.0 * dx * qw - 4.0 * dy * qz + 2.0 * dz * qy) * f2
        + (2.0 * dx * qx + 2.0 * dy * qy) * f3
    )
    return gw, gx, gy, gz


def _madgwick_run(q, ready, gyr, acc, mag, dt, beta_imu, beta_marg, out):
    """Run Madgwick's filter on B streams over N samples: state ``q`` (B, 4) in Madgwick's NWU
    world and ``ready`` (B,), updated in place; ``out`` (B, N, 4) the attitude after each
    sample, sensor -> ENU (``r ⊗ q``, r the +90 deg turn about the vertical)."""
    rw = rz = math.sqrt(0.5)  # r = [cos 45 deg, 0, 0, sin 45 deg]: NWU -> ENU
    for i in numba.prange(gyr.shape[0]):
        qw, qx, qy, qz = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        rdy = ready[i]
        for k in range(gyr.shape[1]):
            ax, ay, az = acc[i, k, 0], acc[i, k, 1], acc[i, k, 2]
            mx, my, mz = mag[i, k, 0], mag[i, k, 1], mag[i, k, 2]
            acc_ok = usable3(ax, ay, az)
            mag_ok = usable3(mx, my, mz)
            if not rdy and acc_ok:  # start: the attitude of this sample, no filter step
                ew, ex, ey, ez = start_quat(ax, ay, az, mx, my, mz, mag_ok)
                qw, qx, qy, qz = quat_mul(rw, 0.0, 0.0, -rz, ew, ex, ey, ez)  # ENU -> NWU
                rdy = True
                out[i, k, 0], out[i, k, 1], out[i, k, 2], out[i, k, 3] = ew, ex, ey, ez
                continue
            gx, gy, gz = gyr[i, k, 0], gyr[i, k, 1], gyr[i, k, 2]
            if not (math.isfinite(gx) and math.isfinite(gy) and math.isfinite(gz)):
                gx, gy, gz = 0.0, 0.0, 0.0
            # rate of change from the gyro: qdot = 0.5 q ⊗ [0, w]
            dw, dx, dy, dz = quat_mul(qw, qx, qy, qz, 0.0, gx, gy, gz)
            dw, dx, dy, dz = 0.5 * dw, 0.5 * dx, 0.5 * dy, 0.5 * dz
            if acc_ok:
                na = math.sqrt(ax * ax + ay * ay + az * az)
                ax, ay, az = ax / na, ay / na, az / na
                # gravity: world up [0, 0, 1] against the normalised specific force
                sw, sx, sy, sz = _misfit_gradient(qw, qx, qy, qz, 0.0, 0.0, 1.0, ax, ay, az)
                beta = beta_imu
                if mag_ok:
                    nm = math.sqrt(mx * mx + my * my + mz * mz)
                    mx, my, mz = mx / nm, my / nm, mz / nm
                    # field reference (NWU): b = [|h_xy|, 0, h_z], h = R(q) m
                    hx, hy, hz = quat_rotate(qw, qx, qy, qz, mx, my, mz)
                    bx = math.sqrt(hx * hx + hy * hy)
                    tw, tx, ty, tz = _misfit_gradient(qw, qx, qy, qz, bx, 0.0, hz, mx, my, mz)
                    sw, sx, sy, sz = sw + tw, sx + tx, sy + ty, sz + tz
                    beta = beta_marg
                ng = math.sqrt(sw * sw + sx * sx + sy * sy + sz * sz)
                if ng > 0.0:  # one step along the normalised gradient
                    dw -= beta * sw / ng
                    dx -= beta * sx / ng
                    dy -= beta * sy / ng
                    dz -= beta * sz / ng
            # integrate and normalise
            qw, qx, qy, qz = qw + dw * dt, qx + dx * dt, qy + dy * dt, qz + dz * dt
            n = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
            qw, qx, qy, qz = qw / n, qx / n, qy / n, qz / n
            out[i, k, 0], out[i, k, 1], out[i, k, 2], out[i, k, 3] = quat_mul(
                rw, 0.0, 0.0, rz, qw, qx, qy, qz
            )
        q[i, 0], q[i, 1], q[i, 2], q[i, 3] = qw, qx, qy, qz
        ready[i] = rdy


#: The compiled kernel:
#: ``madgwick_kernel(B)(q, ready, gyr, acc, mag, dt, beta_imu, beta_marg, out)``.
madgwick_kernel = BatchKernel(_madgwick_run)
