"""Compiled per-sample kernel of the error-state attitude EKF (see :mod:`estimators.attitude`).

This module is the fast mirror of :func:`estimators.attitude.ekf_step_reference`, the readable
numpy implementation that documents the filter; ``tests/test_attitude.py`` checks that both agree
to 1e-9 on the same data. Numba cannot call the broadcasting numpy functions of
:mod:`estimators.rotations`, so the few quaternion products the filter needs are written out here
on scalars: they are the same formulas (Hamilton, ``[w, x, y, z]``, sensor -> ENU world) and the
equality test is what keeps them honest.

Streams are independent, so the kernel loops over streams outside and time inside: each stream's
state stays in cache while its samples are processed. No Python object is touched in the loop.
``ekf_step`` is inlined into the loop (``inline="always"``): passing its 15 array arguments per
call cost about 20 % of the throughput (measured 2.4 vs 2.9 million sample-updates/s, B = 1024).

The layout of the packed parameter vector ``prm`` and of the per-stream auxiliary state ``aux`` is
given by the ``PRM_*`` and ``AUX_*`` indices below; :mod:`estimators.attitude` fills them from
:class:`~estimators.attitude.AttitudeParams`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from estimators.kernels.rotations import quat_from_rotvec

# Packed parameters (float64 vector), filled by ``AttitudeParams.packed()``; units as there.
PRM_MODEL_TRAWNY = 0  # 1.0: F = [[-[w x], -I], [0, 0]] (Trawny); 0.0: the paper's printed F = 0
PRM_GYR_NOISE = 1  # rad/s/sqrt(Hz)
PRM_BIAS_WALK = 2  # rad/s/sqrt(s)
PRM_ATT_INIT_STD = 3  # rad
PRM_BIAS_INIT_STD = 4  # rad/s
PRM_ACC_NOISE = 5  # rad*sqrt(s)
PRM_ACC_MOTION_REF = 6  # m/s^2
PRM_MOTION_TAU = 7  # s
PRM_GRAVITY = 8  # m/s^2
PRM_MAG_NOISE = 9  # rad*sqrt(s)
PRM_MAG_NORM_TOL = 10  # fraction of the reference norm
PRM_MAG_DIP_TOL = 11  # rad
PRM_MAG_LEARN_TIME = 12  # s
PRM_MAG_OK_TIME = 13  # s
PRM_MAG_NEW_TIME = 14  # s
PRM_DECLINATION = 15  # rad
PRM_GYR_GAP_RATE = 16  # rad/s
PRM_REST_GYR = 17  # rad/s
PRM_REST_ACC = 18  # m/s^2
PRM_REST_TIME = 19  # s
N_PRM = 20

# Per-stream auxiliary state (float64), beside q (4), b (3) and P (6, 6).
AUX_INIT = 0  # 1.0 once the attitude has been initialised from an accelerometer sample
AUX_HEAD_INIT = 1  # 1.0 once the heading has been initialised from a magnetometer sample
AUX_MAG_NORM = 2  # reference field norm (field unit)
AUX_MAG_DIP = 3  # reference dip angle (rad), positive when the field points below the horizon
AUX_MAG_LEARN_N = 4  # samples averaged into the reference so far
AUX_MAG_LEARN_T = 5  # s spent learning so far (inf: reference given, no learning)
AUX_CAND_NORM = 6  # candidate new field norm
AUX_CAND_DIP = 7  # candidate new field dip (rad)
AUX_CAND_T = 8  # s the candidate has stayed consistent while the reference was rejected
AUX_MAG_OK_T = 9  # s the field has stayed consistent with the reference
AUX_MOTION = 10  # low-passed | |f| - g | (m/s^2)
AUX_REST_T = 11  # s the sensor has looked at rest
N_AUX = 12


@numba.njit(cache=True, inline="always")
def _rot_row(q, r, out):
    """Row ``r`` of the rotation matrix of unit quaternion ``q`` (sensor -> world)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    if r == 0:
        out[0] = 1.0 - 2.0 * (y * y + z * z)
        out[1] = 2.0 * (x * y - w * z)
        out[2] = 2.0 * (x * z + w * y)
    elif r == 1:
        out[0] = 2.0 * (x * y + w * z)
        out[1] = 1.0 - 2.0 * (x * x + z * z)
        out[2] = 2.0 * (y * z - w * x)
    else:
        out[0] = 2.0 * (x * z - w * y)
        out[1] = 2.0 * (y * z + w * x)
        out[2] = 1.0 - 2.0 * (x * x + y * y)


