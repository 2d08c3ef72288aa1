"""Compiled hand-frame arithmetic of the env: the hand relative to the torso, and hand errors.

Both are per-user kernels (:class:`~estimators.kernels.batch.BatchKernel`, serial builds: their
work per user is a few quaternion products). ``tests/test_vrloco_env/test_users.py`` checks the hand
relative to
the torso against the simulated user's true hand, and :func:`hand_error` against rotation angles
computed with :mod:`estimators.rotations`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from estimators.kernels.batch import BatchKernel
from estimators.kernels.rotations import (
    quat_from_ypr,
    quat_mul,
    quat_rotate,
    quat_to_ypr,
    rotation_angle,
)


def _hand_relative_to_torso(ypr, valid, shoulder_left, shoulder_right, cam_q, sdk_to_hand, out):
    """[yaw, pitch, roll] of the hand relative to the torso heading, NaN where not valid.

    ``ypr`` (B, 3): filtered SDK-wrist orientation in camera space; shoulders (B, 3) in camera
    space; ``cam_q`` camera -> world; ``sdk_to_hand`` the quaternion taking the SDK wrist frame
    to the hand frame (right-multiplied). The torso heading is that of the left-to-right
    shoulder line turned by -90 deg, in the world's horizontal plane.
    """
    for b in numba.prange(ypr.shape[0]):  # users are independent (estimators.kernels.batch)
        ok = valid[b]
        for k in range(3):
            ok = ok and math.isfinite(ypr[b, k])
            ok = ok and math.isfinite(shoulder_left[b, k]) and math.isfinite(shoulder_right[b, k])
        if not ok:
            out[b, 0] = out[b, 1] = out[b, 2] = np.nan
            continue
        qc = quat_from_ypr(ypr[b, 0], ypr[b, 1], ypr[b, 2])
        qw = quat_mul(cam_q[0], cam_q[1], cam_q[2], cam_q[3], qc[0], qc[1], qc[2], qc[3])
        qh = quat_mul(
            qw[0],
            qw[1],
            qw[2],
            qw[3],
            sdk_to_hand[0],
            sdk_to_hand[1],
            sdk_to_hand[2],
            sdk_to_hand[3],
        )
        d = quat_rotate(
            cam_q[0],
            cam_q[1],
            cam_q[2],
            cam_q[3],
            shoulder_left[b, 0] - shoulder_right[b, 0],
            shoulder_left[b, 1] - shoulder_right[b, 1],
            shoulder_left[b, 2] - shoulder_right[b, 2],
        )
        half = 0.5 * (math.atan2(d[1], d[0]) - 0.5 * math.pi)  # torso yaw / 2
        rel = quat_mul(math.cos(half), 0.0, 0.0, -math.sin(half), qh[0], qh[1], qh[2], qh[3])
        y, p, r = quat_to_ypr(rel[0], rel[1], rel[2], rel[3])
        out[b, 0] = y
        out[b, 1] = p
        out[b, 2] = r


#: ``hand_relative_to_torso(B)(ypr, valid, shoulder_left, shoulder_right, cam_q, sdk_to_hand,
#: out)``, every array C-contiguous.
hand_relative_to_torso = BatchKernel(_hand_relative_to_torso, parallel=False)


def hand_error(estimate, target):
    """Rotation angle (rad) between estimated and target hand orientations ([yaw, pitch, roll]
    (B, 3) each); NaN where there is no estimate."""
    est = np.ascontiguousarray(estimate, dtype=np.float64)
    out = np.empty(est.shape[0])
    hand_error_kernel(est.shape[0])(est, np.ascontiguousarray(target, dtype=np.float64), out)
    return out


def _hand_error(estimate, target, out):
    """Rotation angle (rad) between estimated and target [yaw, pitch, roll]; NaN without one."""
    for b in numba.prange(estimate.shape[0]):  # users are independent (estimators.kernels.batch)
        e = estimate[b]
        if not (math.isfinite(e[0]) and math.isfinite(e[1]) and math.isfinite(e[2])):
            out[b] = np.nan
            continue
        qt = quat_from_ypr(target[b, 0], target[b, 1], target[b, 2])
        qe = quat_from_ypr(e[0], e[1], e[2])
        q = quat_mul(qt[0], -qt[1], -qt[2], -qt[3], qe[0], qe[1], qe[2], qe[3])
        out[b] = rotation_angle(q[0], q[1], q[2], q[3])


#: ``hand_error_kernel(B)(estimate, target, out)``.
hand_error_kernel = BatchKernel(_hand_error, parallel=False)
