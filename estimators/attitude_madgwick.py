"""Madgwick's gradient-descent attitude filter (IMU and MARG); attitude output sensor -> ENU.

Sources: S. O. H. Madgwick, "An efficient orientation filter for inertial and inertial/magnetic
sensor arrays", report, University of Bristol, 2010; S. O. H. Madgwick, A. J. L. Harrison,
R. Vaidyanathan, "Estimation of IMU and MARG orientation using a gradient descent algorithm",
IEEE ICORR 2011.

Per sample, with ``q`` the attitude (sensor -> world), ``w`` the gyro reading (rad/s), ``a`` and
``m`` the normalised accelerometer and magnetometer readings:

1. Rate of change from the gyro: ``qdot = 0.5 q ⊗ [0, w]``.
2. One normalised gradient-descent step on the misfit of the predicted directions of the
   references: for a world reference ``d`` and its sensor reading ``s``, ``f(q) = R(q)^T d - s``
   and its Jacobian ``J = df/dq`` (the report's general objective function and Jacobian for an
   arbitrary ``d``); ``grad = sum J^T f`` over gravity ``d = [0, 0, 1]`` and, in MARG mode, the
   field ``d = b``; ``qdot -= beta grad / |grad|``.
3. Magnetic reference (the report's magnetic distortion compensation): the field rotated into
   the world, ``h = R(q) m``, with its horizontal part put on north: ``b = [|h_xy|, 0, h_z]``.
4. Integration: ``q <- normalise(q + qdot dt)``.

World frames. Madgwick's world has north on +x and up on +z (north-west-up, NWU), as in step 3.
The filter runs in that frame, exactly as published, and its attitude is turned into this
project's ENU world on output: ``q_ENU = r ⊗ q_NWU`` with ``r`` the +90 deg rotation about the
vertical (it takes north, NWU +x, onto ENU +y); a state given in ENU (the start, below) enters as
``conj(r) ⊗ q_ENU``. Running the same steps in ENU with ``b = [0, |h_xy|, h_z]`` would not be
exactly the same filter: Madgwick's objective function uses ``1 - 2 y^2 - 2 z^2``-type diagonal
terms, equal to the rotation matrix only on unit quaternions, so its gradient is not equivariant
under a change of world heading (on random noisy samples the two versions differ by 1e-5
after ten samples and by 1e-2 after 2000).
``tests/test_estimators/test_attitude_stages.py`` checks this filter against
``ahrs.filters.Madgwick``
(which
uses the NWU world) to 1e-9.

The gain ``beta`` is ``sqrt(3/4)`` times the gyro measurement error (rad/s); the report's
experiments found 0.033 rad/s (IMU) and 0.041 rad/s (MARG) best. These are this module's
defaults (and those of ``ahrs.filters.Madgwick``); they are not tuned on any data of this project.
The report's gyro bias drift compensation (gain ``zeta``) is not implemented (neither ``ahrs`` nor
Madgwick's published C code implement it).

Missing data: a sample whose accelerometer reading is not usable (non-finite or zero) gets no
correction (the MARG step needs the accelerometer, as in the report); a sample whose magnetometer
reading is not usable takes the IMU step with ``beta_imu``; a non-finite gyro reading counts as a
zero rate for that sample. Start: the convention of the reference stages
(:mod:`estimators._attitude_helpers_numba`): the first sample of a (re)set stream with a usable
accelerometer reading sets the attitude (tilt, plus heading from that sample's field when usable)
and takes no filter step.

The per-sample loop is the compiled kernel :data:`madgwick_kernel` (loop over users inside;
``madgwick_kernel.py_func`` is its readable uncompiled source).
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
from estimators.rotations import quat_multiply
from estimators.validation import check_in_range

__all__ = ["Madgwick", "MadgwickParams", "madgwick_kernel"]

#: ``r``: the +90 deg rotation about the vertical taking Madgwick's NWU world to ENU.
_NWU_TO_ENU = np.array([math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)])
#: The ENU identity attitude expressed in the NWU world, ``conj(r)``.
_ENU_IDENTITY_NWU = np.array([math.sqrt(0.5), 0.0, 0.0, -math.sqrt(0.5)])


@dataclass(frozen=True)
class MadgwickParams:
    """Parameters of :class:`Madgwick`.

    Every field is validated on construction.
    """

    beta_imu: float = 0.033
    """Gradient-descent gain (rad/s) of a step without magnetometer (IMU). Default 0.033 rad/s:
    Madgwick 2010 (the best value in its experiments; also ``ahrs`` ``gain_imu``)."""
    beta_marg: float = 0.041
    """Gradient-descent gain (rad/s) of a step with magnetometer (MARG). Default 0.041 rad/s:
    Madgwick 2010 (the best value in its experiments; also ``ahrs`` ``gain_marg``)."""

    def __post_init__(self) -> None:
        for name in ("beta_imu", "beta_marg"):
            check_in_range(self, name, 0.0, 10.0, "rad/s")

    def build(self, batch_size: int, fs: float) -> Madgwick:
        """The :class:`Madgwick` stage with these parameters."""
        return Madgwick(batch_size, fs, self)


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
    f3 = (2.0 * dx * (qw * qy + qx * qz) + 2.0 * dy * (qy * qz - qw * qx)
          + 2.0 * dz * (0.5 - qx * qx - qy * qy) - sz)  # fmt: skip
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
    gz = ((-4.0 * dx * qz + 2.0 * dy * qw + 2.0 * dz * qx) * f1
          + (-2.0 * dx * qw - 4.0 * dy * qz + 2.0 * dz * qy) * f2
          + (2.0 * dx * qx + 2.0 * dy * qy) * f3)  # fmt: skip
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
                if mag_ok:
                    ew, ex, ey, ez = quat_from_acc_mag(ax, ay, az, mx, my, mz)
                else:
                    ew, ex, ey, ez = quat_from_acc(ax, ay, az)
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


class Madgwick(QuaternionStage):
    """Madgwick's filter as an attitude stage (:class:`estimators.stages.AttitudeStage`).

    Args:
        batch_size: B streams (users).
        fs: IMU rate, Hz (one sample every ``1 / fs`` s).
        params: :class:`MadgwickParams` (defaults if None).
    """

    name = "madgwick"
    Params = MadgwickParams
    per_user_fields = QuaternionStage.per_user_fields
    identity = tuple(_ENU_IDENTITY_NWU)

    def _run(self, gyr: NDArray, acc: NDArray, mag: NDArray, out: NDArray) -> None:
        p = self.params
        madgwick_kernel(self.batch_size)(
            self.q, self.ready, gyr, acc, mag, self.dt, float(p.beta_imu), float(p.beta_marg), out
        )

    @property
    def quat(self) -> NDArray[np.float64]:
        """(B, 4) current attitude, sensor -> ENU."""
        return quat_multiply(_NWU_TO_ENU, self.q)
