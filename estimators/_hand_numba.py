"""Compiled kernel of the hand pipeline (see :mod:`estimators.hand`).

This module is the fast mirror of :meth:`estimators.hand.HandPipeline.update_reference`, which
chains the readable numpy stages :func:`~estimators.hand.select_target`,
:class:`~estimators.joint_smoothing.HoltSmoother` and :class:`~estimators.hand.OrientationFilter`
(eq (1)/(2), :class:`~estimators.hand.EulerKalman`, :class:`~estimators.hand.StreamingMedian`).
Those classes document the mathematics and the semantics (dropouts, reselection, inferred joints,
wrap-around); this kernel evaluates the same formulas in the same order, with explicit loops
over streams, body slots and joints. Only numpy's reductions (vector norms, ``einsum``) may add
in another order, so the two agree to the last bit or two: ``tests/test_hand.py`` checks 1e-12
on sequences that exercise every branch. Numba cannot call the broadcasting helpers of
:mod:`estimators.rotations`, so ``wrap_angle`` is written out here on scalars with the same
definition (``pi - mod(pi - a, 2 pi)``, floored modulo, which numba's float ``%`` implements as
numpy does).

Why a kernel: at B = 1 one frame of the numpy stages is well over a hundred small numpy calls,
about 0.35 ms of interpreter overhead; the kernel does the frame in about 2 us (plus some 10 us of
Python around it), and ``HandPipeline.update_frames`` takes the M frames of a control step in one
call (``benchmarks/bench_hand.py`` has the figures).

The filters' state stays in the reference objects' arrays (``HandPipeline.holt``,
``HandPipeline.orientation``), which the kernel updates in place, so the two paths can be mixed
and ``reset`` is shared. Frames are laid out row-major as ``r = b * M + t`` (B streams of M
frames) for inputs and outputs; streams are independent, so the loop runs over streams outside
and frames inside. The Holt ring's newest entry is global (one index for all streams): at frame
``t`` it is ``(head0 - 1 - t) mod n``, as ``HoltSmoother`` advances it once per frame; the
weighted average sums over ages, newest first, as ``HoltSmoother`` does, so a stream's numbers
do not depend on where the ring stands.

The packed parameter vectors are filled by :meth:`estimators.hand.HandPipeline` from
:class:`~estimators.hand.HandParams`; their layouts are the ``F_*`` and ``I_*`` indices below.
"""

from __future__ import annotations

import math

import numba
import numpy as np

# Packed float parameters (float64 vector).
F_SMOOTHING = 0  # Holt smoothing, [0, 1)
F_CORRECTION = 1  # Holt correction, [0, 1]
F_PREDICTION = 2  # Holt prediction, frames
F_JITTER = 3  # Holt jitter radius, m
F_MAX_DEV = 4  # Holt max deviation radius, m
F_INFERRED_SCALE = 5  # radius factor for inferred joints
F_DT = 6  # Kalman frame period, s
F_DT2_2 = 7  # dt^2 / 2, s^2 (computed in Python, as EulerKalman does)
F_DT3_3 = 8  # dt^3 / 3, s^3
F_LAM = 9  # innovation low-pass gain per frame
F_THRESHOLD = 10  # eq (2) threshold on |wy - zx|
F_R = 11  # 3 values: measurement variance per axis, rad^2
F_Q = 14  # 3 values: accel PSD at rest, rad^2/s^3
F_Q_MAX = 17  # 3 values: cap of the adapted PSD, rad^2/s^3
F_P11_INIT = 20  # 3 values: initial rate variance, rad^2/s^2
N_F = 23

# Packed integer parameters (int64 vector).
I_WRIST = 0  # wrist joint index
I_MIN_WRIST_STATE = 1  # 1 inferred accepted, 2 tracked only
I_MAX_COAST = 2  # Kalman coasting frames before a stream goes stale
N_I = 3

# Error codes of :func:`validate` (the reference raises them in this order within a frame).
ERR_JOINTS_INF = 1
ERR_QUAT_INF = 2
ERR_STATE_RANGE = 3
ERR_NEGATIVE_ID = 4
ERR_DUPLICATE_ID = 5

