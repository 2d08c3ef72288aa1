"""Compiled sample loop of the head-IMU model (see :mod:`vrloco_env.sensors.imu`).

:meth:`vrloco_env.sensors.imu.HeadImu.sample` checks its input (shapes in Python, values with
:func:`first_invalid`), draws one ``(B, N, 27)`` block of standard normals from the users'
:class:`~vrloco_env.batch_rng.BatchRng` -- exactly the draw of the numpy model -- and hands
everything to :func:`sample_kernel`, which runs the whole measurement model with explicit loops
over users and samples: quaternion normalisation, the Gauss-Markov and random-walk bias
recursions, gravity and the geomagnetic field (plus dipole disturbances) rotated into the body
frame, soft and hard iron, white noise, quantisation and saturation. One call replaces some 60
small numpy operations and three to six ``scipy.signal.lfilter`` calls (issue 5: the numpy model
took ~0.17 ms per control step for one user, most of it call overhead on arrays of a few dozen
numbers).

The work runs in three passes: per user, the nine bias channels' recursions along time (each
channel's state in registers); per sample, the truth in the body frame plus bias and white noise;
then the converter (quantisation and saturation) as one flat loop per sensor, which LLVM turns
into SIMD code (a division and a rounding per value).

The readable reference is :meth:`HeadImu.sample_reference` (the numpy model), and
``tests/test_imu.py`` checks that both give the same samples, biases and states. To make that
check exact, every expression here repeats the floating-point operations of the reference in the
same order (no fused multiply-add: numba compiles without fast-math, so LLVM does not contract
``a * b + c``):

* quaternion norm as ``numpy.linalg.norm`` computes it for 4 numbers,
  ``sqrt(((w w + x x) + y y) + z z)``;
* body-frame rotation as :func:`estimators.rotations.quat_rotate_inverse` writes it (the
  conjugate ``[w, -x, -y, -z]`` put into :func:`~estimators.rotations.quat_rotate`'s component
  formula). Numba cannot call the broadcasting functions of :mod:`estimators.rotations`, so the
  formula is written out here on scalars; it is that module's formula, not a second convention;
* each bias recursion as ``lfilter([1], [1, -a], drive, zi=a * state)`` runs it, the transposed
  direct form II: ``y_k = Z + drive_k`` then ``Z = drive_k * 0 - y_k * (-a)`` (scipy's
  ``DOUBLE_filt``), which equals ``a y_k`` up to the sign of a zero;
* the dipole field as :meth:`MagneticDisturbance.field_at` writes it, except ``dist ** 3`` and
  ``dist ** 5``, taken here as products of ``dist`` (a libm ``pow`` costs some 20 ns, twice per
  sample and dipole). Numpy evaluates those powers with ``pow``, on AVX-512 machines with its own
  SIMD routine, so no scalar code could match it everywhere bit for bit anyway: with disturbances
  the magnetometer agrees with the reference to about 1e-13 uT (a few ulp), the other outputs
  exactly.

Units as in :mod:`vrloco_env.sensors.imu`: m/s^2, rad/s, uT, m, A m^2.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from estimators.rotations import GRAVITY

# Rows of the packed per-sensor parameters ``HeadImu._kernel_params`` (7, 3); columns are the
# sensors accel, gyro, mag, except row P_FIELD which holds the ENU earth field (uT) x, y, z.
P_POLE = 0  # Gauss-Markov pole a = exp(-dt / tau), dimensionless
P_GM_STD = 1  # Gauss-Markov drive std sigma sqrt(1 - a^2) (unit of the sensor)
P_RW_STD = 2  # random-walk drive std K sqrt(dt) (unit of the sensor)
P_NOISE_STD = 3  # white-noise std per sample (unit of the sensor)
P_RESOLUTION = 4  # quantisation step (unit of the sensor), 0: none
P_RANGE = 5  # saturation level (unit of the sensor)
P_FIELD = 6  # earth field in ENU (uT)
N_PARAMS = 7

# Columns of the packed dipoles ``HeadImu._kernel_dipoles`` (K, 10).
D_POSITION = 0  # m, 3 columns
D_MOMENT = 3  # A m^2, 3 columns
D_DIRECTION = 6  # unit moment direction (dimensionless), 3 columns
D_MIN_DISTANCE = 9  # m
N_DIPOLE = 10

# Draw layout of one sample (as the numpy model): white noise, Gauss-Markov drive, random-walk
# drive, each 3 sensors x 3 axes, sensor-major.
Z_WHITE = 0
Z_GM = 9
Z_RW = 18
DRAWS_PER_SAMPLE = 27

# Output planes of ``out`` (6, B, N, 3).
O_ACC, O_GYR, O_MAG, O_BIAS_ACC, O_BIAS_GYR, O_BIAS_MAG = 0, 1, 2, 3, 4, 5

# Return codes of first_invalid.
OK = 0
BAD_QUAT = 1  # a non-finite entry
ZERO_QUAT = 2  # a quaternion of norm < 1e-12
BAD_OMEGA = 3
BAD_ACC = 4
BAD_POS = 5

#: Smallest quaternion norm accepted, as :func:`estimators.rotations.ensure_quaternion`.
MIN_QUAT_NORM = 1e-12
#: mu0 / (4 pi) in T m / A (SI, exact before the 2019 redefinition; 1e-7 to 10 significant
#: digits). :data:`vrloco_env.sensors.imu.MU0_OVER_4PI` is this value.
MU0_OVER_4PI = 1e-7


@numba.njit(cache=True)
def _all_finite(x: np.ndarray) -> bool:
    """Whether every entry of ``x`` (C-contiguous) is finite; a branch-free loop LLVM vectorises."""
    flat = x.ravel()
    ok = True
    for i in range(flat.size):
        ok &= math.isfinite(flat[i])
    return ok


@numba.njit(cache=True)
def first_invalid(q: np.ndarray, omega: np.ndarray, acc: np.ndarray, pos: np.ndarray) -> int:
    """The first problem in the input values, in the reference's order, or :data:`OK`.

    Args:
        q: quaternions (B, N, 4), C-contiguous float64.
        omega: body rates (rad/s), (B, N, 3).
        acc: world accelerations (m/s^2), (B, N, 3).
        pos: positions (m), (B, N, 3), or an empty array when none are given.

    Returns:
        One of OK, BAD_QUAT, ZERO_QUAT, BAD_OMEGA, BAD_ACC, BAD_POS.
    """
    if not _all_finite(q):
        return BAD_QUAT
    b, n = q.shape[0], q.shape[1]
    for bi in range(b):
        for k in range(n):
            w, x, y, z = q[bi, k, 0], q[bi, k, 1], q[bi, k, 2], q[bi, k, 3]
            sq = ((w * w + x * x) + y * y) + z * z
            # sqrt(sq) < 1e-12 needs sq < 1e-24 (1 + 2^-52): the exact test only when near.
            if sq < 2.0 * MIN_QUAT_NORM**2 and math.sqrt(sq) < MIN_QUAT_NORM:
                return ZERO_QUAT
    if not _all_finite(omega):
        return BAD_OMEGA
    if not _all_finite(acc):
        return BAD_ACC
    if not _all_finite(pos):
        return BAD_POS
    return OK


@numba.njit(cache=True)
def _rotate_inverse(
    w: float, x: float, y: float, z: float, vx: float, vy: float, vz: float
) -> tuple[float, float, float]:
    """``R(q)^T v`` for a unit quaternion ``[w, x, y, z]``: rotations.quat_rotate_inverse."""
    cx, cy, cz = -x, -y, -z  # the conjugate's vector part (rotations.quat_conjugate)
    tx = 2.0 * (cy * vz - cz * vy)
    ty = 2.0 * (cz * vx - cx * vz)
    tz = 2.0 * (cx * vy - cy * vx)
    return (
        vx + w * tx + (cy * tz - cz * ty),
        vy + w * ty + (cz * tx - cx * tz),
        vz + w * tz + (cx * ty - cy * tx),
    )


@numba.njit(cache=True)
def _quantise_clip(y: np.ndarray, res: float, rng: float) -> None:
    """In place: quantise ``y`` (1-D) to steps of ``res`` (0: none; round half to even, as
    ``numpy.round``), then clip at ``+-rng`` (as ``numpy.clip``)."""
    lo = -rng
    if res > 0.0:
        for i in range(y.size):
            y[i] = min(max(np.rint(y[i] / res) * res, lo), rng)
    else:
        for i in range(y.size):
            y[i] = min(max(y[i], lo), rng)


@numba.njit(cache=True)
def sample_kernel(
    q: np.ndarray,
    omega: np.ndarray,
    acc: np.ndarray,
    pos: np.ndarray,
    z: np.ndarray,
    params: np.ndarray,
    dipoles: np.ndarray,
    turn_on: np.ndarray,
    gm: np.ndarray,
    rw: np.ndarray,
    hard_iron: np.ndarray,
    soft_iron: np.ndarray,
    out: np.ndarray,
) -> None:
    """N samples of B users: fill ``out`` and advance the bias states ``gm`` and ``rw`` in place.

    Args:
        q: true sensor -> world quaternions (B, N, 4), finite and non-zero (normalised here).
        omega: true body rates (rad/s), (B, N, 3).
        acc: true world accelerations without gravity (m/s^2), (B, N, 3).
        pos: sensor positions (m), (B, N, 3); read only when ``dipoles`` has rows.
        z: the call's standard normals (B, N, 27), layout Z_WHITE / Z_GM / Z_RW.
        params: packed parameters (N_PARAMS, 3), rows P_*.
        dipoles: packed magnetic dipoles (K, N_DIPOLE), columns D_*.
        turn_on: turn-on biases (B, 3 sensors, 3 axes).
        gm: Gauss-Markov states (B, 3, 3), updated to the last sample's.
        rw: random-walk states (B, 3, 3), updated to the last sample's.
        hard_iron: hard-iron offsets (uT), (B, 3).
        soft_iron: soft-iron matrices (B, 3, 3).
        out: (6, B, N, 3) output planes O_*: acc, gyr, mag, then their per-sample total biases.
    """
    b, n = q.shape[0], q.shape[1]
    n_dip = dipoles.shape[0]
    # Whether a sensor's bias recursion runs (the reference's test, over all users): a constant
    # bias is carried as it is, a running one goes through the lfilter recursion.
    run_gm = np.zeros(3, dtype=np.bool_)
    run_rw = np.zeros(3, dtype=np.bool_)
    for i in range(3):
        run_rw[i] = params[P_RW_STD, i] > 0.0
        run = params[P_GM_STD, i] > 0.0
        if not run and params[P_POLE, i] != 1.0:
            for bi in range(b):
                for j in range(3):
                    if gm[bi, i, j] != 0.0:
                        run = True
        run_gm[i] = run
    for bi in range(b):
        # Pass 1, biases: turn-on + Gauss-Markov + random walk (+ hard iron for the magnetometer),
        # each channel's recursions as scipy's DOUBLE_filt runs lfilter([1], [1, -a]) (b = [1, 0]),
        # the states in registers.
        for i in range(3):
            pole = params[P_POLE, i]
            neg_pole = -pole
            gm_std = params[P_GM_STD, i]
            rw_std = params[P_RW_STD, i]
            for j in range(3):
                c = 3 * i + j
                yg = gm[bi, i, j]
                yr = rw[bi, i, j]
                zg = pole * yg  # lfilter's zi for y[-1] = state
                zr = 1.0 * yr
                t0 = turn_on[bi, i, j]
                for k in range(n):
                    if run_gm[i]:
                        x = z[bi, k, Z_GM + c] * gm_std
                        yg = zg + x
                        zg = x * 0.0 - yg * neg_pole
                    if run_rw[i]:
                        x = z[bi, k, Z_RW + c] * rw_std
                        yr = zr + x
                        zr = x * 0.0 - yr * -1.0
                    v = t0 + yg + yr
                    if i == 2:
                        v = v + hard_iron[bi, j]
                    out[O_BIAS_ACC + i, bi, k, j] = v
                gm[bi, i, j] = yg  # the last sample's states (unchanged when n = 0)
                rw[bi, i, j] = yr
        # Pass 2, per sample (independent of each other): truth in the body frame, outputs.
        s = soft_iron[bi]
        std_acc = params[P_NOISE_STD, 0]
        std_gyr = params[P_NOISE_STD, 1]
        std_mag = params[P_NOISE_STD, 2]
        for k in range(n):
            # Unit quaternion (rotations.ensure_quaternion).
            qw, qx, qy, qz = q[bi, k, 0], q[bi, k, 1], q[bi, k, 2], q[bi, k, 3]
            nrm = math.sqrt(((qw * qw + qx * qx) + qy * qy) + qz * qz)
            qw, qx, qy, qz = qw / nrm, qx / nrm, qy / nrm, qz / nrm
            # Specific force in the body frame: R^T (a - g), g = [0, 0, -GRAVITY].
            fx, fy, fz = _rotate_inverse(
                qw, qx, qy, qz, acc[bi, k, 0] - 0.0, acc[bi, k, 1] - 0.0, acc[bi, k, 2] - -GRAVITY
            )
            # World field at the IMU: earth field plus each dipole (MagneticDisturbance.field_at).
            mx, my, mz = params[P_FIELD, 0], params[P_FIELD, 1], params[P_FIELD, 2]
            for d in range(n_dip):
                rx = pos[bi, k, 0] - dipoles[d, D_POSITION]
                ry = pos[bi, k, 1] - dipoles[d, D_POSITION + 1]
                rz = pos[bi, k, 2] - dipoles[d, D_POSITION + 2]
                dist = math.sqrt(rx * rx + ry * ry + rz * rz)
                min_d = dipoles[d, D_MIN_DISTANCE]
                if dist < min_d:  # stretch to min_distance; at the dipole, along the moment
                    if dist > 0.0:
                        rx, ry, rz = rx / dist * min_d, ry / dist * min_d, rz / dist * min_d
                    else:
                        rx = dipoles[d, D_DIRECTION] * min_d
                        ry = dipoles[d, D_DIRECTION + 1] * min_d
                        rz = dipoles[d, D_DIRECTION + 2] * min_d
                    dist = min_d
                m0 = dipoles[d, D_MOMENT]
                m1 = dipoles[d, D_MOMENT + 1]
                m2 = dipoles[d, D_MOMENT + 2]
                m_dot_r = rx * m0 + ry * m1 + rz * m2
                d3 = dist * dist * dist
                d5 = d3 * dist * dist
                mx = mx + MU0_OVER_4PI * (3.0 * rx * m_dot_r / d5 - m0 / d3) * 1e6
                my = my + MU0_OVER_4PI * (3.0 * ry * m_dot_r / d5 - m1 / d3) * 1e6
                mz = mz + MU0_OVER_4PI * (3.0 * rz * m_dot_r / d5 - m2 / d3) * 1e6
            bx, by, bz = _rotate_inverse(qw, qx, qy, qz, mx, my, mz)
            # Soft iron S m_body (hard iron is in the magnetometer's bias).
            sx = s[0, 0] * bx + s[0, 1] * by + s[0, 2] * bz
            sy = s[1, 0] * bx + s[1, 1] * by + s[1, 2] * bz
            sz = s[2, 0] * bx + s[2, 1] * by + s[2, 2] * bz
            # Truth + bias + white noise, before the converter (pass 3).
            zk = z[bi, k]
            ba, bg, bm = out[O_BIAS_ACC, bi, k], out[O_BIAS_GYR, bi, k], out[O_BIAS_MAG, bi, k]
            ya, yg, ym = out[O_ACC, bi, k], out[O_GYR, bi, k], out[O_MAG, bi, k]
            ya[0] = fx + ba[0] + std_acc * zk[Z_WHITE]
            ya[1] = fy + ba[1] + std_acc * zk[Z_WHITE + 1]
            ya[2] = fz + ba[2] + std_acc * zk[Z_WHITE + 2]
            yg[0] = omega[bi, k, 0] + bg[0] + std_gyr * zk[Z_WHITE + 3]
            yg[1] = omega[bi, k, 1] + bg[1] + std_gyr * zk[Z_WHITE + 4]
            yg[2] = omega[bi, k, 2] + bg[2] + std_gyr * zk[Z_WHITE + 5]
            ym[0] = sx + bm[0] + std_mag * zk[Z_WHITE + 6]
            ym[1] = sy + bm[1] + std_mag * zk[Z_WHITE + 7]
            ym[2] = sz + bm[2] + std_mag * zk[Z_WHITE + 8]
    # Pass 3, the converter: quantisation and saturation, one flat loop per sensor that LLVM
    # vectorises (a division per value is most of the kernel's time when done one by one).
    for i in range(3):
        _quantise_clip(out[O_ACC + i].ravel(), params[P_RESOLUTION, i], params[P_RANGE, i])
