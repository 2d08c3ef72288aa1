"""Stages 1 and 2 of Yao 2023's hand pipeline, compiled: target selection and joint smoothing.

* :func:`select_target` (Yao 2023, 1.1): keep the current target by id while it is tracked, else
  take the tracked body whose centre, the mean of its valid centre joints, is nearest the sensor
  (ties to the lowest slot).
* :func:`smooth_joints` (1.2): per joint the Kinect SDK's Holt filter (:func:`_holt_joint`;
  :class:`~estimators.hand.joint_smoothing.HoltSmoother` documents the recursion), then the
  weighted average over the ring of its last outputs (:func:`_ring_average`).

:data:`holt_kernel` runs stage 2 alone over one frame of B streams of J joints (the compiled core
of :class:`~estimators.hand.joint_smoothing.HoltSmoother`), with the same scalar functions as the
pipeline's kernel, so the two give the same joints bit for bit. Layouts: the Holt state per user
and joint is a (B, J) record array of :data:`JOINT_FIELDS`, the ring of Holt outputs a
(B, n, J) record array of :data:`RING_FIELDS`; the ring has one newest entry for all users, and
the weighted average sums over ages, newest first, so a user's numbers do not depend on where
the ring stands. The parameter record holds the fields of
:class:`~estimators.hand.joint_smoothing.HoltParams`.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from estimators.hand._kernel.orientation import shared_layout
from estimators.kernels.batch import BatchKernel
from estimators.kernels.records import record_dtype

__all__ = [
    "JOINT_FIELDS",
    "RING_FIELDS",
    "forget_joints",
    "holt_kernel",
    "new_holt_state",
    "select_target",
    "smooth_joints",
]


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
def select_target(ids, tracked, joints, jstate, r, center, cur):
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
def smooth_joints(joints, jstate, r, slot, hj, hr, ages, weights, p, out_joints, out_state):
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


@numba.njit(cache=True, inline="always")
def forget_joints(hj, hr):
    """Restart one user's Holt filters (J joint records ``hj``) and empty its ring ``hr``."""
    for j in range(hj.shape[0]):
        h = hj[j]
        h["count"] = 0.0
        h["trend"][0] = 0.0
        h["trend"][1] = 0.0
        h["trend"][2] = 0.0
        for a in range(hr.shape[0]):
            hr[a, j]["ok"] = 0.0


def new_holt_state(batch_size: int, num_joints: int, history: int) -> tuple[NDArray, NDArray]:
    """A fresh ``(joint, ring)`` state for :data:`holt_kernel`: the Holt records (B, J) of
    :data:`JOINT_FIELDS` and the ring (B, history, J) of :data:`RING_FIELDS`, all restarted."""
    joint = np.zeros((batch_size, num_joints), record_dtype(JOINT_FIELDS))
    ring = np.zeros((batch_size, history, num_joints), record_dtype(RING_FIELDS))
    return shared_layout(joint), shared_layout(ring)


def _holt_rows(joints, jstate, prm, weights, head0, joint, ring, out, holt_out):
    """Stage 2 over one frame of B streams: the Holt filter and the weighted average of every
    joint (:class:`~estimators.hand.joint_smoothing.HoltSmoother`).

    Args:
        joints: (B, J, 3) raw joint positions, m (NaN where not tracked).
        jstate: (B, J) tracking states (0 not tracked, 1 inferred, 2 tracked), float64.
        prm: (1,) record of the :class:`~estimators.hand.joint_smoothing.HoltParams` fields.
        weights: (n,) normalised average weights, newest first. head0: the ring's newest slot
            before this frame.
        joint, ring: :func:`new_holt_state`'s arrays, updated in place.
        out: (B, J, 3) smoothed positions, written (NaN where invalid).
        holt_out: (B, J, 3) the Holt output before the average, written (NaN where invalid).
    """
    n_hist = weights.shape[0]
    ages = np.empty(n_hist, np.int64)  # ring slot of each age, newest first
    head = (head0 - 1) % n_hist
    for a in range(n_hist):
        ages[a] = (head + a) % n_hist
    for i in numba.prange(joints.shape[0]):  # streams are independent (estimators.kernels.batch)
        p = prm[0]
        hj = joint[i]
        hr = ring[i]
        for j in range(joints.shape[1]):
            st = jstate[i, j]
            x0 = joints[i, j, 0]
            x1 = joints[i, j, 1]
            x2 = joints[i, j, 2]
            valid = st >= 1 and math.isfinite(x0) and math.isfinite(x1) and math.isfinite(x2)
            if not valid:
                x0 = x1 = x2 = 0.0
            scale = p["inferred_radius_scale"] if st == 1 else 1.0
            o0, o1, o2 = _holt_joint(hj[j], x0, x1, x2, valid, scale, p)
            if not valid:
                for c in range(3):
                    out[i, j, c] = np.nan
                    holt_out[i, j, c] = np.nan
                if n_hist > 1:
                    _ring_clear(hr, j, ages[0])
                continue
            holt_out[i, j, 0] = o0
            holt_out[i, j, 1] = o1
            holt_out[i, j, 2] = o2
            if n_hist > 1:
                o0, o1, o2 = _ring_average(hr, j, ages, weights, o0, o1, o2)
            out[i, j, 0] = o0
            out[i, j, 1] = o1
            out[i, j, 2] = o2


#: ``holt_kernel(B)(joints, jstate, prm, weights, head0, joint, ring, out, holt_out)``.
holt_kernel = BatchKernel(_holt_rows, parallel=False)
