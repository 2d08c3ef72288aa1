"""Seed 003's hand pipeline, compiled, one user at a time (:class:`estimators.hand.HandPipeline`).

:data:`hand_kernel` runs, for each user (the ``prange`` loop over users) and each of the M Kinect
frames of a call, these stages in order:

1. :func:`_select_target` (seed 003, 1.1): keep the current target by id while it is tracked,
   else take the tracked body whose centre, the mean of its valid centre joints, is nearest the
   sensor (ties to the lowest slot); a new target makes :func:`_forget` clear the filters.
2. :func:`_smooth_joints` (1.2): per joint the Kinect SDK's Holt filter (:func:`_holt_joint`;
   :class:`~estimators.joint_smoothing.HoltSmoother` documents the recursion), then the weighted
   average over the ring of its last outputs (:func:`_ring_average`).
3. :func:`_orientation`: the wrist quaternion to eq (1)/(2) angles (:func:`_paper_ypr`, 1.3),
   the Kalman filter of each angle (:func:`_kalman_step`, 1.4; the model is documented in
   :class:`~estimators.hand.KalmanParams`) and the median over the last Kalman angles
   (:func:`_median_step`).

``hand_kernel.py_func`` is the readable uncompiled source. Stage 3 alone, without target
selection and joint smoothing, is :data:`filter_kernel` (Kalman and median over raw angles) after
:data:`angles_kernel` (eq (1)/(2) of quaternions): the same scalar functions, so
:class:`~estimators.hand.OrientationFilter`, which drives them, gives the pipeline's angles bit
for bit.

Layouts. Inputs and outputs are rows ``r = b * M + t`` (B users of M frames): ``frames`` is the
tuple ``(ids, tracked, joints, joint_state, quat)``, ``out`` the tuple of the
:class:`~estimators.hand.HandFrame` fields in their order. The state is the tuple
``(target, user, joint, ring, window)`` of :func:`new_state`, whose record fields are declared
below (:data:`USER_FIELDS`, :data:`JOINT_FIELDS`, :data:`RING_FIELDS`). The ring of Holt outputs
has one newest entry for all users: at frame ``t`` of a call it is ``(head0 - 1 - t) mod n``, and
the weighted average sums over ages, newest first, so a user's numbers do not depend on where the
ring stands. Parameters are named records built once by the pipeline: ``prm`` (1,) with the
fields of :class:`~estimators.joint_smoothing.HoltParams` and those listed in
:data:`PARAM_FIELDS`, ``axes`` (3,) with the per-angle :data:`AXIS_FIELDS`.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from estimators.kernels.batch import BatchKernel
from estimators.kernels.records import record_dtype, state_records
from estimators.kernels.rotations import wrap_angle

__all__ = [
    "AXIS_FIELDS",
    "JOINT_FIELDS",
    "PARAM_FIELDS",
    "RING_FIELDS",
    "USER_FIELDS",
    "angles_kernel",
    "filter_kernel",
    "forget_kernel",
    "hand_kernel",
    "new_filter_state",
    "new_state",
        "shared_layout",
    "validate",
]

#: Parameter record fields besides :class:`~estimators.joint_smoothing.HoltParams`' own.
PARAM_FIELDS = (
    "singularity_threshold",  # eq (2) threshold on |wy - zx| (HandParams)
    "wrist_joint",  # joint index of the wrist (HandParams)
    "min_wrist_state",  # 1 inferred accepted, 2 tracked only (HandParams)
    "max_coast_frames",  # Kalman coasting frames before a user goes stale (KalmanParams)
    "dt",  # Kalman frame period, s
    "dt2_2",  # dt^2 / 2, s^2
    "dt3_3",  # dt^3 / 3, s^3
    "nis_gain",  # gain per frame of the low-pass on the normalised innovation squared
)

#: Per-angle parameter record fields, ``[yaw, pitch, roll]`` rows.
AXIS_FIELDS = (
    "measurement_var",  # rad^2
    "accel_psd",  # angular acceleration PSD at rest, rad^2/s^3
    "max_accel_psd",  # cap of the adapted PSD, rad^2/s^3
    "init_rate_var",  # rate variance at (re)initialisation, rad^2/s^2
)

#: Per-user state (B,): Kalman filter per angle, median output and the held outputs.
USER_FIELDS = {
    "angle": (3,),  # unwrapped Kalman angle, rad (NaN before the first measurement)
    "rate": (3,),  # rad/s
    "p00": (3,),  # covariance of [angle, rate]
    "p01": (3,),
    "p11": (3,),
    "nis": (3,),  # low-passed normalised innovation squared
    "active": (),  # 1.0 while the filter holds an estimate that is updated or coasted
    "missed": (),  # frames since the last usable wrist quaternion
    "median": (3,),  # last median of the Kalman angles, rad (unwrapped)
    "ypr_raw": (3,),  # last usable eq (1)/(2) angles, rad
    "ypr_kalman": (3,),  # last Kalman output, wrapped to (-pi, pi], rad
}

#: Holt state per user and joint (B, J), metres.
JOINT_FIELDS = {
    "count": (),  # consecutive valid frames, capped at 2
    "raw": (3,),  # last valid raw sample
    "filtered": (3,),  # smoothed position
    "trend": (3,),  # trend per frame
}

#: The ring of Holt outputs per user, ring slot and joint (B, n, J).
RING_FIELDS = {
    "x": (3,),  # Holt output, metres
    "ok": (),  # 1.0 where the entry is valid
}

# Error codes of :func:`validate`, in the order the checks run within a frame.
ERR_JOINTS_INF = 1
ERR_QUAT_INF = 2
ERR_STATE_RANGE = 3
ERR_NEGATIVE_ID = 4
ERR_DUPLICATE_ID = 5

_MIN_QUAT_NORM = 1e-6  # as estimators.hand._MIN_QUAT_NORM

_LAYOUTS: dict[np.dtype, np.dtype] = {}


def shared_layout(a: NDArray) -> NDArray:
    """``a``, a record array, viewed with the one dtype object of its layout, so that numba's
    dispatcher finds the record type by identity whichever pipeline built the array."""
    return a.view(_LAYOUTS.setdefault(a.dtype, a.dtype))


def new_state(
    batch_size: int, num_joints: int, history: int, window: int
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
    """A fresh state tuple ``(target, user, joint, ring, window)`` for the kernels.

    ``target`` (B,) int64 target ids (0: none); ``user`` (B,) :data:`USER_FIELDS`; ``joint``
    (B, J) :data:`JOINT_FIELDS`; ``ring`` (B, history, J) :data:`RING_FIELDS`; ``window``
    (B, window, 3) the median's Kalman angles, newest first.
    """
    user = shared_layout(state_records(USER_FIELDS, batch_size))
    user["nis"] = 1.0
    joint = np.zeros((batch_size, num_joints), record_dtype(JOINT_FIELDS))
    ring = np.zeros((batch_size, history, num_joints), record_dtype(RING_FIELDS))
    state = (
        np.zeros(batch_size, np.int64),
        user,
        shared_layout(joint),
        shared_layout(ring),
        np.full((batch_size, window, 3), np.nan),
    )
    forget_kernel(batch_size)(np.ones(batch_size, np.bool_), state)
    return state


# ----------------------------------------------------------------------------------------------
# Input checks


@numba.njit(cache=True)
def _any_error(ids, joints, state, quat, joints_flat):
    """True if any row has an infinite value, a state outside {0, 1, 2} or a negative id.

    Branch-free per value so that the loops run at memory speed. ``joints_flat`` is ``joints``
    as one contiguous 1-D view, or empty where ``joints`` is not contiguous: the flat loop
    vectorises, the nested one does not.
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
    """First input error, frame by frame, checks in the ``ERR_*`` order; ``(code, frame)`` or
    ``(0, -1)``.

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


# ----------------------------------------------------------------------------------------------
# Stage 1: target selection


@numba.njit(cache=True, inline="always")
def _body_distance(joints, jstate, r, k, center):
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
        if jstate[r, k, jc] >= 1 and math.isfinite(x) and math.isfinite(y) and math.isfinite(z):
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
def _select_target(ids, tracked, joints, jstate, r, center, cur):
    """Slot of row ``r``'s target (-1: no tracked body with a valid centre) given the current
    target id ``cur`` (0: none)."""
    keep = -1
    nearest = 0
    best = np.inf
    for k in range(ids.shape[1]):
        present = tracked[r, k] and ids[r, k] != 0
        if not present:
            continue
        if keep < 0 and cur != 0 and ids[r, k] == cur:
            keep = k
        d = _body_distance(joints, jstate, r, k, center)
        if d < best:
            best = d
            nearest = k
    if keep >= 0:
        return keep
    if math.isfinite(best):
        return nearest
    return -1


@numba.njit(cache=True, inline="always")
def _forget_orientation(s, win):
    """Clear one user's angle filters: Kalman inactive, outputs NaN, median window empty."""
    s["active"] = 0.0
    for c in range(3):
        s["angle"][c] = np.nan
        s["rate"][c] = 0.0
        s["median"][c] = np.nan
        s["ypr_raw"][c] = np.nan
        s["ypr_kalman"][c] = np.nan
        for i in range(win.shape[0]):
            win[i, c] = np.nan