@numba.njit(cache=True, inline="always")
def _quat_mul_rotvec(q, rx, ry, rz):
    """In place ``q <- normalize(q ⊗ exp([rx, ry, rz]))`` (rotation vector in rad, body frame)."""
    pw, px, py, pz = quat_from_rotvec(rx, ry, rz)
    w, x, y, z = q[0], q[1], q[2], q[3]
    nw = w * pw - x * px - y * py - z * pz
    nx = w * px + x * pw + y * pz - z * py
    ny = w * py - x * pz + y * pw + z * px
    nz = w * pz + x * py - y * px + z * pw
    n = math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
    q[0], q[1], q[2], q[3] = nw / n, nx / n, ny / n, nz / n


@numba.njit(cache=True, inline="always")
def _yaw_rotate(q, angle):
    """In place ``q <- Rz(angle) ⊗ q``: turn the attitude about the world vertical (rad)."""
    c = math.cos(0.5 * angle)
    s = math.sin(0.5 * angle)
    w, x, y, z = q[0], q[1], q[2], q[3]
    q[0] = c * w - s * z
    q[1] = c * x - s * y
    q[2] = c * y + s * x
    q[3] = c * z + s * w


@numba.njit(cache=True, inline="always")
def _wrap(a):
    """Wrap an angle (rad) into (-pi, pi], as :func:`estimators.rotations.wrap_angle`."""
    return math.pi - ((math.pi - a) % (2.0 * math.pi))


@numba.njit(cache=True, inline="always")
def _scalar_update(P, dx, h, z, r, ph):
    """One scalar Kalman update with ``H = [h, 0, 0, 0]`` (h acts on dphi only).

    Eq. (14) of seed 000, ``dx+ = dx- + K (z - H dx-)``, processed one measurement row at a time
    (equivalent to the joint update for a diagonal R), and ``P+ = P- - K H P-`` computed on the
    upper triangle and mirrored (P stays exactly symmetric). ``ph`` is (6,) scratch.
    """
    for i in range(6):
        ph[i] = P[i, 0] * h[0] + P[i, 1] * h[1] + P[i, 2] * h[2]
    s = h[0] * ph[0] + h[1] * ph[1] + h[2] * ph[2] + r
    innov = (z - (h[0] * dx[0] + h[1] * dx[1] + h[2] * dx[2])) / s
    for i in range(6):
        dx[i] += ph[i] * innov
        ki = ph[i] / s
        for j in range(i, 6):
            v = P[i, j] - ki * ph[j]
            P[i, j] = v
            P[j, i] = v


@numba.njit(cache=True, inline="always")
def _bias_update(P, dx, j, z, r, ph):
    """One scalar Kalman update measuring bias component j: ``H = e_{3+j}`` (in place)."""
    for i in range(6):
        ph[i] = P[i, 3 + j]
    s = ph[3 + j] + r
    innov = (z - dx[3 + j]) / s
    for i in range(6):
        dx[i] += ph[i] * innov
        ki = ph[i] / s
        for k in range(i, 6):
            v = P[i, k] - ki * ph[k]
            P[i, k] = v
            P[k, i] = v


@numba.njit(cache=True, inline="always")
def _propagate_cov(P, M, dt, ma):
    """``P <- Phi P Phi^T`` for ``Phi = [[M, -dt I], [0, I]]``, by 3x3 blocks.

    With ``P = [[A, C], [C^T, D]]``: ``C' = M C - dt D``,
    ``A' = M A M^T - dt ((M C)^T + C')``, ``D' = D``.
    """
    for i in range(3):
        for j in range(6):
            ma[i, j] = M[i, 0] * P[0, j] + M[i, 1] * P[1, j] + M[i, 2] * P[2, j]
    for i in range(3):
        for j in range(3):
            c_new = ma[i, 3 + j] - dt * P[3 + i, 3 + j]
            P[i, 3 + j] = c_new
            P[3 + j, i] = c_new
    for i in range(3):
        for j in range(3):
            ma[i, 6 + j] = ma[i, 0] * M[j, 0] + ma[i, 1] * M[j, 1] + ma[i, 2] * M[j, 2]
    for i in range(3):
        for j in range(i, 3):
            a_new = ma[i, 6 + j] - dt * (ma[j, 3 + i] + P[i, 3 + j])
            P[i, j] = a_new
            P[j, i] = a_new