_MIN_QUAT_NORM = 1e-6  # as estimators.hand._MIN_QUAT_NORM
_TWO_PI = 2.0 * np.pi


@numba.njit(cache=True, inline="always")
def _wrap(a):
    """``pi - mod(pi - a, 2 pi)`` with numpy's floored float modulo: (-pi, pi], NaN stays NaN."""
    x = math.pi - a
    if 0.0 <= x < _TWO_PI:  # the usual case, where the modulo returns x itself: skip its fmod
        return math.pi - x
    # numba's float % is Python's floored modulo (fmod, then shifted to the divisor's sign,
    # +0.0 for an exact zero), the same algorithm as numpy's np.mod for float64.
    return math.pi - x % _TWO_PI


@numba.njit(cache=True)
def _any_error(ids, joints, state, quat, joints_flat):
    """True if any row has an infinite value, a state outside {0, 1, 2} or a negative id.

    Branch-free per value so that the loops run at memory speed. ``joints_flat`` is ``joints``
    as one contiguous 1-D view, or empty where ``joints`` is not contiguous: the flat loop
    vectorises, the nested one does not (0.012 against 0.045 ms for B = 256 on the dev machine).
    """
    bad = False
    for r in range(ids.shape[0]):
        for k in range(ids.shape[1]):
            bad |= ids[r, k] < 0
            for c in range(4):
                bad |= abs(quat[r, k, c]) == np.inf
            for j in range(state.shape[2]):
                s = state[r, k, j]
                bad |= (s < 0) | (s > 2)
    if joints_flat.size == joints.size:
        for i in range(joints_flat.size):
            bad |= abs(joints_flat[i]) == np.inf
    else:
        for r in range(joints.shape[0]):
            for k in range(joints.shape[1]):
                for j in range(joints.shape[2]):
                    for c in range(3):
                        bad |= abs(joints[r, k, j, c]) == np.inf
    return bad


@numba.njit(cache=True)
def _any_duplicate(ids):
    """True if a row holds the same non-zero id in two slots."""
    for r in range(ids.shape[0]):
        for k in range(ids.shape[1]):
            if ids[r, k] != 0:
                for k2 in range(k + 1, ids.shape[1]):
                    if ids[r, k2] == ids[r, k]:
                        return True
    return False


@numba.njit(cache=True)
def validate(ids, joints, state, quat, b, m, joints_flat):
    """First input error, frame by frame, in the reference's order; ``(code, frame)`` or (0, -1).

    Args:
        ids: (B*M, K) int body ids. joints: (B*M, K, J, 3) float64. state: (B*M, K, J) int.
        quat: (B*M, K, 4) float64. b, m: B and M (row ``r = b * M + t``).
        joints_flat: ``joints.reshape(-1)`` where ``joints`` is C-contiguous, else empty (1-D).
    """
    nk = ids.shape[1]
    nj = state.shape[2]
    if not _any_error(ids, joints, state, quat, joints_flat) and not _any_duplicate(ids):
        return 0, -1  # the usual case, found at memory speed
    for t in range(m):
        for code in range(1, 6):
            for i in range(b):
                r = i * m + t
                for k in range(nk):
                    if code == ERR_JOINTS_INF:
                        for j in range(nj):
                            for c in range(3):
                                if math.isinf(joints[r, k, j, c]):
                                    return code, t
                    elif code == ERR_QUAT_INF:
                        for c in range(4):
                            if math.isinf(quat[r, k, c]):
                                return code, t
                    elif code == ERR_STATE_RANGE:
                        for j in range(nj):
                            if state[r, k, j] < 0 or state[r, k, j] > 2:
                                return code, t
                    elif code == ERR_NEGATIVE_ID:
                        if ids[r, k] < 0:
                            return code, t
                    else:
                        if ids[r, k] != 0:
                            for k2 in range(k + 1, nk):
                                if ids[r, k2] == ids[r, k]:
                                    return code, t
    return 0, -1