@numba.njit(cache=True, inline="always")
def _forget(s, hj, hr, win):
    """Clear one user's filters (a new target, or a reset): the angle filters
    (:func:`_forget_orientation`), Holt restarted and its ring emptied."""
    _forget_orientation(s, win)
    for j in range(hj.shape[0]):
        h = hj[j]
        h["count"] = 0.0
        h["trend"][0] = 0.0
        h["trend"][1] = 0.0
        h["trend"][2] = 0.0
        for a in range(hr.shape[0]):
            hr[a, j]["ok"] = 0.0


# ----------------------------------------------------------------------------------------------
# Stage 2: joint smoothing


@numba.njit(cache=True, inline="always")
def _holt_joint(h, x0, x1, x2, valid, scale, p):
    """One Holt step of a joint (state record ``h``, raw sample ``x``, 0 if invalid): updates
    ``h`` and returns the output, pulled to within the max deviation radius of ``x``, m."""
    jitter_r = p["jitter_radius"] * scale
    max_dev_r = p["max_deviation_radius"] * scale
    s = p["smoothing"]
    c = p["correction"]
    cnt = h["count"]
    f0p = h["filtered"][0]
    f1p = h["filtered"][1]
    f2p = h["filtered"][2]
    b0p = h["trend"][0]
    b1p = h["trend"][1]
    b2p = h["trend"][2]
    if cnt == 0.0:
        f0, f1, f2 = x0, x1, x2
        b0 = b1 = b2 = 0.0
    else:
        if cnt == 1.0:
            f0 = 0.5 * (x0 + h["raw"][0])
            f1 = 0.5 * (x1 + h["raw"][1])
            f2 = 0.5 * (x2 + h["raw"][2])
        else:
            d0, d1, d2 = x0 - f0p, x1 - f1p, x2 - f2p
            a = min(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) / jitter_r, 1.0)
            f0 = (x0 * a + f0p * (1.0 - a)) * (1.0 - s) + (f0p + b0p) * s
            f1 = (x1 * a + f1p * (1.0 - a)) * (1.0 - s) + (f1p + b1p) * s
            f2 = (x2 * a + f2p * (1.0 - a)) * (1.0 - s) + (f2p + b2p) * s
        b0 = c * (f0 - f0p) + (1.0 - c) * b0p
        b1 = c * (f1 - f1p) + (1.0 - c) * b1p
        b2 = c * (f2 - f2p) + (1.0 - c) * b2p
    k = p["prediction"]
    o0 = f0 + k * b0
    o1 = f1 + k * b1
    o2 = f2 + k * b2
    e0, e1, e2 = o0 - x0, o1 - x1, o2 - x2
    dev = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    if dev > max_dev_r:
        pull = max_dev_r / max(dev, 1e-300)
        o0 = o0 * pull + x0 * (1.0 - pull)
        o1 = o1 * pull + x1 * (1.0 - pull)
        o2 = o2 * pull + x2 * (1.0 - pull)
    if valid:
        h["raw"][0] = x0
        h["raw"][1] = x1
        h["raw"][2] = x2
        h["filtered"][0] = f0
        h["filtered"][1] = f1
        h["filtered"][2] = f2
        h["trend"][0] = b0
        h["trend"][1] = b1
        h["trend"][2] = b2
        h["count"] = min(cnt + 1.0, 2.0)
    else:
        h["trend"][0] = 0.0
        h["trend"][1] = 0.0
        h["trend"][2] = 0.0
        h["count"] = 0.0
    return o0, o1, o2


