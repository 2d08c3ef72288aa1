"""Compiled per-step kernels of :mod:`vrloco_env.core` (one call for all B users).

At one user numpy pays ~1 us per array operation, most of a control step's budget; these do a
step's glue in one compiled call each (their ``py_func`` is the uncompiled reference).
"""

from __future__ import annotations

import math

import numba

from estimators.kernels.rotations import quat_from_ypr, quat_mul, quat_to_ypr, rotation_angle

_PI = math.pi


@numba.njit(cache=True)
def _wrap(a):
    return _PI - ((_PI - a) % (2.0 * _PI))


@numba.njit(cache=True)
def _unit(x):
    return min(max(x, -1.0), 1.0)


# Offsets of the common fields in ``at`` (the order of observation.COMMON_FIELDS).
_HEADING, _PITCH, _ROLL, _WALKING, _STEPS, _CADENCE, _HAND, _HAND_VALID = 0, 1, 2, 3, 4, 5, 6, 7
_BEARING, _DISTANCE, _RAYS = 8, 9, 10


@numba.njit(cache=True)
def observation_kernel(
    virtual_yaw, ypr_est, walking, steps, cadence, hand_est, goal_points, position, distance,
    rays, fresh, at, scales, out,
):  # fmt: skip
    """Fill the common fields of ``out`` (B, obs) float32: entry ``j`` is
    ``clip(value / scales[j], -1, 1)`` of its physical value, the fields starting at the
    offsets ``at`` (:data:`vrloco_env.observation.COMMON_FIELDS` order, from the env's
    :class:`~vrloco_env.observation.ObservationSpec`).

    ``fresh[i]``: user i has just been reset (or never stepped): standing, no estimates yet, so
    its attitude, gait and hand entries are zero.
    """
    b = out.shape[0]
    n_rays = rays.shape[1]
    for i in range(b):
        yaw = virtual_yaw[i]
        ok = (not fresh[i]) and (
            math.isfinite(hand_est[i, 0])
            and math.isfinite(hand_est[i, 1])
            and math.isfinite(hand_est[i, 2])
        )
        v = out[i]
        j = at[_HEADING]
        v[j] = _unit(math.sin(yaw) / scales[j])
        v[j + 1] = _unit(math.cos(yaw) / scales[j + 1])
        if fresh[i]:
            pitch = roll = walk = n_steps = cad = 0.0
        else:
            pitch, roll = ypr_est[i, 1], ypr_est[i, 2]
            walk = 1.0 if walking[i] else 0.0
            n_steps, cad = steps[i], cadence[i]
        v[at[_PITCH]] = _unit(pitch / scales[at[_PITCH]])
        v[at[_ROLL]] = _unit(roll / scales[at[_ROLL]])
        v[at[_WALKING]] = _unit(walk / scales[at[_WALKING]])
        v[at[_STEPS]] = _unit(n_steps / scales[at[_STEPS]])
        v[at[_CADENCE]] = _unit(cad / scales[at[_CADENCE]])
        j = at[_HAND]
        for k in range(3):
            v[j + k] = _unit(hand_est[i, k] / scales[j + k]) if ok else 0.0
        v[at[_HAND_VALID]] = 1.0 if ok else 0.0
        bearing = math.atan2(goal_points[i, 1] - position[i, 1],
                             goal_points[i, 0] - position[i, 0]) - yaw  # fmt: skip
        j = at[_BEARING]
        v[j] = _unit(math.sin(bearing) / scales[j])
        v[j + 1] = _unit(math.cos(bearing) / scales[j + 1])
        v[at[_DISTANCE]] = _unit(distance[i] / scales[at[_DISTANCE]])
        j = at[_RAYS]
        for k in range(n_rays):
            v[j + k] = _unit(rays[i, k] / scales[j + k])


@numba.njit(cache=True)
def attitude_error_kernel(q_true, ypr_est, out):
    """Rotation angle (rad) between true attitudes (B, 4) and estimated [yaw, pitch, roll]
    (B, 3): ``angle(conj(q_true) * q(ypr_est))``."""
    for i in range(q_true.shape[0]):
        ew, ex, ey, ez = quat_from_ypr(ypr_est[i, 0], ypr_est[i, 1], ypr_est[i, 2])
        w, x, y, z = quat_mul(q_true[i, 0], -q_true[i, 1], -q_true[i, 2], -q_true[i, 3],
                              ew, ex, ey, ez)  # fmt: skip
        out[i] = rotation_angle(w, x, y, z)


@numba.njit(cache=True)
def quat_to_ypr_rows(q, out):
    """ZYX [yaw, pitch, roll] (rad) of B unit quaternions (B, 4) into ``out`` (B, 3)."""
    for i in range(q.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = quat_to_ypr(q[i, 0], q[i, 1], q[i, 2], q[i, 3])


@numba.njit(cache=True)
def step_summary_kernel(
    gait_steps, true_step, yaw_est, yaw_offset, yaw_true, true_yaw_offset, step_length, in_place,
    o_steps, o_true_steps, o_virtual_yaw, o_true_virtual_yaw, o_true_displacement,
):  # fmt: skip
    """Per-user summary of a control step (``SimulatedUsers._summary_reference`` in numpy):
    detected and true step counts, virtual and true virtual yaw and, walking in place, the
    displacement perfect sensing would give (``step_length`` per true step along the true
    virtual yaw)."""
    for b in range(gait_steps.shape[0]):
        s = 0.0
        for k in range(gait_steps.shape[1]):
            s += gait_steps[b, k]
        ts = 0.0
        for k in range(true_step.shape[1]):
            ts += true_step[b, k]
        o_steps[b] = s
        o_true_steps[b] = ts
        o_virtual_yaw[b] = _wrap(yaw_est[b] + yaw_offset[b])
        tvy = _wrap(yaw_true[b] + true_yaw_offset[b])
        o_true_virtual_yaw[b] = tvy
        if in_place:
            o_true_displacement[b, 0] = step_length * ts * math.cos(tvy)
            o_true_displacement[b, 1] = step_length * ts * math.sin(tvy)
