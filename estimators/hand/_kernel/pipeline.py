"""Yao 2023's hand pipeline, compiled, one user at a time
(:class:`estimators.hand.pipeline.HandPipeline`).

:data:`hand_kernel` runs, for each user (the ``prange`` loop over users) and each of the M Kinect
frames of a call, these stages in order:

1. :func:`~estimators.hand._kernel.joints.select_target` (Yao 2023, 1.1): keep the current target
   by id while it is tracked, else take the tracked body whose centre, the mean of its valid
   centre joints, is nearest the sensor (ties to the lowest slot); a new target makes
   :func:`_forget` clear the filters.
2. :func:`~estimators.hand._kernel.joints.smooth_joints` (1.2): per joint the Kinect SDK's Holt
   filter (:class:`~estimators.hand.joint_smoothing.HoltSmoother` documents the recursion), then
   the weighted average over the ring of its last outputs.
3. :func:`_orientation`: the wrist quaternion to eq (1)/(2) angles (1.3), the Kalman filter of
   each angle (1.4; the model is documented in :class:`~estimators.hand.params.KalmanParams`) and
   the median over the last Kalman angles (:mod:`estimators.hand._kernel.orientation`).

``hand_kernel.py_func`` is the readable uncompiled source. :func:`validate` checks the inputs
first, :data:`forget_kernel` forgets users.

Layouts. Inputs and outputs are rows ``r = b * M + t`` (B users of M frames): ``frames`` is the
tuple ``(ids, tracked, joints, joint_state, quat)``, ``out`` the tuple of the
:class:`~estimators.hand.pipeline.HandFrame` fields in their order. The state is the tuple
``(target, user, joint, ring, window)`` of :func:`new_state` (the record fields:
:data:`~estimators.hand._kernel.orientation.USER_FIELDS`,
:data:`~estimators.hand._kernel.joints.JOINT_FIELDS`,
:data:`~estimators.hand._kernel.joints.RING_FIELDS`). The ring of Holt outputs has one newest
entry for all users: at frame ``t`` of a call it is ``(head0 - 1 - t) mod n``. Parameters are
named records built once by the pipeline (:func:`estimators.hand.params.kernel_params`): ``prm``
(1,) with the fields of :class:`~estimators.hand.joint_smoothing.HoltParams` and those listed in
:data:`PARAM_FIELDS`, ``axes`` (3,) with the per-angle
:data:`~estimators.hand._kernel.orientation.AXIS_FIELDS`.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from estimators.hand._kernel.joints import (
    forget_joints,
    new_holt_state,
    select_target,
    smooth_joints,
)
from estimators.hand._kernel.orientation import (
    USER_FIELDS,
    forget_orientation,
    kalman_step,
    median_step,
    quat_angles,
    shared_layout,
    write_angles,
)
from estimators.kernels.batch import BatchKernel
from estimators.kernels.records import state_records

__all__ = [
    "ERR_DUPLICATE_ID",
    "ERR_JOINTS_INF",
    "ERR_NEGATIVE_ID",
    "ERR_QUAT_INF",
    "ERR_STATE_RANGE",
    "PARAM_FIELDS",
    "forget_kernel",
    "hand_kernel",
    "new_state",
    "validate",
]


#: Parameter record fields besides :class:`~estimators.hand.joint_smoothing.HoltParams`' own.
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

# Error codes of :func:`validate`, in the order the checks run within a frame.
ERR_JOINTS_INF = 1
ERR_QUAT_INF = 2
ERR_STATE_RANGE = 3
ERR_NEGATIVE_ID = 4
ERR_DUPLICATE_ID = 5


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
    joint, ring = new_holt_state(batch_size, num_joints, history)
    state = (
        np.zeros(batch_size, np.int64),
        user,
        joint,
        ring,
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


@numba.njit(cache=True, inline="always")
def _forget(s, hj, hr, win):
    """Clear one user's filters (a new target, or a reset): the angle filters
    (:func:`forget_orientation`), Holt restarted and its ring emptied (:func:`forget_joints`)."""
    forget_orientation(s, win)
    forget_joints(hj, hr)


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
    usable, about_z, pitch, about_x, singular = quat_angles(
        qw, qx, qy, qz, p["singularity_threshold"]
    )
    ok = usable and wrist_ok
    if ok:
        s["ypr_raw"][0] = about_z
        s["ypr_raw"][1] = pitch
        s["ypr_raw"][2] = about_x
    init, active = kalman_step(s, axes, p, ok, about_z, pitch, about_x)
    median_step(s, win, init, active)
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
        out: the :class:`~estimators.hand.pipeline.HandFrame` fields as rows, written.
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
            slot = select_target(ids, tracked, joints, jstate, r, center, cur)
            new_id = ids[r, slot] if slot >= 0 else 0
            changed = new_id != cur and new_id != 0
            target[i] = new_id
            o_slot[r] = slot
            o_id[r] = new_id
            o_changed[r] = changed
            o_has[r] = slot >= 0
            if changed:
                _forget(s, hj, hr, win)
            o_inferred[r] = smooth_joints(
                joints, jstate, r, slot, hj, hr, ages[t], weights, p, o_joints, o_state
            )
            ok, singular = _orientation(quat, jstate, r, slot, s, win, axes, p)
            o_quat_valid[r] = ok
            o_singular[r] = singular and ok
            o_valid[r] = write_angles(s, r, o_raw, o_kalman, o_ypr)


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