@numba.njit(cache=True, inline="always")
def _ring_average(hr, j, ages, weights, x0, x1, x2):
    """Store joint ``j``'s Holt output ``x`` as the newest ring entry (``ages[0]``) and return
    the weighted mean over the valid entries, newest first (``ages``: ring slot of each age)."""
    e = hr[ages[0], j]
    e["x"][0] = x0
    e["x"][1] = x1
    e["x"][2] = x2
    e["ok"] = 1.0
    wsum = 0.0
    acc0 = 0.0
    acc1 = 0.0
    acc2 = 0.0
    for age in range(weights.shape[0]):
        g = hr[ages[age], j]
        wi = g["ok"] * weights[age]
        wsum += wi
        acc0 += wi * g["x"][0]
        acc1 += wi * g["x"][1]
        acc2 += wi * g["x"][2]
    wsum = max(wsum, 1e-300)
    return acc0 / wsum, acc1 / wsum, acc2 / wsum


@numba.njit(cache=True, inline="always")
def _ring_clear(hr, j, head):
    """An invalid frame of joint ``j``: zero its newest ring entry, invalidate all of them."""
    e = hr[head, j]
    e["x"][0] = 0.0
    e["x"][1] = 0.0
    e["x"][2] = 0.0
    for a in range(hr.shape[0]):
        hr[a, j]["ok"] = 0.0


