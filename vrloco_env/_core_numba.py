"""Compiled per-step kernels of :mod:`vrloco_env.core` (one call for all B users).

At one user numpy pays ~1 us per array operation, most of a control step's budget; these do a
step's glue in one compiled call each (their ``py_func`` is the uncompiled reference).
"""

from __future__ import annotations

import math

import numba
from numpy.typing import NDArray

from estimators.kernels import BatchKernel, param_record
from estimators.kernels.rotations import (
    quat_from_ypr,
    quat_mul,
    quat_to_ypr,
    rotation_angle,
    wrap_angle,
)
from vrloco_env.observation import COMMON_FIELDS, ObservationSpec


@numba.njit(cache=True)
def _unit(x):
    return min(max(x, -1.0), 1.0)


def observation_offsets(spec: ObservationSpec) -> NDArray:
    """The (1,) record of the offsets in ``spec``'s observation of the common fields
    (:data:`~vrloco_env.observation.COMMON_FIELDS`, by name), for :data:`observation_kernel`."""
    return param_record(**{name: spec.offset(name) for name in COMMON_FIELDS})


def _observe(
    est, virtual_yaw, goal_points, position, moved, distance, rays, fresh, at, scales, out
):
    """Fill the common fields of ``out`` (B, obs) float32: entry ``j`` is
    ``clip(value / scales[j], -1, 1)`` of its physical value, the fields starting at the
    offsets ``at`` (:func:`observation_offsets` of the env's
    :class:`~vrloco_env.observation.ObservationSpec`).

    ``est`` holds the users' estimates ``(ypr_est, walking, steps, cadence, hand_est)``;
    ``moved`` (B, 2) is each user's displacement in the last control step (room frame, m);
    ``fresh[i]``: user i has just been reset (or never stepped): standing, no estimates yet, so
    its attitude, gait, self-motion and hand entries are zero.
    """
    ypr_est, walking, steps, cadence, hand_est = est
    o = at[0]
    j_heading, j_pitch, j_roll = int(o["heading"]), int(o["pitch"]), int(o["roll"])
    j_walking, j_steps, j_cadence = int(o["walking"]), int(o["steps"]), int(o["cadence"])
    j_moved = int(o["self_motion"])
    j_hand, j_hand_valid, j_bearing = int(o["hand"]), int(o["hand_valid"]), int(o["goal_bearing"])
    j_distance, j_rays = int(o["goal_distance"]), int(o["rays"])
    b = out.shape[0]
    n_rays = rays.shape[1]
    for i in numba.prange(b):
        yaw = virtual_yaw[i]
        ok = (not fresh[i]) and (
            math.isfinite(hand_est[i, 0])
            and math.isfinite(hand_est[i, 1])
            and math.isfinite(hand_est[i, 2])
        )
        v = out[i]
        v[j_heading] = _unit(math.sin(yaw) / scales[j_heading])
        v[j_heading + 1] = _unit(math.cos(yaw) / scales[j_heading + 1])
        if fresh[i]:
            pitch = roll = walk = n_steps = cad = 0.0
        else:
            pitch, roll = ypr_est[i, 1], ypr_est[i, 2]
            walk = 1.0 if walking[i] else 0.0
            n_steps, cad = steps[i], cadence[i]
        v[j_pitch] = _unit(pitch / scales[j_pitch])
        v[j_roll] = _unit(roll / scales[j_roll])
        v[j_walking] = _unit(walk / scales[j_walking])
        v[j_steps] = _unit(n_steps / scales[j_steps])
        v[j_cadence] = _unit(cad / scales[j_cadence])
        if fresh[i]:
            forward = left = 0.0
        else:
            c, s = math.cos(yaw), math.sin(yaw)
            forward = c * moved[i, 0] + s * moved[i, 1]
            left = -s * moved[i, 0] + c * moved[i, 1]
        v[j_moved] = _unit(forward / scales[j_moved])
        v[j_moved + 1] = _unit(left / scales[j_moved + 1])
        for k in range(3):
            v[j_hand + k] = _unit(hand_est[i, k] / scales[j_hand + k]) if ok else 0.0
        v[j_hand_valid] = 1.0 if ok else 0.0
        bearing = (
            math.atan2(goal_points[i, 1] - position[i, 1], goal_points[i, 0] - position[i, 0]) - yaw
        )
        v[j_bearing] = _unit(math.sin(bearing) / scales[j_bearing])
        v[j_bearing + 1] = _unit(math.cos(bearing) / scales[j_bearing + 1])
        v[j_distance] = _unit(distance[i] / scales[j_distance])
        for k in range(n_rays):
            v[j_rays + k] = _unit(rays[i, k] / scales[j_rays + k])


