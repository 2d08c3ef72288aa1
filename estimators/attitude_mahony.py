"""Mahony's explicit complementary filter with gyro-bias estimation (a PI filter on SO(3)).

Source: R. Mahony, T. Hamel, J.-M. Pflimlin, "Nonlinear complementary filters on the special
orthogonal group", IEEE Transactions on Automatic Control 53(5):1203-1218, 2008 (the explicit
complementary filter with bias correction, in its quaternion form).

Per sample, with ``q`` the attitude (sensor -> ENU world), ``w`` the gyro reading (rad/s) and
``b`` the bias estimate (rad/s):

1. Predicted directions in the sensor frame: gravity ``v_a = R(q)^T [0, 0, 1]`` and, when the
   magnetometer is used, the field ``v_m = R(q)^T [0, |h_xy|, h_z]`` with ``h = R(q) m`` the
   measured field in the world (its horizontal part put on north, +y: only the heading is taken
   from the magnetometer, as in the reference implementation ``ahrs.filters.Mahony``).
2. Innovation ``w_mes = a × v_a + m × v_m`` (``a``, ``m`` the normalised readings; the paper's
   ``sum_i k_i v_i × v̂_i`` with unit weights).
3. Bias and rate: ``b <- b - k_I w_mes dt``, ``W = w - b + k_P w_mes``.
4. Integration: ``q <- normalise(q + 0.5 q ⊗ [0, W] dt)``.

Gains: ``k_P = 1`` rad/s and ``k_I = 0.3`` rad/s^2, the defaults of ``ahrs.filters.Mahony``
(which gives them as the experimental settings of the paper); they are not tuned on any data of
this project. ``tests/test_estimators/test_attitude_stages.py`` checks this filter against
``ahrs.filters.Mahony``
to 1e-9 (its world frame puts the field's horizontal part on +y as here, so no frame change).

Missing data: a sample whose accelerometer reading is not usable (non-finite or zero) gets no
correction (``W = w - b``); a sample whose magnetometer reading is not usable uses gravity only;
a non-finite gyro reading counts as a zero rate for that sample (``W = -b + k_P w_mes``). Start:
the convention of the reference stages (:mod:`estimators._attitude_helpers_numba`): the first
sample of a (re)set stream with a usable accelerometer reading sets the attitude (tilt, plus
heading from that sample's field when usable) and takes no filter step; the bias starts at 0.

The per-sample loop is the compiled kernel :data:`mahony_kernel` (loop over users inside;
``mahony_kernel.py_func`` is its readable uncompiled source).
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
from estimators.kernels.rotations import quat_mul, quat_rotate
from estimators.validation import check_in_range

__all__ = ["Mahony", "MahonyParams", "mahony_kernel"]


@dataclass(frozen=True)
class MahonyParams:
    """Parameters of :class:`Mahony`.

    Every field is validated on construction.
    """

    kp: float = 1.0
    """Proportional gain ``k_P`` (rad/s): the bandwidth of the attitude correction. Default 1.0:
    ``ahrs.filters.Mahony`` ``k_P`` (the experimental setting of Mahony et al. 2008)."""
    ki: float = 0.3
    """Integral gain ``k_I`` (rad/s^2) of the gyro-bias estimate; 0 disables the bias estimate.
    Default 0.3: ``ahrs.filters.Mahony`` ``k_I`` (the experimental setting of Mahony et al.
    2008)."""

    def __post_init__(self) -> None:
        check_in_range(self, "kp", 0.0, 100.0, "rad/s")
        check_in_range(self, "ki", 0.0, 100.0, "rad/s^2")

    def build(self, batch_size: int, fs: float) -> Mahony:
        """The :class:`Mahony` stage with these parameters."""
        return Mahony(batch_size, fs, self)


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
                if mag_ok:
                    qw, qx, qy, qz = quat_from_acc_mag(ax, ay, az, mx, my, mz)
                else:
                    qw, qx, qy, qz = quat_from_acc(ax, ay, az)
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
            qw, qx, qy, qz = (qw + 0.5 * dw * dt, qx + 0.5 * dx * dt, qy + 0.5 * dy * dt,
                              qz + 0.5 * dz * dt)  # fmt: skip
            n = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
            qw, qx, qy, qz = qw / n, qx / n, qy / n, qz / n
            out[i, k, 0], out[i, k, 1], out[i, k, 2], out[i, k, 3] = qw, qx, qy, qz
        q[i, 0], q[i, 1], q[i, 2], q[i, 3] = qw, qx, qy, qz
        bias[i, 0], bias[i, 1], bias[i, 2] = bx, by, bz
        ready[i] = rdy


#: The compiled kernel: ``mahony_kernel(B)(q, bias, ready, gyr, acc, mag, dt, kp, ki, out)``.
mahony_kernel = BatchKernel(_mahony_run)


class Mahony(QuaternionStage):
    """Mahony's filter as an attitude stage (:class:`estimators.stages.AttitudeStage`).

    Args:
        batch_size: B streams (users).
        fs: IMU rate, Hz (one sample every ``1 / fs`` s).
        params: :class:`MahonyParams` (defaults if None).
    """

    name = "mahony"
    Params = MahonyParams
    per_user_fields = (*QuaternionStage.per_user_fields, "b")

    def _allocate(self) -> None:
        self.b = np.zeros((self.batch_size, 3))  # gyro-bias estimates (rad/s)

    def _reset_rows(self, rows: NDArray[np.intp]) -> None:
        self.b[rows] = 0.0

    def _run(self, gyr: NDArray, acc: NDArray, mag: NDArray, out: NDArray) -> None:
        p = self.params
        mahony_kernel(self.batch_size)(
            self.q, self.b, self.ready, gyr, acc, mag, self.dt, float(p.kp), float(p.ki), out
        )

    @property
    def quat(self) -> NDArray[np.float64]:
        """(B, 4) current attitude."""
        return self.q.copy()

    @property
    def bias(self) -> NDArray[np.float64]:
        """(B, 3) current gyro-bias estimates, rad/s."""
        return self.b.copy()
