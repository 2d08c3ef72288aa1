"""Compiled per-sample kernels of seed 004: strapdown mechanisation and the visual-inertial ESKF.

This module is the fast mirror of the readable numpy code that documents the algorithms:

* :func:`strapdown_run` <-> :func:`estimators.strapdown.mechanisation_step` (and
  :func:`estimators.strapdown.rk4_attitude`);
* :func:`eskf_predict` <-> :func:`estimators.visual_inertial.eskf_predict_reference`;
* :func:`eskf_update` <-> :func:`estimators.visual_inertial.eskf_update_reference`.

``tests/test_strapdown.py`` and ``tests/test_visual_inertial.py`` check that both sides agree
(1e-12 and 1e-10). Numba cannot call the broadcasting functions of :mod:`estimators.rotations`,
so the few quaternion products needed are written out on scalars: the same formulas (Hamilton,
``[w, x, y, z]``, body -> ENU world), kept honest by those equality tests.

Streams (users) are independent: every kernel loops over streams outside and samples inside, with
no Python object in the loop, so a batch of B gives bit for bit the results of B single runs.

Packed layouts (filled by :mod:`estimators.strapdown` and :mod:`estimators.visual_inertial`):

* nominal state ``x`` (B, N_X): the ``X_*`` offsets below; the last IMU sample is kept raw (bias
  not removed) so that a bias correction applies to both ends of the next interval.
* ``prm`` (N_PRM,) float64 filter parameters, ``aux`` (B, N_AUX) float64 per-user counters.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from estimators.kernels.rotations import quat_from_rotvec

# Nominal state, per user.
X_P = 0  # position, world, m (3)
X_V = 3  # velocity, world, m/s (3)
X_Q = 6  # attitude quaternion body -> world [w, x, y, z] (4)
X_BA = 10  # accelerometer bias, m/s^2 (3)
X_BG = 13  # gyro bias, rad/s (3)
X_GYR = 16  # previous raw gyro sample, rad/s (3)
X_ACC = 19  # previous raw specific-force sample, m/s^2 (3)
N_X = 22

# Filter parameters (float64 vector), from ``VioConfig.packed()``; units as there.
PRM_GRAVITY = 0  # m/s^2
PRM_ACC_NOISE = 1  # m/s^2/sqrt(Hz)
PRM_GYR_NOISE = 2  # rad/s/sqrt(Hz)
PRM_ACC_WALK = 3  # m/s^2/sqrt(s)
PRM_GYR_WALK = 4  # rad/s/sqrt(s)
PRM_SAGE_HUSA = 5  # 1.0: Sage-Husa R estimation, 0.0: fixed R
PRM_FORGET = 6  # Sage-Husa forgetting factor b
PRM_DIAGONAL = 7  # 1.0: diagonal-only R estimate
PRM_PRIOR_FRAMES = 8  # frames the initial R (and Q scale) count for in the fading average
PRM_ADAPT_Q = 9  # 1.0: adapt the Q scale factor
PRM_Q_FORGET = 10  # forgetting factor of the Q scale
PRM_Q_MIN = 11  # lower bound of the Q scale
PRM_Q_MAX = 12  # upper bound of the Q scale
PRM_GATE = 13  # chi-square threshold on the 6-dof NIS (inf: no gate)
PRM_GATE_MAX = 14  # consecutive rejections after which a frame is taken anyway
PRM_R_FLOOR_POS = 15  # m^2
PRM_R_FLOOR_ATT = 16  # rad^2
PRM_R_CEIL_POS = 17  # m^2
PRM_R_CEIL_ATT = 18  # rad^2
N_PRM = 19

# Per-user auxiliary state (float64).
AUX_HAS_PREV = 0  # 1.0 once an IMU sample has been seen (first-order hold possible)
AUX_K = 1  # fading-memory count k of d_k (prior frames + accepted updates)
AUX_Q_SCALE = 2  # current Q scale factor
AUX_CONSEC = 3  # consecutive gate rejections
AUX_UPDATES = 4  # accepted (incl. forced) updates since reset
AUX_REJECTED = 5  # gate rejections since reset
AUX_FORCED = 6  # frames taken after gate_max_consecutive rejections
AUX_NIS = 7  # normalised innovation squared of the last valid frame (with the prior R)
N_AUX = 8

# Update status codes (per user and frame).
STATUS_SKIPPED = 0  # valid was False: no measurement
STATUS_ACCEPTED = 1
STATUS_REJECTED = 2  # failed the innovation gate
STATUS_FORCED = 3  # failed the gate but taken after too many consecutive rejections

# Measured error-state rows: position (0-2) and attitude (6-8).
_IDX = (0, 1, 2, 6, 7, 8)


@numba.njit(cache=True, inline="always")
def _qdot(qw, qx, qy, qz, wx, wy, wz):
    """``0.5 * q ⊗ [0, w]`` on scalars."""
    return (
        0.5 * (-qx * wx - qy * wy - qz * wz),
        0.5 * (qw * wx + qy * wz - qz * wy),
        0.5 * (qw * wy - qx * wz + qz * wx),
        0.5 * (qw * wz + qx * wy - qy * wx),
    )


@numba.njit(cache=True, inline="always")
def rk4_quat(qw, qx, qy, qz, ax, ay, az, bx, by, bz, dt):
    """One RK4 step of ``q_dot = 0.5 q ⊗ [0, w(t)]``, ``w`` linear from ``a`` to ``b``; unit q."""
    mx, my, mz = 0.5 * (ax + bx), 0.5 * (ay + by), 0.5 * (az + bz)
    h = 0.5 * dt
    k1w, k1x, k1y, k1z = _qdot(qw, qx, qy, qz, ax, ay, az)
    k2w, k2x, k2y, k2z = _qdot(qw + h * k1w, qx + h * k1x, qy + h * k1y, qz + h * k1z, mx, my, mz)
    k3w, k3x, k3y, k3z = _qdot(qw + h * k2w, qx + h * k2x, qy + h * k2y, qz + h * k2z, mx, my, mz)
    k4w, k4x, k4y, k4z = _qdot(
        qw + dt * k3w, qx + dt * k3x, qy + dt * k3y, qz + dt * k3z, bx, by, bz
    )
    s = dt / 6.0
    nw = qw + s * (k1w + 2.0 * k2w + 2.0 * k3w + k4w)
    nx = qx + s * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
    ny = qy + s * (k1y + 2.0 * k2y + 2.0 * k3y + k4y)
    nz = qz + s * (k1z + 2.0 * k2z + 2.0 * k3z + k4z)
    n = math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
    return nw / n, nx / n, ny / n, nz / n


@numba.njit(cache=True, inline="always")
def _rotmat(qw, qx, qy, qz, m):
    """Fill ``m`` (3, 3) with the rotation matrix of unit ``q`` (body -> world)."""
    xx, yy, zz = qx * qx, qy * qy, qz * qz
    xy, xz, yz = qx * qy, qx * qz, qy * qz
    wx, wy, wz = qw * qx, qw * qy, qw * qz
    m[0, 0] = 1.0 - 2.0 * (yy + zz)
    m[0, 1] = 2.0 * (xy - wz)
    m[0, 2] = 2.0 * (xz + wy)
    m[1, 0] = 2.0 * (xy + wz)
    m[1, 1] = 1.0 - 2.0 * (xx + zz)
    m[1, 2] = 2.0 * (yz - wx)
    m[2, 0] = 2.0 * (xz - wy)
    m[2, 1] = 2.0 * (yz + wx)
    m[2, 2] = 1.0 - 2.0 * (xx + yy)


@numba.njit(cache=True, inline="always")
def _mech_step(x, has_prev, w1x, w1y, w1z, f1x, f1y, f1z, dt, g, r0, r1, af):
    """Advance the nominal state ``x`` (N_X,) by one IMU interval, in place.

    RK4 attitude with the gyro linear between the previous and this sample; specific force of
    each end rotated with the attitude at that end, gravity added, trapezoid for v and p. Fills
    ``r1`` with the rotation matrix at the end and ``af`` with the world specific force there
    (bias-corrected): the ESKF's Jacobian needs both. ``r0`` is (3, 3) scratch.
    """
    bax, bay, baz = x[X_BA], x[X_BA + 1], x[X_BA + 2]
    bgx, bgy, bgz = x[X_BG], x[X_BG + 1], x[X_BG + 2]
    if has_prev:
        w0x, w0y, w0z = x[X_GYR], x[X_GYR + 1], x[X_GYR + 2]
        f0x, f0y, f0z = x[X_ACC], x[X_ACC + 1], x[X_ACC + 2]
    else:
        w0x, w0y, w0z = w1x, w1y, w1z
        f0x, f0y, f0z = f1x, f1y, f1z
    qw, qx, qy, qz = x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3]
    nw, nx, ny, nz = rk4_quat(
        qw, qx, qy, qz, w0x - bgx, w0y - bgy, w0z - bgz, w1x - bgx, w1y - bgy, w1z - bgz, dt
    )
    _rotmat(qw, qx, qy, qz, r0)
    _rotmat(nw, nx, ny, nz, r1)
    c0x, c0y, c0z = f0x - bax, f0y - bay, f0z - baz
    c1x, c1y, c1z = f1x - bax, f1y - bay, f1z - baz
    h = 0.5 * dt
    for i in range(3):
        a0 = r0[i, 0] * c0x + r0[i, 1] * c0y + r0[i, 2] * c0z
        a1 = r1[i, 0] * c1x + r1[i, 1] * c1y + r1[i, 2] * c1z
        af[i] = a1
        acc = a0 + a1
        if i == 2:
            acc -= 2.0 * g
        v0 = x[X_V + i]
        v1 = v0 + h * acc
        x[X_V + i] = v1
        x[X_P + i] = x[X_P + i] + h * (v0 + v1)
    x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3] = nw, nx, ny, nz
    x[X_GYR], x[X_GYR + 1], x[X_GYR + 2] = w1x, w1y, w1z
    x[X_ACC], x[X_ACC + 1], x[X_ACC + 2] = f1x, f1y, f1z


@numba.njit(cache=True)
def strapdown_run(x, has_prev, gyr, acc, dt, g, out_q, out_v, out_p):
    """Strapdown mechanisation of (B, N) samples; state ``x`` (B, N_X) and ``has_prev`` (B,) in
    place, per-sample outputs into ``out_q`` (B, N, 4), ``out_v``/``out_p`` (B, N, 3)."""
    r0 = np.empty((3, 3))
    r1 = np.empty((3, 3))
    af = np.empty(3)
    for b in range(gyr.shape[0]):
        xb = x[b]
        for k in range(gyr.shape[1]):
            _mech_step(
                xb, has_prev[b] != 0.0,
                gyr[b, k, 0], gyr[b, k, 1], gyr[b, k, 2],
                acc[b, k, 0], acc[b, k, 1], acc[b, k, 2],
                dt, g, r0, r1, af,
            )  # fmt: skip
            has_prev[b] = 1.0
            for i in range(4):
                out_q[b, k, i] = xb[X_Q + i]
            for i in range(3):
                out_v[b, k, i] = xb[X_V + i]
                out_p[b, k, i] = xb[X_P + i]


@numba.njit(cache=True, inline="always")
def _propagate_cov(P, r1, af, dt, qv, qth, qba, qbg, m, n):
    """``P <- F P F^T + Q`` with ``F = I + A dt`` and the sparse A of the ESKF, in place.

    ``A``: rows dp: ``dv``; rows dv: ``-[af x] dtheta - R dba``; rows dtheta: ``-R dbg``. With
    ``M = A P`` and ``N = M A^T`` (= A P A^T): ``P + dt (M + M^T) + dt^2 N + Q``, computed on
    the upper triangle and mirrored. ``m``, ``n`` are (15, 15) scratch.
    """
    ax, ay, az = af[0], af[1], af[2]
    # [af x] = [[0, -az, ay], [az, 0, -ax], [-ay, ax, 0]]
    for j in range(15):
        for i in range(3):
            m[i, j] = P[3 + i, j]
        p6, p7, p8 = P[6, j], P[7, j], P[8, j]
        # -[af x] P[6:9, j]
        m[3, j] = -(-az * p7 + ay * p8)
        m[4, j] = -(az * p6 - ax * p8)
        m[5, j] = -(-ay * p6 + ax * p7)
        for i in range(3):
            m[3 + i, j] -= r1[i, 0] * P[9, j] + r1[i, 1] * P[10, j] + r1[i, 2] * P[11, j]
            m[6 + i, j] = -(r1[i, 0] * P[12, j] + r1[i, 1] * P[13, j] + r1[i, 2] * P[14, j])
        for i in range(9, 15):
            m[i, j] = 0.0
    # N = M A^T: N[:, 0:3] = M[:, 3:6]; N[:, 3:6] = M[:, 6:9] [af x] - M[:, 9:12] R^T;
    # N[:, 6:9] = -M[:, 12:15] R^T; N[:, 9:15] = 0. Only rows 0-8 of M are nonzero.
    for i in range(9):
        for j in range(3):
            n[i, j] = m[i, 3 + j]
        m6, m7, m8 = m[i, 6], m[i, 7], m[i, 8]
        # row vector times [af x]: (u [a x])_j = sum_l u_l [a x]_{l j}
        n[i, 3] = m7 * az - m8 * ay
        n[i, 4] = -m6 * az + m8 * ax
        n[i, 5] = m6 * ay - m7 * ax
        for j in range(3):
            n[i, 3 + j] -= m[i, 9] * r1[j, 0] + m[i, 10] * r1[j, 1] + m[i, 11] * r1[j, 2]
            n[i, 6 + j] = -(m[i, 12] * r1[j, 0] + m[i, 13] * r1[j, 1] + m[i, 14] * r1[j, 2])
    dt2 = dt * dt
    for i in range(15):
        for j in range(i, 15):
            v = P[i, j] + dt * (m[i, j] + m[j, i])
            if i < 9 and j < 9:
                v += dt2 * n[i, j]
            P[i, j] = v
            P[j, i] = v
    for i in range(3):
        P[3 + i, 3 + i] += qv
        P[6 + i, 6 + i] += qth
        P[9 + i, 9 + i] += qba
        P[12 + i, 12 + i] += qbg


@numba.njit(cache=True)
def eskf_predict(x, P, aux, gyr, acc, dt, prm, out_p, out_q):
    """ESKF prediction over (B, N) IMU samples: mechanisation + covariance, in place."""
    g = prm[PRM_GRAVITY]
    r0 = np.empty((3, 3))
    r1 = np.empty((3, 3))
    af = np.empty(3)
    m = np.empty((15, 15))
    n = np.empty((15, 15))
    for b in range(gyr.shape[0]):
        xb = x[b]
        pb = P[b]
        s = aux[b, AUX_Q_SCALE] * dt
        qv = s * prm[PRM_ACC_NOISE] ** 2
        qth = s * prm[PRM_GYR_NOISE] ** 2
        qba = s * prm[PRM_ACC_WALK] ** 2
        qbg = s * prm[PRM_GYR_WALK] ** 2
        for k in range(gyr.shape[1]):
            _mech_step(
                xb, aux[b, AUX_HAS_PREV] != 0.0,
                gyr[b, k, 0], gyr[b, k, 1], gyr[b, k, 2],
                acc[b, k, 0], acc[b, k, 1], acc[b, k, 2],
                dt, g, r0, r1, af,
            )  # fmt: skip
            aux[b, AUX_HAS_PREV] = 1.0
            _propagate_cov(pb, r1, af, dt, qv, qth, qba, qbg, m, n)
            for i in range(3):
                out_p[b, k, i] = xb[X_P + i]
            for i in range(4):
                out_q[b, k, i] = xb[X_Q + i]


@numba.njit(cache=True, inline="always")
def _cholesky6(a, low):
    """Lower Cholesky factor of the SPD 6x6 ``a`` into ``low``; False if not positive definite."""
    for j in range(6):
        s = a[j, j]
        for k in range(j):
            s -= low[j, k] * low[j, k]
        if not s > 0.0:
            return False
        d = math.sqrt(s)
        low[j, j] = d
        for i in range(j + 1, 6):
            t = a[i, j]
            for k in range(j):
                t -= low[i, k] * low[j, k]
            low[i, j] = t / d
        for i in range(j):
            low[i, j] = 0.0
    return True


@numba.njit(cache=True, inline="always")
def _chol_solve6(low, rhs, out):
    """``out = (L L^T)^-1 rhs`` for a vector ``rhs`` (6,)."""
    for i in range(6):
        t = rhs[i]
        for k in range(i):
            t -= low[i, k] * out[k]
        out[i] = t / low[i, i]
    for i in range(5, -1, -1):
        t = out[i]
        for k in range(i + 1, 6):
            t -= low[k, i] * out[k]
        out[i] = t / low[i, i]


@numba.njit(cache=True, inline="always")
def _fading_weight(b, k):
    """Sage-Husa weight ``d_k = (1 - b) / (1 - b^(k+1))``."""
    return (1.0 - b) / (1.0 - b ** (k + 1.0))


@numba.njit(cache=True, inline="always")
def _adapt_r(Rb, nu, hph, d, prm, work):
    """Sage-Husa ``R <- (1 - d) R + d (nu nu^T - H P^- H^T)``, clamped (see VioConfig)."""
    if prm[PRM_DIAGONAL] != 0.0:
        for i in range(6):
            lo = prm[PRM_R_FLOOR_POS] if i < 3 else prm[PRM_R_FLOOR_ATT]
            hi = prm[PRM_R_CEIL_POS] if i < 3 else prm[PRM_R_CEIL_ATT]
            v = (1.0 - d) * Rb[i, i] + d * (nu[i] * nu[i] - hph[i, i])
            for j in range(6):
                Rb[i, j] = 0.0
            Rb[i, i] = min(max(v, lo), hi)
        return
    for i in range(6):
        for j in range(6):
            work[i, j] = (1.0 - d) * Rb[i, j] + d * (nu[i] * nu[j] - hph[i, j])
    for i in range(6):
        for j in range(i + 1, 6):
            v = 0.5 * (work[i, j] + work[j, i])
            work[i, j] = v
            work[j, i] = v
    lo = min(prm[PRM_R_FLOOR_POS], prm[PRM_R_FLOOR_ATT])
    hi = max(prm[PRM_R_CEIL_POS], prm[PRM_R_CEIL_ATT])
    w, vec = np.linalg.eigh(work)
    for i in range(6):
        w[i] = min(max(w[i], lo), hi)
    for i in range(6):
        for j in range(i, 6):
            v = 0.0
            for k in range(6):
                v += vec[i, k] * w[k] * vec[j, k]
            Rb[i, j] = v
            Rb[j, i] = v


@numba.njit(cache=True)
def eskf_update(x, P, R, aux, pos, quat, valid, prm, status):
    """ESKF update with a visual pose per user (rows with ``valid`` False are skipped)."""
    nu = np.empty(6)
    hph = np.empty((6, 6))
    s = np.empty((6, 6))
    low = np.empty((6, 6))
    tmp = np.empty(6)
    rhs = np.empty(6)
    gain = np.empty((15, 6))
    hp = np.empty((6, 15))
    a1 = np.empty((15, 15))
    work = np.empty((6, 6))
    dx = np.empty(15)
    for b in range(x.shape[0]):
        if not valid[b]:
            status[b] = STATUS_SKIPPED
            continue
        xb = x[b]
        pb = P[b]
        rb = R[b]
        # Innovation: position difference, and the world-frame small rotation
        # log(q_meas ⊗ q_est^-1), sign chosen so that its scalar part is >= 0.
        for i in range(3):
            nu[i] = pos[b, i] - xb[X_P + i]
        mw, mx, my, mz = quat[b, 0], quat[b, 1], quat[b, 2], quat[b, 3]
        mn = math.sqrt(mw * mw + mx * mx + my * my + mz * mz)
        mw, mx, my, mz = mw / mn, mx / mn, my / mn, mz / mn
        ew, ex, ey, ez = xb[X_Q], -xb[X_Q + 1], -xb[X_Q + 2], -xb[X_Q + 3]
        dw = mw * ew - mx * ex - my * ey - mz * ez
        dqx = mw * ex + mx * ew + my * ez - mz * ey
        dqy = mw * ey - mx * ez + my * ew + mz * ex
        dqz = mw * ez + mx * ey - my * ex + mz * ew
        if dw < 0.0:
            dw, dqx, dqy, dqz = -dw, -dqx, -dqy, -dqz
        sn = math.sqrt(dqx * dqx + dqy * dqy + dqz * dqz)
        if sn < 1e-8:
            sc = 2.0 / dw
        else:
            sc = 2.0 * math.atan2(sn, dw) / sn
        nu[3], nu[4], nu[5] = sc * dqx, sc * dqy, sc * dqz
        for i in range(6):
            for j in range(6):
                hph[i, j] = pb[_IDX[i], _IDX[j]]
                s[i, j] = hph[i, j] + rb[i, j]
        if not _cholesky6(s, low):
            status[b] = STATUS_REJECTED
            aux[b, AUX_REJECTED] += 1.0
            continue
        _chol_solve6(low, nu, tmp)
        nis = 0.0
        for i in range(6):
            nis += nu[i] * tmp[i]
        aux[b, AUX_NIS] = nis
        code = STATUS_ACCEPTED
        if nis > prm[PRM_GATE]:
            if aux[b, AUX_CONSEC] < prm[PRM_GATE_MAX]:
                aux[b, AUX_CONSEC] += 1.0
                aux[b, AUX_REJECTED] += 1.0
                status[b] = STATUS_REJECTED
                if prm[PRM_SAGE_HUSA] != 0.0:  # robust Sage-Husa: clipped to the gate (Huber)
                    clip = math.sqrt(prm[PRM_GATE] / nis)
                    for i in range(6):
                        tmp[i] = clip * nu[i]
                    k = aux[b, AUX_K]
                    _adapt_r(rb, tmp, hph, _fading_weight(prm[PRM_FORGET], k), prm, work)
                    aux[b, AUX_K] = k + 1.0
                continue
            code = STATUS_FORCED
            aux[b, AUX_FORCED] += 1.0
        aux[b, AUX_CONSEC] = 0.0
        k = aux[b, AUX_K]
        if prm[PRM_ADAPT_Q] != 0.0:
            dq_ = _fading_weight(prm[PRM_Q_FORGET], k)
            qs = aux[b, AUX_Q_SCALE] * (1.0 + dq_ * (nis / 6.0 - 1.0))
            aux[b, AUX_Q_SCALE] = min(max(qs, prm[PRM_Q_MIN]), prm[PRM_Q_MAX])
        if prm[PRM_SAGE_HUSA] != 0.0:
            _adapt_r(rb, nu, hph, _fading_weight(prm[PRM_FORGET], k), prm, work)
            for i in range(6):
                for j in range(6):
                    s[i, j] = hph[i, j] + rb[i, j]
            if not _cholesky6(s, low):  # cannot happen: R is clamped positive definite
                status[b] = STATUS_REJECTED
                aux[b, AUX_REJECTED] += 1.0
                continue
        aux[b, AUX_K] = k + 1.0
        # Gain K = P H^T S^-1, one row at a time (S symmetric: K^T = S^-1 H P).
        for r in range(15):
            for i in range(6):
                rhs[i] = pb[r, _IDX[i]]
            _chol_solve6(low, rhs, tmp)
            for i in range(6):
                gain[r, i] = tmp[i]
        for r in range(15):
            v = 0.0
            for i in range(6):
                v += gain[r, i] * nu[i]
            dx[r] = v
        # Joseph form: (I - K H) P (I - K H)^T + K R K^T.
        for i in range(6):
            for j in range(15):
                hp[i, j] = pb[_IDX[i], j]
        for r in range(15):
            for c in range(15):
                v = pb[r, c]
                for i in range(6):
                    v -= gain[r, i] * hp[i, c]
                a1[r, c] = v
        for i in range(6):
            for c in range(15):
                t = 0.0
                for j in range(6):
                    t += rb[i, j] * gain[c, j]
                hp[i, c] = t  # now R K^T
        for r in range(15):
            for c in range(r, 15):
                v = a1[r, c]
                for i in range(6):
                    v += gain[r, i] * hp[i, c] - a1[r, _IDX[i]] * gain[c, i]
                pb[r, c] = v
        for r in range(15):
            for c in range(r + 1, 15):
                pb[c, r] = pb[r, c]
        # Inject the error state into the nominal state.
        for i in range(3):
            xb[X_P + i] += dx[i]
            xb[X_V + i] += dx[3 + i]
            xb[X_BA + i] += dx[9 + i]
            xb[X_BG + i] += dx[12 + i]
        rx, ry, rz = dx[6], dx[7], dx[8]
        pw, px, py, pz = quat_from_rotvec(rx, ry, rz)
        qw, qx, qy, qz = xb[X_Q], xb[X_Q + 1], xb[X_Q + 2], xb[X_Q + 3]
        nw = pw * qw - px * qx - py * qy - pz * qz
        nx = pw * qx + px * qw + py * qz - pz * qy
        ny = pw * qy - px * qz + py * qw + pz * qx
        nz = pw * qz + px * qy - py * qx + pz * qw
        nn = math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
        xb[X_Q], xb[X_Q + 1], xb[X_Q + 2], xb[X_Q + 3] = nw / nn, nx / nn, ny / nn, nz / nn
        # Reset Jacobian of the world-frame attitude error: G = I + 0.5 [dtheta x] on rows/cols
        # 6-8, P <- G P G^T (rows first, then columns).
        hx, hy, hz = 0.5 * rx, 0.5 * ry, 0.5 * rz
        for c in range(15):
            p6, p7, p8 = pb[6, c], pb[7, c], pb[8, c]
            pb[6, c] = p6 - hz * p7 + hy * p8
            pb[7, c] = hz * p6 + p7 - hx * p8
            pb[8, c] = -hy * p6 + hx * p7 + p8
        for r in range(15):
            p6, p7, p8 = pb[r, 6], pb[r, 7], pb[r, 8]
            pb[r, 6] = p6 - hz * p7 + hy * p8
            pb[r, 7] = hz * p6 + p7 - hx * p8
            pb[r, 8] = -hy * p6 + hx * p7 + p8
        aux[b, AUX_UPDATES] += 1.0
        status[b] = code
