"""Compiled per-step kernels of :mod:`vrloco_env.core` (one call for all B users).

Each repeats the arithmetic of a numpy twin in :mod:`vrloco_env.core`, which
``tests/test_env.py`` checks it against: :func:`observation_kernel` is
``LocoCore.observe_reference``, :func:`attitude_error_kernel` the infos' attitude error. At one
user the numpy versions pay ~1 us per array operation, most of a control step's budget.
"""

from __future__ import annotations

import math

import numba

from estimators._rotations_numba import quat_from_ypr, quat_mul, quat_to_ypr, rotation_angle

_PI = math.pi


@numba.njit(cache=True)
def _wrap(a):
    return _PI - ((_PI - a) % (2.0 * _PI))


@numba.njit(cache=True)
def _unit(x):
    return min(max(x, -1.0), 1.0)


@numba.njit(cache=True)
def observation_kernel(
    virtual_yaw, ypr_est, walking, steps, cadence, hand_est, hand_target, use_hand_target,
    goal_points, position, distance, rays, ray_range, dwell_fraction, fresh, max_goal_distance,
    out,
):  # fmt: skip
    """Fill ``out`` (B, obs) float32 with the observation of :func:`core.observation_names`.

    ``fresh[i]``: user i has just been reset (or never stepped): standing, no estimates yet, so
    its attitude, gait and hand entries are zero and its hand error is the target itself.
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
        v[0] = _unit(math.sin(yaw))
        v[1] = _unit(math.cos(yaw))
        if fresh[i]:
            v[2] = 0.0
            v[3] = 0.0
            v[4] = 0.0
            v[5] = 0.0
            v[6] = 0.0
        else:
            v[2] = _unit(ypr_est[i, 1] / (_PI / 2.0))
            v[3] = _unit(ypr_est[i, 2] / _PI)
            v[4] = 1.0 if walking[i] else 0.0
            v[5] = _unit(min(steps[i] / 3.0, 1.0))
            v[6] = _unit(min(cadence[i] / 3.0, 1.0))
        for k in range(3):
            v[7 + k] = _unit(hand_est[i, k] / _PI) if ok else 0.0
        v[10] = 1.0 if ok else 0.0
        bearing = math.atan2(goal_points[i, 1] - position[i, 1],
                             goal_points[i, 0] - position[i, 0]) - yaw  # fmt: skip
        v[11] = _unit(math.sin(bearing))
        v[12] = _unit(math.cos(bearing))
        v[13] = _unit(min(distance[i] / max_goal_distance, 1.0))
        for k in range(n_rays):
            v[14 + k] = _unit(min(rays[i, k], ray_range) / ray_range)
        j = 14 + n_rays
        for k in range(3):
            if not use_hand_target:
                err = 0.0
            elif fresh[i]:
                err = hand_target[i, k]
            elif ok:
                err = _wrap(hand_target[i, k] - hand_est[i, k])
            else:
                err = 0.0
            v[j + k] = _unit(err / _PI)
        v[j + 3] = _unit(min(dwell_fraction[i], 1.0))


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
    dt, cadence_tau, since_step, cadence, o_steps, o_true_steps, o_virtual_yaw,
    o_true_virtual_yaw, o_true_displacement,
):  # fmt: skip
    """Per-user summary of a control step (``SimulatedUsers._summary_reference`` in numpy):
    detected and true step counts, virtual and true virtual yaw, the cadence estimate
    (``since_step`` and ``cadence`` updated in place) and, walking in place, the displacement
    perfect sensing would give (``step_length`` per true step along the true virtual yaw)."""
    decay = math.exp(-dt / cadence_tau)
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
        since = since_step[b] + dt
        if s > 0.0 and math.isfinite(since):
            c = s / max(since, dt)
        else:
            c = cadence[b] * decay
        cadence[b] = min(c, 4.0)
        since_step[b] = 0.0 if s > 0.0 else since
        if in_place:
            o_true_displacement[b, 0] = step_length * ts * math.cos(tvy)
            o_true_displacement[b, 1] = step_length * ts * math.sin(tvy)
