"""Compiled measurement model of the head IMU (see :mod:`vrloco_env.sensors.imu`), per user.

:meth:`vrloco_env.sensors.imu.HeadImu.sample` checks its input (shapes in Python, values with
:func:`first_invalid`), draws one ``(B, N, 27)`` block of standard normals from the users'
:class:`~vrloco_env.batch_rng.BatchRng` and calls ``sample_kernel(B)(...)``, whose loop over users
runs three stages for each user:

1. :func:`_biases`: per sensor and axis, the turn-on bias plus the Gauss-Markov and random-walk
   recursions along time (each channel's state in registers), plus hard iron on the magnetometer;
2. per sample, the truth in the body frame (:func:`_specific_force`, :func:`_world_field`, soft
   iron) plus bias and white noise (:func:`_add_bias_noise`);
3. :func:`_quantise_clip`: the converter (quantisation and saturation), one flat loop per sensor
   over the user's samples, which LLVM turns into SIMD code (a division and a rounding per value).

Parameters and state are named records (:mod:`estimators.kernels.records`): ``sensors`` holds one
record per sensor (accel, gyro, mag), ``earth`` the undisturbed field, ``dipoles`` one record per
magnetic dipole (fields :data:`DIPOLE`) and ``state`` one record per user (fields :data:`STATE`).

Floating-point order (numba compiles without fast-math, so LLVM does not contract ``a * b + c``):

* quaternion norm ``sqrt(((w w + x x) + y y) + z z)``, the order ``numpy.linalg.norm`` uses for
  4 numbers, so a unit quaternion here is :func:`estimators.rotations.ensure_quaternion`'s;
* body-frame rotation ``R^T v`` as :func:`estimators.rotations.quat_rotate_inverse`: the conjugate
  put into :func:`estimators.kernels.rotations.quat_rotate`;
* each bias recursion as ``scipy.signal.lfilter([1], [1, -a], drive, zi=a * state)`` runs it, the
  transposed direct form II: ``y_k = Z + drive_k`` then ``Z = drive_k * 0 - y_k * (-a)``, which
  equals ``a y_k`` up to the sign of a zero;
* the dipole field (:func:`_dipole_field`, also behind
  :meth:`~vrloco_env.sensors.imu.MagneticDisturbance.field_at`) with ``dist ** 3`` and
  ``dist ** 5`` taken as products of ``dist``.

Units as in :mod:`vrloco_env.sensors.imu`: m/s^2, rad/s, uT, m, A m^2.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from estimators.kernels import BatchKernel
from estimators.kernels.rotations import quat_rotate
from estimators.rotations import GRAVITY

#: Fields of one magnetic dipole record (world frame): position (m) until ``t_start``, moment
#: (A m^2), the moment's unit direction (the offset used at the dipole itself), the radius below
#: which the field no longer grows (m), and its motion: ``velocity`` (m/s) from ``t_start`` to
#: ``t_stop`` (s since the user's reset), where it stays.
DIPOLE = {
    "position": (3,),
    "moment": (3,),
    "direction": (3,),
    "min_distance": (),
    "velocity": (3,),
    "t_start": (),
    "t_stop": (),
}

#: Fields of one user's state record; rows of the (3, 3) fields are the sensors accel, gyro, mag,
#: columns the axes: turn-on biases, Gauss-Markov and random-walk states (unit of each sensor),
#: hard-iron offset (uT) and soft-iron matrix (dimensionless).
STATE = {"turn_on": (3, 3), "gm": (3, 3), "rw": (3, 3), "hard_iron": (3,), "soft_iron": (3, 3)}

# Draw layout of one sample: white noise, Gauss-Markov drive, random-walk drive, each 3 sensors x
# 3 axes, sensor-major.
Z_WHITE = 0
Z_GM = 9
Z_RW = 18
DRAWS_PER_SAMPLE = 27

# Output planes of ``out`` (6, B, N, 3): the outputs, then their per-sample total biases.
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
    """The first problem in the input values, checked in argument order, or :data:`OK`.

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
def _gm_runs(sensor, gm) -> bool:
    """Whether a sensor's Gauss-Markov recursion changes its states ``gm`` (3,): it has a drive,
    or a pole below 1 and a non-zero state to decay. Otherwise the state is carried as it is."""
    if sensor["gm_std"] > 0.0:
        return True
    if sensor["pole"] != 1.0:
        for j in range(3):
            if gm[j] != 0.0:
                return True
    return False


