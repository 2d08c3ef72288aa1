"""Compiled per-user kernels of the helmet-tracking paper: strapdown mechanisation and the
visual-inertial ESKF.

* :func:`strapdown_run`: the strapdown mechanisation of
  :class:`estimators.head_pose.strapdown.Strapdown` (stage :func:`_mech_step`), checked against
  closed forms by ``tests/test_estimators/head_pose/test_strapdown.py``;
* :data:`predict_kernel`: the ESKF prediction, per IMU sample the stages :func:`_mech_step`
  (nominal state) and :func:`_propagate_cov` (covariance);
* :data:`update_kernel`: the ESKF update with one visual pose, in stages: :func:`_innovation`,
  :func:`_project` (``H P H^T`` and ``S``), the gate, :func:`_adapt_q`, :func:`_adapt_r`
  (Sage-Husa), :func:`_gain`, :func:`_joseph`, :func:`_inject` and :func:`_reset_cov`.

The filter (state, equations, choices) is described in :mod:`estimators.head_pose.visual_inertial`.
The two ESKF kernels are :class:`~estimators.kernels.BatchKernel` s over users with a serial build
only; their ``py_func`` is the readable reference that ``tests/test_kernels_compiled.py`` plays
against the compiled build.

Streams (users) are independent: every kernel loops over users outside and samples inside, with
no Python object in the loop, so a batch of B gives bit for bit the results of B single runs.

Layouts (filled by :mod:`estimators.head_pose.strapdown` and
:mod:`estimators.head_pose.visual_inertial`):

* nominal state ``x`` (N_X,) per user: the ``X_*`` offsets below, shared with the strapdown
  kernel; the last IMU sample is kept raw (bias not removed) so that a bias correction applies
  to both ends of the next interval.
* the filter's per-user state: a (B,) record array with the fields of :data:`STATE_FIELDS`;
* its parameters: the (1,) record of :meth:`estimators.head_pose.visual_inertial.VioConfig.packed`;
* per-user scratch: a (B,) record array with the fields of :data:`WORK_FIELDS`, allocated once
  by the filter, so that no step allocates and users share no memory.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from estimators.kernels.batch import BatchKernel
from estimators.kernels.records import state_records
from estimators.kernels.rotations import quat_from_rotvec, quat_mul, rotation_matrix

# Nominal state, per user.
X_P = 0  # position, world, m (3)
X_V = 3  # velocity, world, m/s (3)
X_Q = 6  # attitude quaternion body -> world [w, x, y, z] (4)
X_BA = 10  # accelerometer bias, m/s^2 (3)
X_BG = 13  # gyro bias, rad/s (3)
X_GYR = 16  # previous raw gyro sample, rad/s (3)
X_ACC = 19  # previous raw specific-force sample, m/s^2 (3)
N_X = 22

#: The filter's per-user state (record fields and shapes).
STATE_FIELDS = {
    "x": (N_X,),  # nominal state, ``X_*`` offsets
    "P": (15, 15),  # error-state covariance (m, m/s, rad, m/s^2, rad/s)
    "R": (6, 6),  # measurement covariance (m^2, rad^2)
    "has_prev": (),  # 1.0 once an IMU sample has been seen (first-order hold possible)
    "k": (),  # fading-memory count k of d_k (prior frames + frames in the R estimate)
    "q_scale": (),  # current Q scale factor
    "consec": (),  # consecutive gate rejections
    "updates": (),  # accepted (incl. forced) updates since reset
    "rejected": (),  # gate rejections since reset
    "forced": (),  # frames taken after gate_max_consecutive rejections
    "nis": (),  # normalised innovation squared of the last valid frame (with the prior R)
}

#: Per-user scratch of the two ESKF kernels.
WORK_FIELDS = {
    "r0": (3, 3),  # rotation at the start of the IMU interval
    "r1": (3, 3),  # rotation at its end
    "af": (3,),  # world specific force at its end (bias-corrected)
    "m": (15, 15),  # A P
    "n": (15, 15),  # A P A^T
    "nu": (6,),  # innovation
    "hph": (6, 6),  # H P^- H^T
    "s": (6, 6),  # innovation covariance S
    "low": (6, 6),  # its Cholesky factor
    "tmp": (6,),
    "rhs": (6,),
    "gain": (15, 6),  # K
    "hp": (6, 15),  # H P, then R K^T
    "a1": (15, 15),  # (I - K H) P
    "work": (6, 6),  # raw Sage-Husa estimate (full mode)
    "dx": (15,),  # error-state correction
}

# Update status codes (per user and frame).
STATUS_SKIPPED = 0  # valid was False: no measurement
STATUS_ACCEPTED = 1
STATUS_REJECTED = 2  # failed the innovation gate
STATUS_FORCED = 3  # failed the gate but taken after too many consecutive rejections

# Measured error-state rows: position (0-2) and attitude (6-8).
_IDX = (0, 1, 2, 6, 7, 8)


def records(fields: dict, batch_size: int) -> np.ndarray:
    """Zeroed (B,) record array of ``fields`` whose elements read fields as attributes
    (``s = state[i]; s.P``) in Python too, as they do in the kernels."""
    out = state_records(fields, batch_size)
    return out.view(np.dtype((np.record, out.dtype)))


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


# ------------------------------------------------------------------------------------------------
# Prediction stages.
# ------------------------------------------------------------------------------------------------


@numba.njit(cache=True, inline="always")
def _mech_step(x, has_prev, w1, f1, dt, g, r0, r1, af):
    """Advance the nominal state ``x`` (N_X,) by one IMU interval ending at the raw gyro and
    specific-force samples ``w1``, ``f1`` (3,), in place.

    RK4 attitude with the gyro linear between the previous and this sample (this sample held
    over the interval without ``has_prev``); specific force of each end rotated with the attitude
    at that end, gravity ``g`` added, trapezoid for v and p. Fills ``r1`` with the rotation
    matrix at the end and ``af`` with the world specific force there (bias-corrected): the
    ESKF's Jacobian needs both. ``r0`` is (3, 3) scratch.
    """
    w1x, w1y, w1z = w1[0], w1[1], w1[2]
    f1x, f1y, f1z = f1[0], f1[1], f1[2]
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
    rotation_matrix(qw, qx, qy, qz, r0)
    rotation_matrix(nw, nx, ny, nz, r1)
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
            _mech_step(xb, has_prev[b] != 0.0, gyr[b, k], acc[b, k], dt, g, r0, r1, af)
            has_prev[b] = 1.0
            for i in range(4):
                out_q[b, k, i] = xb[X_Q + i]
            for i in range(3):
                out_v[b, k, i] = xb[X_V + i]
                out_p[b, k, i] = xb[X_P + i]


@numba.njit(cache=True, inline="always")
def _process_noise(q_scale, dt, p):
    """Diagonal of ``Q`` per block (dv, dtheta, db_a, db_g) for the Q scale ``q_scale``."""
    s = q_scale * dt
    return (
        s * p.accel_noise_density**2,
        s * p.gyro_noise_density**2,
        s * p.accel_bias_walk**2,
        s * p.gyro_bias_walk**2,
    )


@numba.njit(cache=True, inline="always")
def _propagate_cov(P, r1, af, dt, q, m, n):
    """``P <- F P F^T + Q`` with ``F = I + A dt`` and the sparse A of the ESKF, in place.

    ``A``: rows dp: ``dv``; rows dv: ``-[af x] dtheta - R dba``; rows dtheta: ``-R dbg``. With
    ``M = A P`` and ``N = M A^T`` (= A P A^T): ``P + dt (M + M^T) + dt^2 N + Q``, computed on
    the upper triangle and mirrored. ``q`` is :func:`_process_noise`; ``m``, ``n`` are (15, 15)
    scratch.
    """
    qv, qth, qba, qbg = q
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


def _predict(state, prm, gyr, acc, dt, out_p, out_q, work):
    """ESKF prediction over (B, N) IMU samples ``gyr`` (rad/s), ``acc`` (m/s^2) at interval
    ``dt`` (s): mechanisation and covariance of each user's ``state`` record, in place; the
    position and attitude after each sample into ``out_p`` (B, N, 3) and ``out_q`` (B, N, 4)."""
    p = prm[0]
    for i in numba.prange(gyr.shape[0]):
        s = state[i]
        w = work[i]
        x = s.x
        P = s.P
        q = _process_noise(s.q_scale, dt, p)
        for k in range(gyr.shape[1]):
            _mech_step(x, s.has_prev != 0.0, gyr[i, k], acc[i, k], dt, p.gravity, w.r0, w.r1, w.af)
            s.has_prev = 1.0
            _propagate_cov(P, w.r1, w.af, dt, q, w.m, w.n)
            for j in range(3):
                out_p[i, k, j] = x[X_P + j]
            for j in range(4):
                out_q[i, k, j] = x[X_Q + j]


#: ESKF prediction kernel, ``predict_kernel(B)(state, prm, gyr, acc, dt, out_p, out_q, work)``.
predict_kernel = BatchKernel(_predict, parallel=False)


# ------------------------------------------------------------------------------------------------
# Update stages.
# ------------------------------------------------------------------------------------------------


@numba.njit(cache=True, inline="always")
def _innovation(x, pos, quat, nu):
    """``nu`` (6,) = [position difference, world-frame small rotation log(q_meas ⊗ q_est^-1)]
    of the measured pose ``pos`` (3,), ``quat`` (4,) of any norm; the sign of the quaternion
    difference is chosen so that its scalar part is >= 0."""
    for i in range(3):
        nu[i] = pos[i] - x[X_P + i]
    mw, mx, my, mz = quat[0], quat[1], quat[2], quat[3]
    mn = math.sqrt(mw * mw + mx * mx + my * my + mz * mz)
    mw, mx, my, mz = mw / mn, mx / mn, my / mn, mz / mn
    dw, dqx, dqy, dqz = quat_mul(mw, mx, my, mz, x[X_Q], -x[X_Q + 1], -x[X_Q + 2], -x[X_Q + 3])
    if dw < 0.0:
        dw, dqx, dqy, dqz = -dw, -dqx, -dqy, -dqz
    sn = math.sqrt(dqx * dqx + dqy * dqy + dqz * dqz)
    if sn < 1e-8:
        sc = 2.0 / dw
    else:
        sc = 2.0 * math.atan2(sn, dw) / sn
    nu[3], nu[4], nu[5] = sc * dqx, sc * dqy, sc * dqz


@numba.njit(cache=True, inline="always")
def _innovation_cov(hph, R, s):
    """``S = H P^- H^T + R`` into ``s``."""
    for i in range(6):
        for j in range(6):
            s[i, j] = hph[i, j] + R[i, j]


@numba.njit(cache=True, inline="always")
def _project(P, R, hph, s):
    """``H P^- H^T`` into ``hph`` and ``S`` into ``s``."""
    for i in range(6):
        for j in range(6):
            hph[i, j] = P[_IDX[i], _IDX[j]]
    _innovation_cov(hph, R, s)


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
def _adapt_q(s, p, k, nis):
    """Q scale ``alpha <- clip(alpha (1 + d_q (nis / 6 - 1)), q_scale_bounds)`` of record ``s``."""
    dq_ = _fading_weight(p.q_forgetting, k)
    qs = s.q_scale * (1.0 + dq_ * (nis / 6.0 - 1.0))
    s.q_scale = min(max(qs, p.q_min), p.q_max)


@numba.njit(cache=True, inline="always")
def _adapt_r(R, nu, hph, d, p, work):
    """Sage-Husa ``R <- (1 - d) R + d (nu nu^T - H P^- H^T)``, clamped (see VioConfig)."""
    if p.sage_husa_diagonal != 0.0:
        for i in range(6):
            lo = p.r_floor_pos if i < 3 else p.r_floor_att
            hi = p.r_ceil_pos if i < 3 else p.r_ceil_att
            v = (1.0 - d) * R[i, i] + d * (nu[i] * nu[i] - hph[i, i])
            for j in range(6):
                R[i, j] = 0.0
            R[i, i] = min(max(v, lo), hi)
        return
    for i in range(6):
        for j in range(6):
            work[i, j] = (1.0 - d) * R[i, j] + d * (nu[i] * nu[j] - hph[i, j])
    for i in range(6):
        for j in range(i + 1, 6):
            v = 0.5 * (work[i, j] + work[j, i])
            work[i, j] = v
            work[j, i] = v
    lo = min(p.r_floor_pos, p.r_floor_att)
    hi = max(p.r_ceil_pos, p.r_ceil_att)
    w, vec = np.linalg.eigh(work)
    for i in range(6):
        w[i] = min(max(w[i], lo), hi)
    for i in range(6):
        for j in range(i, 6):
            v = 0.0
            for k in range(6):
                v += vec[i, k] * w[k] * vec[j, k]
            R[i, j] = v
            R[j, i] = v


@numba.njit(cache=True, inline="always")
def _adapt_r_refused(s, p, nis, w):
    """Robust Sage-Husa step of a frame the gate refused: its innovation clipped to the gate
    (Huber), ``k`` advanced."""
    clip = math.sqrt(p.gate / nis)
    tmp = w.tmp
    nu = w.nu
    for i in range(6):
        tmp[i] = clip * nu[i]
    k = s.k
    _adapt_r(s.R, tmp, w.hph, _fading_weight(p.forgetting, k), p, w.work)
    s.k = k + 1.0


@numba.njit(cache=True, inline="always")
def _gain(P, low, nu, w):
    """Gain ``K = P H^T S^-1`` into ``w.gain``, one row at a time (S symmetric:
    ``K^T = S^-1 H P``), and the correction ``dx = K nu`` into ``w.dx``."""
    gain, rhs, tmp, dx = w.gain, w.rhs, w.tmp, w.dx
    for r in range(15):
        for i in range(6):
            rhs[i] = P[r, _IDX[i]]
        _chol_solve6(low, rhs, tmp)
        for i in range(6):
            gain[r, i] = tmp[i]
    for r in range(15):
        v = 0.0
        for i in range(6):
            v += gain[r, i] * nu[i]
        dx[r] = v


@numba.njit(cache=True, inline="always")
def _joseph(P, R, gain, hp, a1):
    """Joseph form ``P <- (I - K H) P (I - K H)^T + K R K^T``, in place; ``hp`` (6, 15) and
    ``a1`` (15, 15) scratch."""
    for i in range(6):
        for j in range(15):
            hp[i, j] = P[_IDX[i], j]
    for r in range(15):
        for c in range(15):
            v = P[r, c]
            for i in range(6):
                v -= gain[r, i] * hp[i, c]
            a1[r, c] = v
    for i in range(6):
        for c in range(15):
            t = 0.0
            for j in range(6):
                t += R[i, j] * gain[c, j]
            hp[i, c] = t  # now R K^T
    for r in range(15):
        for c in range(r, 15):
            v = a1[r, c]
            for i in range(6):
                v += gain[r, i] * hp[i, c] - a1[r, _IDX[i]] * gain[c, i]
            P[r, c] = v
    for r in range(15):
        for c in range(r + 1, 15):
            P[c, r] = P[r, c]


@numba.njit(cache=True, inline="always")
def _inject(x, dx):
    """Inject the error state ``dx`` (15,) into the nominal state ``x``: additive for p, v and
    the biases, ``q <- normalise(exp(dtheta) ⊗ q)``."""
    for i in range(3):
        x[X_P + i] += dx[i]
        x[X_V + i] += dx[3 + i]
        x[X_BA + i] += dx[9 + i]
        x[X_BG + i] += dx[12 + i]
    pw, px, py, pz = quat_from_rotvec(dx[6], dx[7], dx[8])
    nw, nx, ny, nz = quat_mul(pw, px, py, pz, x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3])
    nn = math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
    x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3] = nw / nn, nx / nn, ny / nn, nz / nn


@numba.njit(cache=True, inline="always")
def _reset_cov(P, dx):
    """Reset Jacobian of the world-frame attitude error: ``G = I + 0.5 [dtheta x]`` on rows and
    columns 6-8, ``P <- G P G^T`` (rows first, then columns)."""
    hx, hy, hz = 0.5 * dx[6], 0.5 * dx[7], 0.5 * dx[8]
    for c in range(15):
        p6, p7, p8 = P[6, c], P[7, c], P[8, c]
        P[6, c] = p6 - hz * p7 + hy * p8
        P[7, c] = hz * p6 + p7 - hx * p8
        P[8, c] = -hy * p6 + hx * p7 + p8
    for r in range(15):
        p6, p7, p8 = P[r, 6], P[r, 7], P[r, 8]
        P[r, 6] = p6 - hz * p7 + hy * p8
        P[r, 7] = hz * p6 + p7 - hx * p8
        P[r, 8] = -hy * p6 + hx * p7 + p8


def _update(state, prm, pos, quat, valid, status, work):
    """ESKF update of each user's ``state`` record with its visual pose ``pos`` (B, 3) m,
    ``quat`` (B, 4); users with ``valid`` False are skipped. Status codes into ``status`` (B,)."""
    p = prm[0]
    for i in numba.prange(pos.shape[0]):
        if not valid[i]:
            status[i] = STATUS_SKIPPED
            continue
        s = state[i]
        w = work[i]
        P = s.P
        R = s.R
        nu = w.nu
        _innovation(s.x, pos[i], quat[i], nu)
        _project(P, R, w.hph, w.s)
        if not _cholesky6(w.s, w.low):
            status[i] = STATUS_REJECTED
            s.rejected += 1.0
            continue
        _chol_solve6(w.low, nu, w.tmp)
        nis = 0.0
        for j in range(6):
            nis += nu[j] * w.tmp[j]
        s.nis = nis
        code = STATUS_ACCEPTED
        if nis > p.gate:
            if s.consec < p.gate_max_consecutive:
                s.consec += 1.0
                s.rejected += 1.0
                status[i] = STATUS_REJECTED
                if p.sage_husa != 0.0:
                    _adapt_r_refused(s, p, nis, w)
                continue
            code = STATUS_FORCED
            s.forced += 1.0
        s.consec = 0.0
        k = s.k
        if p.adapt_q != 0.0:
            _adapt_q(s, p, k, nis)
        if p.sage_husa != 0.0:
            _adapt_r(R, nu, w.hph, _fading_weight(p.forgetting, k), p, w.work)
            _innovation_cov(w.hph, R, w.s)
            if not _cholesky6(w.s, w.low):  # cannot happen: R is clamped positive definite
                status[i] = STATUS_REJECTED
                s.rejected += 1.0
                continue
        s.k = k + 1.0
        _gain(P, w.low, nu, w)
        _joseph(P, R, w.gain, w.hp, w.a1)
        _inject(s.x, w.dx)
        _reset_cov(P, w.dx)
        s.updates += 1.0
        status[i] = code


#: ESKF update kernel, ``update_kernel(B)(state, prm, pos, quat, valid, status, work)``.
update_kernel = BatchKernel(_update, parallel=False)