#: The common observation fields of B users: ``observation_kernel(B)(...)`` (see ``_observe``).
observation_kernel = BatchKernel(_observe, parallel=False)


def _attitude_error(q_true, ypr_est, out):
    """Rotation angle (rad) between true attitudes (B, 4) and estimated [yaw, pitch, roll]
    (B, 3): ``angle(conj(q_true) * q(ypr_est))``."""
    for i in numba.prange(q_true.shape[0]):
        ew, ex, ey, ez = quat_from_ypr(ypr_est[i, 0], ypr_est[i, 1], ypr_est[i, 2])
        w, x, y, z = quat_mul(
            q_true[i, 0], -q_true[i, 1], -q_true[i, 2], -q_true[i, 3], ew, ex, ey, ez
        )
        out[i] = rotation_angle(w, x, y, z)


#: The attitude errors of B users: ``attitude_error_kernel(B)(...)`` (see ``_attitude_error``).
attitude_error_kernel = BatchKernel(_attitude_error, parallel=False)


def _quat_to_ypr_rows(q, out):
    """ZYX [yaw, pitch, roll] (rad) of B unit quaternions (B, 4) into ``out`` (B, 3)."""
    for i in numba.prange(q.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = quat_to_ypr(q[i, 0], q[i, 1], q[i, 2], q[i, 3])


#: ``quat_to_ypr_rows(batch_size)(q, out)`` (see ``_quat_to_ypr_rows``).
quat_to_ypr_rows = BatchKernel(_quat_to_ypr_rows, parallel=False)


def _step_summary(gait_steps, true_step, yaw, yaw_offset, prm, out):
    """Per-user summary of a control step (:meth:`vrloco_env.users.SimulatedUsers._summary`).

    ``yaw`` and ``yaw_offset`` are ``(estimated, true)`` pairs of (B,) head yaws and their
    offsets to the virtual heading; ``prm`` the (1,) record of ``step_length`` (m) and
    ``in_place`` (1.0 walking in place). Fills ``out`` = ``(steps, true_steps, virtual_yaw,
    true_virtual_yaw, true_displacement)``: detected and true step counts, virtual and true
    virtual yaw and, walking in place, the displacement perfect sensing would give
    (``step_length`` per true step along the true virtual yaw).
    """
    yaw_est, yaw_true = yaw
    yaw_offset_est, yaw_offset_true = yaw_offset
    o_steps, o_true_steps, o_virtual_yaw, o_true_virtual_yaw, o_true_displacement = out
    p = prm[0]
    step_length = p["step_length"]
    for b in numba.prange(gait_steps.shape[0]):
        s = 0.0
        for k in range(gait_steps.shape[1]):
            s += gait_steps[b, k]
        ts = 0.0
        for k in range(true_step.shape[1]):
            ts += true_step[b, k]
        o_steps[b] = s
        o_true_steps[b] = ts
        o_virtual_yaw[b] = wrap_angle(yaw_est[b] + yaw_offset_est[b])
        tvy = wrap_angle(yaw_true[b] + yaw_offset_true[b])
        o_true_virtual_yaw[b] = tvy
        if p["in_place"] != 0.0:
            o_true_displacement[b, 0] = step_length * ts * math.cos(tvy)
            o_true_displacement[b, 1] = step_length * ts * math.sin(tvy)


#: ``step_summary_kernel(batch_size)(...)`` (see ``_step_summary``).
step_summary_kernel = BatchKernel(_step_summary, parallel=False)