@numba.njit(cache=True, inline="always")
def _body_distance(joints, state, r, k, center):
    """Distance (m) of body ``k``'s centre (mean of its valid centre joints) from the sensor."""
    n = 0
    sx = 0.0
    sy = 0.0
    sz = 0.0
    for ci in range(center.shape[0]):
        jc = center[ci]
        x = joints[r, k, jc, 0]
        y = joints[r, k, jc, 1]
        z = joints[r, k, jc, 2]
        if state[r, k, jc] >= 1 and math.isfinite(x) and math.isfinite(y) and math.isfinite(z):
            sx += x
            sy += y
            sz += z
            n += 1
    if n == 0:
        return np.inf
    cx = sx / n
    cy = sy / n
    cz = sz / n
    return math.sqrt(cx * cx + cy * cy + cz * cz)


@numba.njit(cache=True, inline="always")
def _holt_step(x0, x1, x2, count, raw, filt, trend, b, j, valid, jitter_r, max_dev_r, s, c, k):
    """One HoltSmoother step of joint ``j`` of stream ``b`` (raw sample ``x``, 0 if invalid).

    Updates ``count``, ``raw``, ``filt``, ``trend`` in place as ``HoltSmoother.update`` does and
    returns the output ``p`` (after the max-deviation pull), m.
    """
    cnt = count[b, j]
    f0p = filt[b, j, 0]
    f1p = filt[b, j, 1]
    f2p = filt[b, j, 2]
    b0p = trend[b, j, 0]
    b1p = trend[b, j, 1]
    b2p = trend[b, j, 2]
    if cnt == 0:
        f0, f1, f2 = x0, x1, x2
        b0 = b1 = b2 = 0.0
    else:
        if cnt == 1:
            f0 = 0.5 * (x0 + raw[b, j, 0])
            f1 = 0.5 * (x1 + raw[b, j, 1])
            f2 = 0.5 * (x2 + raw[b, j, 2])
        else:
            d0, d1, d2 = x0 - f0p, x1 - f1p, x2 - f2p
            a = min(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) / jitter_r, 1.0)
            f0 = (x0 * a + f0p * (1.0 - a)) * (1.0 - s) + (f0p + b0p) * s
            f1 = (x1 * a + f1p * (1.0 - a)) * (1.0 - s) + (f1p + b1p) * s
            f2 = (x2 * a + f2p * (1.0 - a)) * (1.0 - s) + (f2p + b2p) * s
        b0 = c * (f0 - f0p) + (1.0 - c) * b0p
        b1 = c * (f1 - f1p) + (1.0 - c) * b1p
        b2 = c * (f2 - f2p) + (1.0 - c) * b2p
    p0 = f0 + k * b0
    p1 = f1 + k * b1
    p2 = f2 + k * b2
    e0, e1, e2 = p0 - x0, p1 - x1, p2 - x2
    dev = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    if dev > max_dev_r:
        pull = max_dev_r / max(dev, 1e-300)
        p0 = p0 * pull + x0 * (1.0 - pull)
        p1 = p1 * pull + x1 * (1.0 - pull)
        p2 = p2 * pull + x2 * (1.0 - pull)
    if valid:
        raw[b, j, 0] = x0
        raw[b, j, 1] = x1
        raw[b, j, 2] = x2
        filt[b, j, 0] = f0
        filt[b, j, 1] = f1
        filt[b, j, 2] = f2
        trend[b, j, 0] = b0
        trend[b, j, 1] = b1
        trend[b, j, 2] = b2
        count[b, j] = min(cnt + 1, 2)
    else:
        trend[b, j, 0] = 0.0
        trend[b, j, 1] = 0.0
        trend[b, j, 2] = 0.0
        count[b, j] = 0
    return p0, p1, p2