@numba.njit(cache=True, inline="always")
def _smooth_joints(joints, jstate, r, slot, hj, hr, ages, weights, p, out_joints, out_state):
    """Holt filter and weighted average of every joint of the target in ``slot`` (-1: none),
    into ``out_joints[r]`` (NaN where invalid) and ``out_state[r]``; True where the target has
    inferred joints and no tracked one."""
    has = slot >= 0
    n_hist = weights.shape[0]
    any_tracked = False
    any_inferred = False
    for j in range(hj.shape[0]):
        st = jstate[r, slot, j] if has else 0
        out_state[r, j] = st
        if st == 2:
            any_tracked = True
        elif st == 1:
            any_inferred = True
        if has:
            x0 = joints[r, slot, j, 0]
            x1 = joints[r, slot, j, 1]
            x2 = joints[r, slot, j, 2]
            valid = st >= 1 and math.isfinite(x0) and math.isfinite(x1) and math.isfinite(x2)
        else:
            valid = False
        if not valid:
            x0 = x1 = x2 = 0.0
        scale = p["inferred_radius_scale"] if st == 1 else 1.0
        o0, o1, o2 = _holt_joint(hj[j], x0, x1, x2, valid, scale, p)
        if not valid:
            out_joints[r, j, 0] = np.nan
            out_joints[r, j, 1] = np.nan
            out_joints[r, j, 2] = np.nan
            if n_hist > 1:
                _ring_clear(hr, j, ages[0])
            continue
        if n_hist > 1:
            o0, o1, o2 = _ring_average(hr, j, ages, weights, o0, o1, o2)
        out_joints[r, j, 0] = o0
        out_joints[r, j, 1] = o1
        out_joints[r, j, 2] = o2
    return has and not any_tracked and any_inferred


# ----------------------------------------------------------------------------------------------
# Stage 3: orientation


@numba.njit(cache=True, inline="always")
def _paper_ypr(w, x, y, z, threshold):
    """Eq (1), or eq (2) where ``|wy - zx| > threshold``, of a unit quaternion in our order:
    ``(about_z, pitch, about_x, singular)`` (see :mod:`estimators.hand` for the names)."""
    s = w * y - z * x
    singular = abs(s) > threshold
    about_x = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(min(max(2.0 * s, -1.0), 1.0))
    about_z = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    if singular:
        sgn = 1.0 if s > 0.0 else -1.0
        about_z = wrap_angle(-2.0 * sgn * math.atan2(x, w))
        pitch = sgn * (0.5 * np.pi)
        about_x = 0.0
    return about_z, pitch, about_x, singular


@numba.njit(cache=True, inline="always")
def _quat_angles(qw, qx, qy, qz, threshold):
    """A quaternion of any norm to eq (1)/(2) angles: ``(usable, about_z, pitch, about_x,
    singular)``; not usable (NaN, infinite or norm <= 1e-6) gives the identity's angles."""
    norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    usable = math.isfinite(norm) and norm > _MIN_QUAT_NORM
    if usable:
        w, x, y, z = qw / norm, qx / norm, qy / norm, qz / norm
    else:
        w, x, y, z = 1.0, 0.0, 0.0, 0.0
    about_z, pitch, about_x, singular = _paper_ypr(w, x, y, z, threshold)
    return usable, about_z, pitch, about_x, singular