@numba.njit(cache=True)
def _biases(z, sensors, s, bias) -> None:
    """One user's per-sample total biases ``bias`` (3 sensors, N, 3), advancing its Gauss-Markov
    and random-walk states in the state record ``s`` to the last sample's (unchanged when N = 0).

    Each channel's recursions run as scipy's ``lfilter([1], [1, -a])`` (transposed direct form
    II, numerator ``[1, 0]``) from ``zi = a * state``; ``z`` is the user's draws (N, 27).
    """
    n = z.shape[0]
    gm, rw = s["gm"], s["rw"]
    for i in range(3):
        sensor = sensors[i]
        run_gm = _gm_runs(sensor, gm[i])
        run_rw = sensor["rw_std"] > 0.0
        pole = sensor["pole"]
        neg_pole = -pole
        gm_std, rw_std = sensor["gm_std"], sensor["rw_std"]
        for j in range(3):
            c = 3 * i + j
            yg = gm[i, j]
            yr = rw[i, j]
            zg = pole * yg  # lfilter's zi for y[-1] = state
            zr = 1.0 * yr
            t0 = s["turn_on"][i, j]
            for k in range(n):
                if run_gm:
                    x = z[k, Z_GM + c] * gm_std
                    yg = zg + x
                    zg = x * 0.0 - yg * neg_pole
                if run_rw:
                    x = z[k, Z_RW + c] * rw_std
                    yr = zr + x
                    zr = x * 0.0 - yr * -1.0
                v = t0 + yg + yr
                if i == 2:
                    v = v + s["hard_iron"][j]
                bias[i, k, j] = v
            gm[i, j] = yg
            rw[i, j] = yr


@numba.njit(cache=True, inline="always")
def _unit_quaternion(q) -> tuple[float, float, float, float]:
    """``q`` (4,) divided by its norm (:func:`estimators.rotations.ensure_quaternion`)."""
    qw, qx, qy, qz = q[0], q[1], q[2], q[3]
    nrm = math.sqrt(((qw * qw + qx * qx) + qy * qy) + qz * qz)
    return qw / nrm, qx / nrm, qy / nrm, qz / nrm


@numba.njit(cache=True, inline="always")
def _specific_force(qw, qx, qy, qz, a) -> tuple[float, float, float]:
    """Specific force in the body frame, ``R^T (a - g)`` with ``g = [0, 0, -GRAVITY]``."""
    return quat_rotate(qw, -qx, -qy, -qz, a[0] - 0.0, a[1] - 0.0, a[2] - -GRAVITY)


@numba.njit(cache=True, inline="always")
def _dipole_field(dip, rx, ry, rz) -> tuple[float, float, float]:
    """Field (uT) of the dipole record ``dip`` (:data:`DIPOLE`) at offset ``r`` (m) from it:
    ``mu0/(4 pi) (3 r (m . r) / |r|^5 - m / |r|^3)``, with ``r`` stretched to the record's
    ``min_distance`` below it (at the dipole itself, along the moment)."""
    m = dip["moment"]
    dist = math.sqrt(rx * rx + ry * ry + rz * rz)
    min_d = dip["min_distance"]
    if dist < min_d:  # stretch to min_distance; at the dipole, along the moment
        if dist > 0.0:
            rx, ry, rz = rx / dist * min_d, ry / dist * min_d, rz / dist * min_d
        else:
            u = dip["direction"]
            rx, ry, rz = u[0] * min_d, u[1] * min_d, u[2] * min_d
        dist = min_d
    m_dot_r = rx * m[0] + ry * m[1] + rz * m[2]
    d3 = dist * dist * dist
    d5 = d3 * dist * dist
    return (
        MU0_OVER_4PI * (3.0 * rx * m_dot_r / d5 - m[0] / d3) * 1e6,
        MU0_OVER_4PI * (3.0 * ry * m_dot_r / d5 - m[1] / d3) * 1e6,
        MU0_OVER_4PI * (3.0 * rz * m_dot_r / d5 - m[2] / d3) * 1e6,
    )


@numba.njit(cache=True, inline="always")
def _dipole_offset(dip, px, py, pz, t) -> tuple[float, float, float]:
    """The offset (m) of the point ``p`` from the dipole record ``dip`` at time ``t`` (s): from
    its ``position``, moved by ``velocity`` for the part of ``[t_start, t_stop]`` before ``t``
    (a still dipole, velocity 0, is exactly at its position)."""
    at, v = dip["position"], dip["velocity"]
    if v[0] == 0.0 and v[1] == 0.0 and v[2] == 0.0:
        return px - at[0], py - at[1], pz - at[2]
    moved = min(max(t - dip["t_start"], 0.0), dip["t_stop"] - dip["t_start"])
    return (px - (at[0] + v[0] * moved), py - (at[1] + v[1] * moved), pz - (at[2] + v[2] * moved))


@numba.njit(cache=True, inline="always")
def _world_field(earth, dipoles, pos, times, i, k) -> tuple[float, float, float]:
    """World field (uT) at user ``i``'s sample ``k``: the earth field plus each dipole's
    (:func:`_dipole_field`) where it is at that sample's time; ``pos`` (B, N, 3) m and ``times``
    (B, N) s are read only when there are dipoles."""
    mx, my, mz = earth["east"], earth["north"], earth["up"]
    for d in range(dipoles.shape[0]):
        rx, ry, rz = _dipole_offset(
            dipoles[d], pos[i, k, 0], pos[i, k, 1], pos[i, k, 2], times[i, k]
        )
        bx, by, bz = _dipole_field(dipoles[d], rx, ry, rz)
        mx = mx + bx
        my = my + by
        mz = mz + bz
    return mx, my, mz