@numba.njit(cache=True)
def hand_frames(
    ids,
    tracked,
    joints,
    state,
    quat,
    b_count,
    m_count,
    center,
    fprm,
    iprm,
    weights,
    head0,
    target_id,
    h_count,
    h_raw,
    h_filt,
    h_trend,
    h_hist,
    h_hist_ok,
    h_out,
    k_angle,
    k_rate,
    k_p00,
    k_p01,
    k_p11,
    k_active,
    k_missed,
    k_init_now,
    k_nis,
    m_buf,
    m_last,
    o_raw,
    o_kf,
    out_slot,
    out_id,
    out_changed,
    out_has,
    out_joints,
    out_state,
    out_all_inferred,
    out_ypr_raw,
    out_ypr_kalman,
    out_ypr,
    out_quat_valid,
    out_singular,
    out_valid,
):
    """Run the hand pipeline over M frames of B streams (inputs already validated).

    Inputs (rows ``r = b * M + t``): ``ids`` (B*M, K) int, ``tracked`` (B*M, K) bool, ``joints``
    (B*M, K, J, 3) m, ``state`` (B*M, K, J) int, ``quat`` (B*M, K, 4). ``center`` (C,) centre
    joint indices, ``fprm``/``iprm`` the packed parameters, ``weights`` (n,) the normalised Holt
    average weights (newest first), ``head0`` the Holt ring's newest index before the first frame.

    State (updated in place): ``target_id`` (B,); Holt ``h_count`` (B, J), ``h_raw``, ``h_filt``,
    ``h_trend``, ``h_out`` (B, J, 3), ``h_hist`` (n, B, J, 3), ``h_hist_ok`` (n, B, J); Kalman
    ``k_*`` (B, 3) and (B,); median ``m_buf`` (W, B, 3), ``m_last`` (B, 3); held raw and Kalman
    outputs ``o_raw``, ``o_kf`` (B, 3).

    Outputs (rows ``r``): the :class:`~estimators.hand.HandFrame` fields.
    """
    nk = ids.shape[1]
    nj = state.shape[2]
    n_hist = weights.shape[0]
    win = m_buf.shape[0]
    smoothing = fprm[F_SMOOTHING]
    correction = fprm[F_CORRECTION]
    prediction = fprm[F_PREDICTION]
    jitter = fprm[F_JITTER]
    max_dev = fprm[F_MAX_DEV]
    inferred_scale = fprm[F_INFERRED_SCALE]
    dt = fprm[F_DT]
    dt2_2 = fprm[F_DT2_2]
    dt3_3 = fprm[F_DT3_3]
    lam = fprm[F_LAM]
    threshold = fprm[F_THRESHOLD]
    wrist = iprm[I_WRIST]
    min_wrist_state = iprm[I_MIN_WRIST_STATE]
    max_coast = iprm[I_MAX_COAST]
    sorted_buf = np.empty(win)
    ypr = np.empty(3)
    # The ring's newest index at frame t, and the ring index of each age (newest first): both
    # depend on t only.
    heads = np.empty(m_count, np.int64)
    ring = np.empty((m_count, n_hist), np.int64)
    for t in range(m_count):
        heads[t] = (head0 - 1 - t) % n_hist
        for i in range(n_hist):
            ring[t, i] = (heads[t] + i) % n_hist

    for b in range(b_count):
        for t in range(m_count):
            r = b * m_count + t
            # ---- target selection (select_target)
            cur = target_id[b]
            keep = -1
            nearest = 0
            best = np.inf
            for k in range(nk):
                present = tracked[r, k] and ids[r, k] != 0
                if not present:
                    continue
                if keep < 0 and cur != 0 and ids[r, k] == cur:
                    keep = k
                d = _body_distance(joints, state, r, k, center)
                if d < best:
                    best = d
                    nearest = k
            if keep >= 0:
                slot = keep
            elif math.isfinite(best):
                slot = nearest
            else:
                slot = -1
            new_id = ids[r, slot] if slot >= 0 else 0
            changed = new_id != cur and new_id != 0
            target_id[b] = new_id
            has = slot >= 0
            out_slot[r] = slot
            out_id[r] = new_id
            out_changed[r] = changed
            out_has[r] = has

            # ---- Holt smoother (HoltSmoother.reset, then HoltSmoother.update)
            if changed:
                for j in range(nj):
                    h_count[b, j] = 0
                    for c in range(3):
                        h_trend[b, j, c] = 0.0
                        h_out[b, j, c] = np.nan
                    for i in range(n_hist):
                        h_hist_ok[i, b, j] = 0.0
            head = heads[t]
            any_tracked = False
            any_inferred = False
            for j in range(nj):
                st = state[r, slot, j] if has else 0
                out_state[r, j] = st
                if st == 2:
                    any_tracked = True
                elif st == 1:
                    any_inferred = True
                if has:
                    x0 = joints[r, slot, j, 0]
                    x1 = joints[r, slot, j, 1]
                    x2 = joints[r, slot, j, 2]
                    valid = (
                        st >= 1 and math.isfinite(x0) and math.isfinite(x1) and math.isfinite(x2)
                    )
                else:
                    valid = False
                if not valid:
                    x0 = x1 = x2 = 0.0
                scale = inferred_scale if st == 1 else 1.0
                p0, p1, p2 = _holt_step(
                    x0,
                    x1,
                    x2,
                    h_count,
                    h_raw,
                    h_filt,
                    h_trend,
                    b,
                    j,
                    valid,
                    jitter * scale,
                    max_dev * scale,
                    smoothing,
                    correction,
                    prediction,
                )
                if not valid:
                    for c in range(3):
                        h_out[b, j, c] = np.nan
                        out_joints[r, j, c] = np.nan
                    if n_hist > 1:
                        for c in range(3):
                            h_hist[head, b, j, c] = 0.0
                        for i in range(n_hist):
                            h_hist_ok[i, b, j] = 0.0
                    continue
                h_out[b, j, 0] = p0
                h_out[b, j, 1] = p1
                h_out[b, j, 2] = p2
                if n_hist == 1:
                    out_joints[r, j, 0] = p0
                    out_joints[r, j, 1] = p1
                    out_joints[r, j, 2] = p2
                    continue
                # Weighted average over the ring of the last Holt outputs.
                h_hist[head, b, j, 0] = p0
                h_hist[head, b, j, 1] = p1
                h_hist[head, b, j, 2] = p2
                h_hist_ok[head, b, j] = 1.0
                wsum = 0.0
                acc0 = 0.0
                acc1 = 0.0
                acc2 = 0.0
                for age in range(n_hist):  # newest first, as HoltSmoother sums
                    i = ring[t, age]
                    wi = h_hist_ok[i, b, j] * weights[age]
                    wsum += wi
                    acc0 += wi * h_hist[i, b, j, 0]
                    acc1 += wi * h_hist[i, b, j, 1]
                    acc2 += wi * h_hist[i, b, j, 2]
                wsum = max(wsum, 1e-300)
                out_joints[r, j, 0] = acc0 / wsum
                out_joints[r, j, 1] = acc1 / wsum
                out_joints[r, j, 2] = acc2 / wsum
            out_all_inferred[r] = has and not any_tracked and any_inferred

            # ---- orientation (OrientationFilter.reset, then OrientationFilter.update)
            if changed:
                k_active[b] = False
                for c in range(3):
                    k_angle[b, c] = np.nan
                    k_rate[b, c] = 0.0
                    m_last[b, c] = np.nan
                    o_raw[b, c] = np.nan
                    o_kf[b, c] = np.nan
                    for i in range(win):
                        m_buf[i, b, c] = np.nan
            wrist_ok = has and state[r, slot, wrist] >= min_wrist_state
            if has:
                qw = quat[r, slot, 0]
                qx = quat[r, slot, 1]
                qy = quat[r, slot, 2]
                qz = quat[r, slot, 3]
            else:
                qw = qx = qy = qz = np.nan
            norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
            ok = math.isfinite(norm) and norm > _MIN_QUAT_NORM and wrist_ok
            if ok:
                w, x, y, z = qw / norm, qx / norm, qy / norm, qz / norm
            else:
                w, x, y, z = 1.0, 0.0, 0.0, 0.0
            # eq (1), eq (2) in our [yaw, pitch, roll] order (hand._paper_ypr)
            s = w * y - z * x
            singular = abs(s) > threshold
            about_x = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
            pitch = math.asin(min(max(2.0 * s, -1.0), 1.0))
            about_z = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
            if singular:
                sgn = 1.0 if s > 0.0 else -1.0
                about_z = _wrap(-2.0 * sgn * math.atan2(x, w))
                pitch = sgn * (0.5 * np.pi)
                about_x = 0.0
            ypr[0] = about_z
            ypr[1] = pitch
            ypr[2] = about_x
            out_quat_valid[r] = ok
            out_singular[r] = singular and ok
            if ok:
                for c in range(3):
                    o_raw[b, c] = ypr[c]
            # EulerKalman.update
            act = k_active[b]
            missed = 0 if ok else k_missed[b] + 1
            k_missed[b] = missed
            stale = act and missed > max_coast
            init = ok and not act
            upd = act and ok
            a_act = act and not stale
            for c in range(3):
                p00_0 = k_p00[b, c]
                p01_0 = k_p01[b, c]
                p11_0 = k_p11[b, c]
                a_p = k_angle[b, c] + dt * k_rate[b, c]
                nis_old = k_nis[b, c]
                q = min(fprm[F_Q + c] * max(nis_old, 1.0) ** 2, fprm[F_Q_MAX + c])
                p00 = p00_0 + 2.0 * dt * p01_0 + dt * dt * p11_0 + q * dt3_3
                p01 = p01_0 + dt * p11_0 + q * dt2_2
                p11 = p11_0 + q * dt
                zz = ypr[c] if ok else 0.0
                if init:
                    k_angle[b, c] = zz
                    k_rate[b, c] = 0.0
                    k_p00[b, c] = fprm[F_R + c]
                    k_p01[b, c] = 0.0
                    k_p11[b, c] = fprm[F_P11_INIT + c]
                    k_nis[b, c] = 1.0
                elif a_act:
                    if upd:
                        a_p0 = a_p if math.isfinite(a_p) else 0.0
                        innov = _wrap(zz - a_p0)
                        sv = p00 + fprm[F_R + c]
                        k0 = p00 / sv
                        k1 = p01 / sv
                        nis = innov * innov / sv
                        k_nis[b, c] = nis_old + lam * (nis - nis_old)
                        k_angle[b, c] = a_p + k0 * innov
                        k_rate[b, c] = k_rate[b, c] + k1 * innov
                        k_p00[b, c] = (1.0 - k0) * p00
                        k_p01[b, c] = (1.0 - k0) * p01
                        k_p11[b, c] = p11 - k1 * p01
                    else:
                        k_angle[b, c] = a_p
                        k_p00[b, c] = p00
                        k_p01[b, c] = p01
                        k_p11[b, c] = p11
                elif stale:
                    k_rate[b, c] = 0.0
            active = a_act or init
            k_active[b] = active
            k_init_now[b] = init
            # StreamingMedian.reset(initialised_now), StreamingMedian.update(angle, active)
            if init:
                for c in range(3):
                    m_last[b, c] = np.nan
                    for i in range(win):
                        m_buf[i, b, c] = np.nan
            if active:
                for c in range(3):
                    for i in range(win - 1, 0, -1):
                        m_buf[i, b, c] = m_buf[i - 1, b, c]
                    m_buf[0, b, c] = k_angle[b, c]
                    n = 0
                    for i in range(win):  # insertion sort of the finite samples
                        v = m_buf[i, b, c]
                        if math.isfinite(v):
                            p = n
                            while p > 0 and sorted_buf[p - 1] > v:
                                sorted_buf[p] = sorted_buf[p - 1]
                                p -= 1
                            sorted_buf[p] = v
                            n += 1
                    if n > 0:
                        m_last[b, c] = 0.5 * (sorted_buf[(n - 1) // 2] + sorted_buf[n // 2])
                    else:
                        m_last[b, c] = np.nan
                    o_kf[b, c] = _wrap(k_angle[b, c])
            all_finite = True
            for c in range(3):
                out_ypr_raw[r, c] = o_raw[b, c]
                out_ypr_kalman[r, c] = o_kf[b, c]
                out_ypr[r, c] = _wrap(m_last[b, c])
                if not math.isfinite(o_kf[b, c]):
                    all_finite = False
            out_valid[r] = all_finite