@numba.njit(cache=True, inline="always")
def _kalman_axis(s, c, a, p, z, init, a_act, upd, stale):
    """One frame of the Kalman filter of angle ``c`` (axis parameters ``a``): (re)initialise
    from ``z``, predict and correct with ``z``, predict only, or stop a stale stream's rate."""
    dt = p["dt"]
    p00_0 = s["p00"][c]
    p01_0 = s["p01"][c]
    p11_0 = s["p11"][c]
    a_p = s["angle"][c] + dt * s["rate"][c]
    nis_old = s["nis"][c]
    q = min(a["accel_psd"] * max(nis_old, 1.0) ** 2, a["max_accel_psd"])
    p00 = p00_0 + 2.0 * dt * p01_0 + dt * dt * p11_0 + q * p["dt3_3"]
    p01 = p01_0 + dt * p11_0 + q * p["dt2_2"]
    p11 = p11_0 + q * dt
    if init:
        s["angle"][c] = z
        s["rate"][c] = 0.0
        s["p00"][c] = a["measurement_var"]
        s["p01"][c] = 0.0
        s["p11"][c] = a["init_rate_var"]
        s["nis"][c] = 1.0
    elif a_act:
        if upd:
            a_p0 = a_p if math.isfinite(a_p) else 0.0
            innov = wrap_angle(z - a_p0)
            sv = p00 + a["measurement_var"]
            k0 = p00 / sv
            k1 = p01 / sv
            nis = innov * innov / sv
            s["nis"][c] = nis_old + p["nis_gain"] * (nis - nis_old)
            s["angle"][c] = a_p + k0 * innov
            s["rate"][c] = s["rate"][c] + k1 * innov
            s["p00"][c] = (1.0 - k0) * p00
            s["p01"][c] = (1.0 - k0) * p01
            s["p11"][c] = p11 - k1 * p01
        else:
            s["angle"][c] = a_p
            s["p00"][c] = p00
            s["p01"][c] = p01
            s["p11"][c] = p11
    elif stale:
        s["rate"][c] = 0.0


@numba.njit(cache=True, inline="always")
def _kalman_step(s, axes, p, ok, z0, z1, z2):
    """The Kalman filters of the three angles, measurement ``z`` where ``ok``; returns
    ``(init, active)``: re-initialised this frame, holds an estimate after it."""
    act = s["active"] != 0.0
    missed = 0.0 if ok else s["missed"] + 1.0
    s["missed"] = missed
    stale = act and missed > p["max_coast_frames"]
    init = ok and not act
    upd = act and ok
    a_act = act and not stale
    _kalman_axis(s, 0, axes[0], p, z0, init, a_act, upd, stale)
    _kalman_axis(s, 1, axes[1], p, z1, init, a_act, upd, stale)
    _kalman_axis(s, 2, axes[2], p, z2, init, a_act, upd, stale)
    active = a_act or init
    s["active"] = 1.0 if active else 0.0
    if active:
        for c in range(3):
            s["ypr_kalman"][c] = wrap_angle(s["angle"][c])
    return init, active


@numba.njit(cache=True, inline="always")
def _sorted_at(win, c, k):
    """The ``k``-th (0-based) finite value of ``win[:, c]`` in ascending order, ties in window
    order (a stable sort's order)."""
    for i in range(win.shape[0]):
        v = win[i, c]
        if not math.isfinite(v):
            continue
        rank = 0
        for i2 in range(win.shape[0]):
            u = win[i2, c]
            if math.isfinite(u) and (u < v or (u == v and i2 < i)):
                rank += 1
        if rank == k:
            return v
    return np.nan


@numba.njit(cache=True, inline="always")
def _write_angles(s, r, o_raw, o_kalman, o_ypr) -> bool:
    """Row ``r`` of the outputs from the stream's state ``s``: the raw, Kalman and median-filtered
    angles (rad); whether the Kalman estimate is finite (the row is valid)."""
    valid = True
    for c in range(3):
        o_raw[r, c] = s["ypr_raw"][c]
        o_kalman[r, c] = s["ypr_kalman"][c]
        o_ypr[r, c] = wrap_angle(s["median"][c])
        if not math.isfinite(s["ypr_kalman"][c]):
            valid = False
    return valid