def _dipole_points(dipole, points, times, out) -> None:
    """The field (uT) of the (1,) dipole record at each of the (P, 3) ``points`` (m), point
    ``k`` at time ``times[k]`` (s), into ``out`` (P, 3):
    :meth:`~vrloco_env.sensors.imu.MagneticDisturbance.field_at`."""
    for k in numba.prange(points.shape[0]):
        rx, ry, rz = _dipole_offset(dipole[0], points[k, 0], points[k, 1], points[k, 2], times[k])
        out[k, 0], out[k, 1], out[k, 2] = _dipole_field(dipole[0], rx, ry, rz)


@numba.njit(cache=True, inline="always")
def _add_bias_noise(y, tx, ty, tz, bias, std, z, at) -> None:
    """``y`` (3,) = truth ``t`` + ``bias`` (3,) + ``std`` times the draws ``z[at:at + 3]``."""
    y[0] = tx + bias[0] + std * z[at]
    y[1] = ty + bias[1] + std * z[at + 1]
    y[2] = tz + bias[2] + std * z[at + 2]


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


def _sample(q, omega, acc, pos, times, z, sensors, earth, dipoles, state, out) -> None:
    """N samples of B users: fill ``out`` and advance the bias states in ``state`` in place.

    Args:
        q: true sensor -> world quaternions (B, N, 4), finite and non-zero (normalised here).
        omega: true body rates (rad/s), (B, N, 3).
        acc: true world accelerations without gravity (m/s^2), (B, N, 3).
        pos: sensor positions (m), (B, N, 3); read only when ``dipoles`` has rows.
        times: the samples' times (s) since each user's reset, (B, N); read only when
            ``dipoles`` has rows.
        z: the call's standard normals (B, N, 27), layout Z_WHITE / Z_GM / Z_RW.
        sensors: (3,) parameter records of accel, gyro, mag (unit of each sensor): ``range``,
            ``resolution`` (0: none), the Gauss-Markov ``pole`` and drive std ``gm_std``, the
            random-walk drive std ``rw_std`` and the white-noise std per sample ``noise_std``.
        earth: (1,) record of the undisturbed ENU field (uT): ``east``, ``north``, ``up``.
        dipoles: (K,) records :data:`DIPOLE`.
        state: (B,) records :data:`STATE`; the Gauss-Markov and random-walk states advance to the
            last sample's.
        out: (6, B, N, 3) output planes O_*: acc, gyr, mag, then their per-sample total biases.
    """
    n = q.shape[1]
    e = earth[0]
    std_acc, std_gyr, std_mag = (
        sensors[0]["noise_std"],
        sensors[1]["noise_std"],
        sensors[2]["noise_std"],
    )
    for i in numba.prange(q.shape[0]):  # users are independent (estimators.kernels.batch)
        s = state[i]
        _biases(z[i], sensors, s, out[O_BIAS_ACC:, i])
        soft = s["soft_iron"]
        for k in range(n):
            qw, qx, qy, qz = _unit_quaternion(q[i, k])
            fx, fy, fz = _specific_force(qw, qx, qy, qz, acc[i, k])
            mx, my, mz = _world_field(e, dipoles, pos, times, i, k)
            bx, by, bz = quat_rotate(qw, -qx, -qy, -qz, mx, my, mz)
            # Soft iron S m_body (hard iron is in the magnetometer's bias).
            sx = soft[0, 0] * bx + soft[0, 1] * by + soft[0, 2] * bz
            sy = soft[1, 0] * bx + soft[1, 1] * by + soft[1, 2] * bz
            sz = soft[2, 0] * bx + soft[2, 1] * by + soft[2, 2] * bz
            zk, w = z[i, k], omega[i, k]
            _add_bias_noise(
                out[O_ACC, i, k], fx, fy, fz, out[O_BIAS_ACC, i, k], std_acc, zk, Z_WHITE
            )
            _add_bias_noise(
                out[O_GYR, i, k], w[0], w[1], w[2], out[O_BIAS_GYR, i, k], std_gyr, zk, Z_WHITE + 3
            )
            _add_bias_noise(
                out[O_MAG, i, k], sx, sy, sz, out[O_BIAS_MAG, i, k], std_mag, zk, Z_WHITE + 6
            )
        for c in range(3):  # the converter, one flat loop per sensor
            _quantise_clip(out[O_ACC + c, i].ravel(), sensors[c]["resolution"], sensors[c]["range"])


sample_kernel = BatchKernel(_sample, parallel=False)

#: The field of one dipole at P points: ``dipole_kernel(P)(dipole, points, times, out)``.
dipole_kernel = BatchKernel(_dipole_points, parallel=False)
"""The measurement model for B users: ``sample_kernel(B)(...)`` (see :func:`_sample`)."""