@numba.njit(cache=True, inline="always")
def ekf_step(q, b, P, aux, w, f, m, dt, prm, dx, h, M, ma, Rm, ph):
    """Advance one stream by one sample; mirrors :func:`estimators.attitude.ekf_step_reference`.

    Args:
        q: (4,) nominal quaternion, updated in place.
        b: (3,) gyro bias (rad/s), updated in place.
        P: (6, 6) error covariance, updated in place.
        aux: (N_AUX,) auxiliary state, updated in place.
        w: (3,) gyro sample (rad/s); non-finite skips the propagation.
        f: (3,) accelerometer sample (m/s^2); non-finite skips the tilt measurement.
        m: (3,) magnetometer sample (any unit); non-finite skips the heading measurement.
        dt: sample interval (s).
        prm: (N_PRM,) packed parameters.
        dx, h, M, ma, Rm, ph: scratch arrays of shapes (6,), (3,), (3, 3), (3, 9), (3, 3),
            (6,).
    """
    g = prm[PRM_GRAVITY]
    w_ok = math.isfinite(w[0]) and math.isfinite(w[1]) and math.isfinite(w[2])
    f_ok = math.isfinite(f[0]) and math.isfinite(f[1]) and math.isfinite(f[2])
    m_ok = math.isfinite(m[0]) and math.isfinite(m[1]) and math.isfinite(m[2])
    fn = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]) if f_ok else 0.0
    mn = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]) if m_ok else 0.0
    f_ok = f_ok and fn > 0.0
    m_ok = m_ok and mn > 0.0

    # ---- initialisation from the first plausible accelerometer (and magnetometer) sample ----
    if aux[AUX_INIT] == 0.0:
        if f_ok and abs(fn - g) < 0.5 * g:
            # Tilt: the shortest rotation taking the measured up (f/|f|, sensor) to world +z.
            ux, uy, uz = f[0] / fn, f[1] / fn, f[2] / fn
            if uz > -1.0 + 1e-9:
                qw = math.sqrt(0.5 * (1.0 + uz))
                q[0], q[1], q[2], q[3] = qw, uy / (2.0 * qw), -ux / (2.0 * qw), 0.0
            else:
                q[0], q[1], q[2], q[3] = 0.0, 1.0, 0.0, 0.0
            for i in range(6):
                for j in range(6):
                    P[i, j] = 0.0
            for i in range(3):
                b[i] = 0.0
                P[i, i] = prm[PRM_ATT_INIT_STD] ** 2
                P[i + 3, i + 3] = prm[PRM_BIAS_INIT_STD] ** 2
            aux[AUX_INIT] = 1.0
            aux[AUX_MOTION] = abs(fn - g)
        elif w_ok:
            _quat_mul_rotvec(q, w[0] * dt, w[1] * dt, w[2] * dt)
        if aux[AUX_INIT] == 0.0:
            return
    if aux[AUX_HEAD_INIT] == 0.0 and m_ok and f_ok:
        # Heading: turn about the world vertical until the measured east (m x f in the sensor:
        # north x up = east, the tilt-compensated compass of eq (12) as a vector) points along
        # the magnetic east of ENU, at yaw -D from +x.
        ex = m[1] * f[2] - m[2] * f[1]
        ey = m[2] * f[0] - m[0] * f[2]
        ez = m[0] * f[1] - m[1] * f[0]
        _rot_row(q, 0, h)
        e_wx = h[0] * ex + h[1] * ey + h[2] * ez
        _rot_row(q, 1, h)
        e_wy = h[0] * ex + h[1] * ey + h[2] * ez
        if e_wx * e_wx + e_wy * e_wy > 0.0:
            _yaw_rotate(q, _wrap(-prm[PRM_DECLINATION] - math.atan2(e_wy, e_wx)))
            aux[AUX_HEAD_INIT] = 1.0

    # ---- propagation: q_dot = 1/2 q ⊗ (y - b), eqs (3)-(5); Phi = I + F dt, eq (9) ----------
    wx, wy, wz = 0.0, 0.0, 0.0
    if w_ok:
        wx, wy, wz = w[0] - b[0], w[1] - b[1], w[2] - b[2]
        if prm[PRM_MODEL_TRAWNY] != 0.0:
            # M = I - [w x] dt, the attitude block of I + F dt.
            M[0, 0], M[0, 1], M[0, 2] = 1.0, wz * dt, -wy * dt
            M[1, 0], M[1, 1], M[1, 2] = -wz * dt, 1.0, wx * dt
            M[2, 0], M[2, 1], M[2, 2] = wy * dt, -wx * dt, 1.0
            _propagate_cov(P, M, dt, ma)
        _quat_mul_rotvec(q, wx * dt, wy * dt, wz * dt)
    qg = prm[PRM_GYR_NOISE] ** 2 * dt
    if not w_ok:
        qg += (prm[PRM_GYR_GAP_RATE] * dt) ** 2  # the rotation missed during the gap
    qb = prm[PRM_BIAS_WALK] ** 2 * dt
    for i in range(3):
        P[i, i] += qg
        P[i + 3, i + 3] += qb

    for i in range(6):
        dx[i] = 0.0
    updated = False
    _rot_row(q, 0, Rm[0])
    _rot_row(q, 1, Rm[1])
    _rot_row(q, 2, Rm[2])

    # ---- tilt measurement: horizontal part of the specific force in the world, over g --------
    if f_ok:
        # Motion level: | |f| - g | low-passed over PRM_MOTION_TAU; it lowers the weight.
        aux[AUX_MOTION] += min(1.0, dt / prm[PRM_MOTION_TAU]) * (abs(fn - g) - aux[AUX_MOTION])
        lvl = aux[AUX_MOTION] / prm[PRM_ACC_MOTION_REF]
        r = prm[PRM_ACC_NOISE] ** 2 * (1.0 + lvl * lvl) / dt
        ax = Rm[0, 0] * f[0] + Rm[0, 1] * f[1] + Rm[0, 2] * f[2]
        ay = Rm[1, 0] * f[0] + Rm[1, 1] * f[1] + Rm[1, 2] * f[2]
        _scalar_update(P, dx, Rm[0], ay / g, r, ph)
        _scalar_update(P, dx, Rm[1], -ax / g, r, ph)
        updated = True

    # ---- heading measurement: tilt-compensated magnetometer, eqs (12)-(13) -------------------
    if m_ok and aux[AUX_HEAD_INIT] != 0.0:
        # Field direction in the world through the predicted attitude: heading and dip.
        mx = (Rm[0, 0] * m[0] + Rm[0, 1] * m[1] + Rm[0, 2] * m[2]) / mn
        my = (Rm[1, 0] * m[0] + Rm[1, 1] * m[1] + Rm[1, 2] * m[2]) / mn
        mz = (Rm[2, 0] * m[0] + Rm[2, 1] * m[1] + Rm[2, 2] * m[2]) / mn
        dip = math.asin(min(1.0, max(-1.0, -mz)))
        accept = True
        if aux[AUX_MAG_LEARN_T] < prm[PRM_MAG_LEARN_TIME]:
            # Learn the reference field: running mean of norm and dip over the first samples.
            n_l = aux[AUX_MAG_LEARN_N] + 1.0
            aux[AUX_MAG_NORM] += (mn - aux[AUX_MAG_NORM]) / n_l
            aux[AUX_MAG_DIP] += (dip - aux[AUX_MAG_DIP]) / n_l
            aux[AUX_MAG_LEARN_N] = n_l
            aux[AUX_MAG_LEARN_T] += dt
        else:
            ref_n, ref_d = aux[AUX_MAG_NORM], aux[AUX_MAG_DIP]
            if (
                abs(mn - ref_n) <= prm[PRM_MAG_NORM_TOL] * ref_n
                and abs(dip - ref_d) <= prm[PRM_MAG_DIP_TOL]
            ):
                aux[AUX_CAND_T] = 0.0
                aux[AUX_MAG_OK_T] += dt
                accept = aux[AUX_MAG_OK_T] >= prm[PRM_MAG_OK_TIME]
            else:
                # Disturbed. A field that stays consistent long enough becomes the reference.
                c_n, c_d = aux[AUX_CAND_NORM], aux[AUX_CAND_DIP]
                if (
                    aux[AUX_CAND_T] > 0.0
                    and abs(mn - c_n) <= prm[PRM_MAG_NORM_TOL] * c_n
                    and abs(dip - c_d) <= prm[PRM_MAG_DIP_TOL]
                ):
                    aux[AUX_CAND_T] += dt
                    a_c = min(1.0, dt / prm[PRM_MOTION_TAU])
                    aux[AUX_CAND_NORM] += a_c * (mn - c_n)
                    aux[AUX_CAND_DIP] += a_c * (dip - c_d)
                else:
                    aux[AUX_CAND_NORM], aux[AUX_CAND_DIP], aux[AUX_CAND_T] = mn, dip, dt
                if aux[AUX_CAND_T] >= prm[PRM_MAG_NEW_TIME]:
                    aux[AUX_MAG_NORM], aux[AUX_MAG_DIP] = aux[AUX_CAND_NORM], aux[AUX_CAND_DIP]
                    aux[AUX_CAND_T] = 0.0
                    aux[AUX_MAG_OK_T] = prm[PRM_MAG_OK_TIME]
                else:
                    aux[AUX_MAG_OK_T] = 0.0
                    accept = False
        if accept and mx * mx + my * my > 1e-6:
            # Magnetic north lies at yaw pi/2 - D in ENU; residual wrapped into (-pi, pi].
            zpsi = _wrap(0.5 * math.pi - prm[PRM_DECLINATION] - math.atan2(my, mx))
            _scalar_update(P, dx, Rm[2], zpsi, prm[PRM_MAG_NOISE] ** 2 / dt, ph)
            updated = True

    # ---- zero-rate update at rest: the gyro then reads its bias ------------------------------
    if w_ok and f_ok:
        still = (
            abs(fn - g) < prm[PRM_REST_ACC] and wx * wx + wy * wy + wz * wz < prm[PRM_REST_GYR] ** 2
        )
        aux[AUX_REST_T] = aux[AUX_REST_T] + dt if still else 0.0
        if aux[AUX_REST_T] >= prm[PRM_REST_TIME]:
            r_b = prm[PRM_GYR_NOISE] ** 2 / dt
            _bias_update(P, dx, 0, w[0] - b[0], r_b, ph)
            _bias_update(P, dx, 1, w[1] - b[1], r_b, ph)
            _bias_update(P, dx, 2, w[2] - b[2], r_b, ph)
            updated = True

    # ---- inject and reset: q <- q ⊗ exp(dphi), b <- b + db, dx <- 0 --------------------------
    if updated:
        _quat_mul_rotvec(q, dx[0], dx[1], dx[2])
        b[0] += dx[3]
        b[1] += dx[4]
        b[2] += dx[5]