@numba.njit(cache=True, inline="always")
def _median_step(s, win, init, active):
    """Median over the window of Kalman angles: emptied on (re)initialisation, fed while the
    filter is active (its median then in ``s["median"]``, NaN without a finite sample)."""
    if init:
        for c in range(3):
            s["median"][c] = np.nan
            for i in range(win.shape[0]):
                win[i, c] = np.nan
    if not active:
        return
    for c in range(3):
        for i in range(win.shape[0] - 1, 0, -1):
            win[i, c] = win[i - 1, c]
        win[0, c] = s["angle"][c]
        n = 0
        for i in range(win.shape[0]):
            if math.isfinite(win[i, c]):
                n += 1
        if n == 0:
            s["median"][c] = np.nan
            continue
        lo = _sorted_at(win, c, (n - 1) // 2)
        hi = lo if n % 2 == 1 else _sorted_at(win, c, n // 2)
        s["median"][c] = 0.5 * (lo + hi)


@numba.njit(cache=True, inline="always")
def _orientation(quat, jstate, r, slot, s, win, axes, p):
    """Eq (1)/(2) of the target's wrist quaternion, Kalman filter and median; returns
    ``(ok, singular)``: the quaternion was usable, eq (2) was taken."""
    has = slot >= 0
    wrist_ok = has and jstate[r, slot, int(p["wrist_joint"])] >= p["min_wrist_state"]
    if has:
        qw = quat[r, slot, 0]
        qx = quat[r, slot, 1]
        qy = quat[r, slot, 2]
        qz = quat[r, slot, 3]
    else:
        qw = qx = qy = qz = np.nan
    usable, about_z, pitch, about_x, singular = _quat_angles(
        qw, qx, qy, qz, p["singularity_threshold"]
    )
    ok = usable and wrist_ok
    if ok:
        s["ypr_raw"][0] = about_z
        s["ypr_raw"][1] = pitch
        s["ypr_raw"][2] = about_x
    init, active = _kalman_step(s, axes, p, ok, about_z, pitch, about_x)
    _median_step(s, win, init, active)
    return ok, singular


# ----------------------------------------------------------------------------------------------
# The kernels


def _hand_frames(frames, m_count, prm, axes, center, weights, head0, state, out):
    """The hand pipeline over M frames of B users (inputs already checked by :func:`validate`).

    Args:
        frames: ``(ids, tracked, joints, joint_state, quat)``, rows ``r = b * M + t``: (B*M, K)
            int ids, (B*M, K) bool, (B*M, K, J, 3) m, (B*M, K, J) int states, (B*M, K, 4).
        m_count: M.
        prm, axes: the parameter records (module docstring).
        center: (C,) int64 centre joints. weights: (n,) normalised Holt average weights, newest
            first. head0: the ring's newest slot before the first frame.
        state: :func:`new_state`'s tuple, updated in place.
        out: the :class:`~estimators.hand.HandFrame` fields as rows, written.
    """
    ids, tracked, joints, jstate, quat = frames
    target, user, joint, ring, window = state
    o_slot, o_id, o_changed, o_has, o_joints, o_state, o_inferred = out[:7]
    o_raw, o_kalman, o_ypr, o_quat_valid, o_singular, o_valid = out[7:]
    n_hist = weights.shape[0]
    ages = np.empty((m_count, n_hist), np.int64)  # ring slot of each age at frame t
    for t in range(m_count):
        head = (head0 - 1 - t) % n_hist
        for a in range(n_hist):
            ages[t, a] = (head + a) % n_hist
    for i in numba.prange(target.shape[0]):  # users are independent (estimators.kernels.batch)
        p = prm[0]
        s = user[i]
        hj = joint[i]
        hr = ring[i]
        win = window[i]
        for t in range(m_count):
            r = i * m_count + t
            cur = target[i]
            slot = _select_target(ids, tracked, joints, jstate, r, center, cur)
            new_id = ids[r, slot] if slot >= 0 else 0
            changed = new_id != cur and new_id != 0
            target[i] = new_id
            o_slot[r] = slot
            o_id[r] = new_id
            o_changed[r] = changed
            o_has[r] = slot >= 0
            if changed:
                _forget(s, hj, hr, win)
            o_inferred[r] = _smooth_joints(
                joints, jstate, r, slot, hj, hr, ages[t], weights, p, o_joints, o_state
            )
            ok, singular = _orientation(quat, jstate, r, slot, s, win, axes, p)
            o_quat_valid[r] = ok
            o_singular[r] = singular and ok
            o_valid[r] = _write_angles(s, r, o_raw, o_kalman, o_ypr)


#: ``hand_kernel(B)(frames, m_count, prm, axes, center, weights, head0, state, out)``.
hand_kernel = BatchKernel(_hand_frames, parallel=False)


def _forget_rows(rows, state):
    """Forget the target and filters of the users where ``rows`` (B,) bool is True."""
    target, user, joint, ring, window = state
    for i in numba.prange(rows.shape[0]):
        if rows[i]:
            target[i] = 0
            _forget(user[i], joint[i], ring[i], window[i])


#: ``forget_kernel(B)(rows, state)``.
forget_kernel = BatchKernel(_forget_rows, parallel=False)


# ----------------------------------------------------------------------------------------------
# Stage 3 alone: the orientation filter over angle or quaternion sequences


def new_filter_state(batch_size: int, window: int) -> tuple[NDArray, NDArray]:
    """A fresh state ``(user, window)`` for :data:`filter_kernel`: the ``user`` records
    (:data:`USER_FIELDS`) and median windows (B, window, 3) of :func:`new_state`, all forgotten."""
    user = shared_layout(state_records(USER_FIELDS, batch_size))
    user["nis"] = 1.0
    for name in ("angle", "median", "ypr_raw", "ypr_kalman"):
        user[name] = np.nan
    return user, np.full((batch_size, window, 3), np.nan)


def _filter_angles(z, usable, restart, m_count, prm, axes, state, out):
    """Stage 3 without target selection: Kalman then median of B streams of M raw angles.

    The same per-frame steps as :func:`_orientation` after its eq (1)/(2) (:func:`_kalman_step`,
    :func:`_median_step`), so a stream fed the pipeline's ``ypr_raw`` and ``quat_valid`` (and
    restarted where the pipeline reselected) reproduces its ``ypr_kalman`` and ``ypr``.

    Args:
        z: (B*M, 3) raw ``[yaw, pitch, roll]``, rad, rows ``r = b * M + t``.
        usable: (B*M,) bool, the frame's angles are a measurement (False: a dropout; NaN angles
            are a dropout too).
        restart: (B*M,) bool, forget the stream before this frame (a new target).
        m_count: M.
        prm, axes: the parameter records of :func:`~estimators.hand._kernel_params`.
        state: :func:`new_filter_state`'s ``(user, window)``, updated in place.
        out: ``(ypr_raw, ypr_kalman, ypr, valid)``: (B*M, 3) x 3 and (B*M,) bool, written.
    """
    user, window = state
    o_raw, o_kalman, o_ypr, o_valid = out
    for i in numba.prange(user.shape[0]):  # streams are independent (estimators.kernels.batch)
        p = prm[0]
        s = user[i]
        win = window[i]
        for t in range(m_count):
            r = i * m_count + t
            if restart[r]:
                _forget_orientation(s, win)
            z0 = z[r, 0]
            z1 = z[r, 1]
            z2 = z[r, 2]
            ok = usable[r] and math.isfinite(z0) and math.isfinite(z1) and math.isfinite(z2)
            if ok:
                s["ypr_raw"][0] = z0
                s["ypr_raw"][1] = z1
                s["ypr_raw"][2] = z2
            init, active = _kalman_step(s, axes, p, ok, z0, z1, z2)
            _median_step(s, win, init, active)
            o_valid[r] = _write_angles(s, r, o_raw, o_kalman, o_ypr)


#: ``filter_kernel(B)(z, usable, restart, m_count, prm, axes, state, out)``.
filter_kernel = BatchKernel(_filter_angles, parallel=False)


def _angle_rows(quat, threshold, out, usable, singular):
    """Eq (1)/(2) of N quaternions of any norm (:func:`_quat_angles`), row by row.

    Args:
        quat: (N, 4) ``[w, x, y, z]``. threshold: eq (2) threshold on ``|wy - zx|``.
        out: (N, 3) our ``[yaw, pitch, roll]``, rad, written (the identity's angles where not
            usable). usable, singular: (N,) bool, written.
    """
    for r in numba.prange(quat.shape[0]):
        ok, about_z, pitch, about_x, sing = _quat_angles(
            quat[r, 0], quat[r, 1], quat[r, 2], quat[r, 3], threshold
        )
        out[r, 0] = about_z
        out[r, 1] = pitch
        out[r, 2] = about_x
        usable[r] = ok
        singular[r] = sing and ok


#: ``angles_kernel(N)(quat, threshold, out, usable, singular)``.
angles_kernel = BatchKernel(_angle_rows, parallel=False)