# Unit guard (not part of the filter): per-stream counts of finite samples, of gyro samples above
# MAX_GYR_NORM and of accelerometer samples below MIN_ACC_NORM (see estimators.attitude).
UNIT_SEEN = 0
UNIT_GYR_BIG = 1
UNIT_ACC_SMALL = 2
N_UNIT = 3


@numba.njit(cache=True)
def ekf_run(q, b, P, aux, units, gyr, acc, mag, dt, prm, guard, out):
    """Run B independent streams over N samples; ``out[i, n]`` receives q after sample n.

    Args:
        q, b, P, aux: (B, 4), (B, 3), (B, 6, 6), (B, N_AUX) state, updated in place.
        units: (B, N_UNIT) int64 unit-guard counters, updated in place.
        gyr, acc, mag: (B, N, 3) samples (mag all-NaN for a 6D filter).
        dt: sample interval (s).
        prm: (N_PRM,) packed parameters.
        guard: (max gyro norm rad/s, min accelerometer norm m/s^2, min count) of the unit guard.
        out: (B, N, 4) output quaternions.

    Returns:
        -1, or ``2 * i + k`` for the first stream i whose counters look like a unit mix-up
        (k = 0: gyro not in rad/s, k = 1: accelerometer in g). The caller raises.
    """
    n_streams, n_samples = gyr.shape[0], gyr.shape[1]
    dx = np.empty(6)
    h = np.empty(3)
    M = np.empty((3, 3))
    ma = np.empty((3, 9))
    Rm = np.empty((3, 3))
    ph = np.empty(6)
    g_max2, a_min2, min_count = guard[0] ** 2, guard[1] ** 2, guard[2]
    flag = -1
    for i in range(n_streams):
        qi, bi, pi, ai = q[i], b[i], P[i], aux[i]
        for n in range(n_samples):
            w, f = gyr[i, n], acc[i, n]
            a2 = f[0] * f[0] + f[1] * f[1] + f[2] * f[2]
            if math.isfinite(a2):
                units[i, UNIT_SEEN] += 1
                if a2 < a_min2:
                    units[i, UNIT_ACC_SMALL] += 1
            if w[0] * w[0] + w[1] * w[1] + w[2] * w[2] > g_max2:
                units[i, UNIT_GYR_BIG] += 1
            ekf_step(qi, bi, pi, ai, w, f, mag[i, n], dt, prm, dx, h, M, ma, Rm, ph)
            out[i, n, 0] = qi[0]
            out[i, n, 1] = qi[1]
            out[i, n, 2] = qi[2]
            out[i, n, 3] = qi[3]
        if flag < 0:
            seen, big, small = units[i, UNIT_SEEN], units[i, UNIT_GYR_BIG], units[i, UNIT_ACC_SMALL]
            if big >= min_count and big * 100 >= seen:
                flag = 2 * i
            elif small >= min_count and small * 2 > seen:
                flag = 2 * i + 1
    return flag
