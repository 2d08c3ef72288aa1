"""Compiled body of the simulated user (see :mod:`vrloco_env.user.motion`): per user, per time.

Two kernels, each a :class:`~estimators.kernels.BatchKernel` whose loop over users runs small
stages:

* :data:`evaluate_kernel`, the head and body at given times after a control step's start, from the
  user's state record (fields :data:`STATE`) and intent: step phase (:func:`_step_phase`), vertical
  bob (:func:`_bob`), lateral sway (:func:`_sway`), body yaw (:func:`_body_yaw`), gestures, lean and
  head-on-torso yaw (:func:`_gestures`, :func:`_critically_damped`), the head's orientation and body
  rate (:func:`_body_rate`), the neck pivot (:func:`_neck`) and the forehead IMU;
* :data:`skeleton_kernel`, the Kinect v2 joints and the right hand's orientation at the Kinect
  frames, from the body evaluated there and the body geometry record of
  :data:`vrloco_env.user.motion._BODY`: torso (:func:`_torso`), head, legs (:func:`_legs`) and the
  right arm and hand (:func:`_right_hand`).

Units: s, m, rad, steps/s.
"""

from __future__ import annotations

import math

import numba

from estimators.kernels import BatchKernel
from estimators.kernels.rotations import quat_from_ypr, quat_rotate

#: Fields of one user's state record, carried between control steps: continuous step phase
#: (integer when standing at a step boundary), cadence of the step in progress (steps/s), body
#: yaw (rad, unwrapped) and its rate (rad/s), the gesture amplitudes (rad), their rates (rad/s)
#: and phases (rad) about yaw, pitch, roll, head lean (rad) and its rate (rad/s), the hand's
#: [yaw, pitch, roll] relative to the torso (rad), the standing place in the tracked space (m),
#: the user's style factors (step impact, sway), the overground walking speed (m/s; 0 in place)
#: and the head-on-torso yaw (rad) and its rate (rad/s).
STATE = {
    "phase": (),
    "step_cadence": (),
    "yaw": (),
    "yaw_rate": (),
    "gesture_amp": (3,),
    "gesture_amp_rate": (3,),
    "gesture_phase": (3,),
    "lean": (),
    "lean_rate": (),
    "hand_ypr": (3,),
    "base": (2,),
    "impact_scale": (),
    "sway_scale": (),
    "speed": (),
    "head_yaw": (),
    "head_yaw_rate": (),
}

#: Planes of :data:`evaluate_kernel`'s per-time outputs ``scalars`` (S, B, T) and ``vectors`` (V, B,
#: T, 3), by name: step phase, cadence (steps/s), body yaw (rad) and rate (rad/s), lean (rad) and
#: rate (rad/s), head-on-torso yaw (rad) and rate (rad/s); head [yaw, pitch, roll] (rad) and their
#: rates (rad/s), the head's body-frame rate (rad/s), neck pivot and IMU position (m), gesture
#: amplitudes (rad), their rates (rad/s) and phases (rad).
SCALARS = ("phase", "cadence", "yaw", "yaw_rate", "lean", "lean_rate", "head_yaw", "head_yaw_rate")
VECTORS = (
    "head_ypr",
    "d_head_ypr",
    "omega",
    "neck",
    "imu_pos",
    "gesture_amp",
    "gesture_amp_rate",
    "g_phase",
)
S_PHASE, S_CADENCE, S_YAW, S_YAW_RATE, S_LEAN, S_LEAN_RATE, S_HEAD, S_HEAD_RATE = map(
    SCALARS.index,
    ("phase", "cadence", "yaw", "yaw_rate", "lean", "lean_rate", "head_yaw", "head_yaw_rate"),
)
V_YPR, V_D_YPR, V_OMEGA, V_NECK, V_IMU, V_GAMP, V_GAMP_RATE, V_GPHASE = map(
    VECTORS.index,
    (
        "head_ypr",
        "d_head_ypr",
        "omega",
        "neck",
        "imu_pos",
        "gesture_amp",
        "gesture_amp_rate",
        "g_phase",
    ),
)

_TWO_PI = 2.0 * math.pi


@numba.njit(cache=True, inline="always")
def _critically_damped(x0, v0, target, lag, tau):
    """Value and rate, ``tau`` s on, of a critically damped second-order response (time constant
    ``lag``) from value ``x0`` and rate ``v0`` towards ``target``."""
    e0 = x0 - target
    c = v0 + e0 / lag
    decay = math.exp(-tau / lag)
    return target + (e0 + c * tau) * decay, (c - (e0 + c * tau) / lag) * decay


@numba.njit(cache=True, inline="always")
def _step_phase(ph0, to_boundary, t_b, c_old, c_new, tt):
    """Step phase and cadence ``tt`` s after the step start: the step in progress finishes at its
    own cadence ``c_old`` (at ``t_b``, ``to_boundary`` phase on), then the commanded ``c_new``."""
    if tt < t_b:
        return ph0 + c_old * tt, c_old
    return ph0 + to_boundary + c_new * (tt - t_b), c_new


@numba.njit(cache=True, inline="always")
def _bob(p, phase, cad, impact):
    """Vertical head bob (m) at ``phase``: the heel-strike pulse's double integral
    ``sum_k pos_k cos(k th)`` (cosines by the angle-addition recurrence, harmonics 1..K), less its
    value at a step boundary, scaled by the peak acceleration ``a_peak(cad)`` over ``cad^2``."""
    lo, hi = p["cadence_range_hz"][0], p["cadence_range_hz"][1]
    pk_lo, pk_hi = p["peak_accel_g"][0], p["peak_accel_g"][1]
    alpha = min(max((cad - lo) / (hi - lo), 0.0), 1.0)
    a_peak = (pk_lo + alpha * (pk_hi - pk_lo)) * p["gravity"] * impact
    amp = a_peak / (cad * cad) if cad > 0.0 else 0.0
    frac = phase - math.floor(phase)
    th = _TWO_PI * (frac - 0.5)
    c1, s1 = math.cos(th), math.sin(th)
    ck, sk = c1, s1
    z = 0.0
    pulse_pos = p["pulse_pos"]
    for k in range(pulse_pos.shape[0]):
        z += pulse_pos[k] * ck
        ck, sk = ck * c1 - sk * s1, sk * c1 + ck * s1
    return amp * (z - p["pulse_z0"])


@numba.njit(cache=True, inline="always")
def _sway(p, phase, cad, scale):
    """Lateral sway (m), the head roll that goes with it (rad) and the roll's rate (rad/s): one
    cycle per stride (two steps), zero with zero slope at step boundaries."""
    sin_p = math.sin(math.pi * phase)
    s3 = sin_p * sin_p * sin_p
    sway = p["sway_m"] * scale * s3
    roll = p["sway_roll"] * scale * s3
    d_roll = (
        p["sway_roll"] * scale * 3.0 * sin_p * sin_p * math.cos(math.pi * phase) * math.pi * cad
    )
    return sway, roll, d_roll


@numba.njit(cache=True, inline="always")
def _body_yaw(yaw0, r0, rc, lag, tt):
    """Body yaw (rad) and rate (rad/s) ``tt`` s on: the rate follows its command ``rc`` from
    ``r0`` with a first-order lag ``lag``."""
    decay = math.exp(-tt / lag)
    return yaw0 + rc * tt + (r0 - rc) * lag * (1.0 - decay), rc + (r0 - rc) * decay


@numba.njit(cache=True, inline="always")
def _gestures(s, amp_cmd, freq, lag, tt, row):
    """The head gestures about yaw, pitch, roll ``tt`` s on, into this time's vector outputs
    ``row`` (V, 3): the amplitudes (critically damped towards ``amp_cmd``), their rates and the
    oscillation phases; and into the head-angle rows the gesture angles ``amp sin(phase)`` (rad)
    and their rates (rad/s), to which the body's angles are added after."""
    for a in range(3):
        ga, dga = _critically_damped(
            s["gesture_amp"][a], s["gesture_amp_rate"][a], amp_cmd[a], lag, tt
        )
        om = _TWO_PI * freq[a]
        gp = s["gesture_phase"][a] + om * tt
        sg, cg = math.sin(gp), math.cos(gp)
        row[V_GAMP, a] = ga
        row[V_GAMP_RATE, a] = dga
        row[V_GPHASE, a] = gp
        row[V_YPR, a] = ga * sg
        row[V_D_YPR, a] = dga * sg + ga * om * cg


@numba.njit(cache=True, inline="always")
def _body_rate(pitch, roll, dy, dp, dr):
    """Body-frame angular velocity (rad/s) of a ZYX attitude from its Euler-angle rates."""
    sp, cp = math.sin(pitch), math.cos(pitch)
    sr, cr = math.sin(roll), math.cos(roll)
    return dr - dy * sp, dp * cr + dy * cp * sr, -dp * sr + dy * cp * cr


@numba.njit(cache=True, inline="always")
def _neck(base, yaw, sway, height, bob):
    """Neck pivot (m): standing place + lateral sway (torso-left axis) + vertical bob."""
    return base[0] - math.sin(yaw) * sway, base[1] + math.cos(yaw) * sway, height + bob


@numba.njit(cache=True, inline="always")
def _set3(out, x, y, z):
    """``out[:3] = x, y, z``."""
    out[0] = x
    out[1] = y
    out[2] = z


def _evaluate(
    state,
    cadence,
    turn_rate,
    gesture_amplitude,
    gesture_frequency,
    lean,
    head_yaw,
    prm,
    tau,
    t_boundary,
    scalars,
    vectors,
    quat,
):
    """Head and body of B users at the times ``tau`` (T,) s after the control step's start.

    Args:
        state: (B,) records :data:`STATE` at the step start (read only).
        cadence, turn_rate, lean, head_yaw: the intent (steps/s, rad/s, rad, rad), (B,) each.
        gesture_amplitude, gesture_frequency: the intent's gestures (rad, Hz), (B, 3) each.
        prm: (1,) parameter record (:func:`vrloco_env.user.motion._kernel_params`).
        tau: evaluation times (s), (T,).
        t_boundary: out, time (s) at which the step in progress ends, (B,) (0 when standing).
        scalars, vectors: out, (S, B, T) and (V, B, T, 3), planes :data:`SCALARS`, :data:`VECTORS`.
        quat: out, head orientation (sensor -> world), (B, T, 4).
    """
    for b in numba.prange(state.shape[0]):  # users are independent (estimators.kernels.batch)
        p = prm[0]  # taken here: numba's parallel build cannot pass a record into the loop
        lag, imu_off = p["gesture_lag_s"], p["imu_offset_m"]
        s = state[b]
        ph0, c_old, c_new = s["phase"], s["step_cadence"], cadence[b]
        to_boundary = math.ceil(ph0 - 1e-12) - ph0
        t_b = to_boundary / c_old if c_old > 0.0 else 0.0
        t_boundary[b] = t_b
        for t in range(tau.shape[0]):
            tt = tau[t]
            phase, cad = _step_phase(ph0, to_boundary, t_b, c_old, c_new, tt)
            bob = _bob(p, phase, cad, s["impact_scale"])
            sway, sway_roll, d_sway_roll = _sway(p, phase, cad, s["sway_scale"])
            yaw, d_yaw = _body_yaw(s["yaw"], s["yaw_rate"], turn_rate[b], p["turn_lag_s"], tt)
            row = vectors[:, b, t]
            _gestures(s, gesture_amplitude[b], gesture_frequency[b], lag, tt, row)
            ln, d_ln = _critically_damped(s["lean"], s["lean_rate"], lean[b], lag, tt)
            hy, d_hy = _critically_damped(
                s["head_yaw"], s["head_yaw_rate"], head_yaw[b], p["head_turn_lag_s"], tt
            )
            # Head angles and their rates: body yaw, lean and sway roll plus the gestures, and
            # the head-on-torso yaw (added only where it moves, so a straight head leaves the
            # sums bit for bit as they were without it).
            ypr, d_ypr = row[V_YPR], row[V_D_YPR]
            y, pt, r = yaw + ypr[0], ln + ypr[1], sway_roll + ypr[2]
            dy, dp, dr = d_yaw + d_ypr[0], d_ln + d_ypr[1], d_sway_roll + d_ypr[2]
            if hy != 0.0 or d_hy != 0.0:
                y += hy
                dy += d_hy
            _set3(ypr, y, pt, r)
            _set3(d_ypr, dy, dp, dr)
            wx, wy, wz = _body_rate(pt, r, dy, dp, dr)
            _set3(row[V_OMEGA], wx, wy, wz)
            qw, qx, qy, qz = quat_from_ypr(y, pt, r)
            q = quat[b, t]
            q[0], q[1], q[2], q[3] = qw, qx, qy, qz
            nx, ny, nz = _neck(s["base"], yaw, sway, p["neck_height_m"], bob)
            _set3(row[V_NECK], nx, ny, nz)
            ox, oy, oz = quat_rotate(qw, qx, qy, qz, imu_off[0], imu_off[1], imu_off[2])
            _set3(row[V_IMU], nx + ox, ny + oy, nz + oz)
            scalars[S_PHASE, b, t] = phase
            scalars[S_CADENCE, b, t] = cad
            scalars[S_YAW, b, t] = yaw
            scalars[S_YAW_RATE, b, t] = d_yaw
            scalars[S_LEAN, b, t] = ln
            scalars[S_LEAN_RATE, b, t] = d_ln
            scalars[S_HEAD, b, t] = hy
            scalars[S_HEAD_RATE, b, t] = d_hy


evaluate_kernel = BatchKernel(_evaluate)
"""Head and body at the given times for B users: ``evaluate_kernel(B)(...)`` (:func:`_evaluate`)."""


@numba.njit(cache=True, inline="always")
def _in_torso(cy, sy, ox, oy):
    """A torso-frame horizontal offset turned by the body yaw (cosine ``cy``, sine ``sy``)."""
    return cy * ox - sy * oy, sy * ox + cy * oy


@numba.njit(cache=True, inline="always")
def _torso(joints, body, nx, ny, nz, cy, sy):
    """The joints fixed in the torso frame, from the neck pivot ``n`` (m)."""
    offsets = body["torso_offsets"]
    for j in range(offsets.shape[0]):
        dx, dy = _in_torso(cy, sy, offsets[j, 0], offsets[j, 1])
        _set3(joints[body["torso_joints"][j]], nx + dx, ny + dy, nz + offsets[j, 2])


@numba.njit(cache=True, inline="always")
def _legs(joints, body, nx, ny, nz, cy, sy, phase, walking):
    """Legs: the leg of step n (parity of floor(phase)) lifts its knee during that step; ankles
    and feet stay above the floor."""
    lift = math.sin(math.pi * (phase - math.floor(phase))) * (1.0 if walking else 0.0)
    right_lifts = math.floor(phase) % 2 == 0
    rest, full = body["leg_rest"], body["leg_lift"]
    for leg in range(2):
        up = lift if (leg == 1) == right_lifts else 0.0
        for jj in range(4):
            ox = rest[leg, jj, 0] + up * full[jj, 0]
            oy = rest[leg, jj, 1] + up * full[jj, 1]
            oz = rest[leg, jj, 2] + up * full[jj, 2]
            z = nz + oz
            if jj >= 2:
                z = max(z, body["floor_z"])
            dx, dy = _in_torso(cy, sy, ox, oy)
            _set3(joints[body["leg_joints"][leg * 4 + jj]], nx + dx, ny + dy, z)


@numba.njit(cache=True, inline="always")
def _right_hand(joints, body, yaw, cy, sy, hand_ypr, hand_quat):
    """The right hand's orientation (torso yaw, then the hand's own angles ``hand_ypr``), the
    wrist (the forearm held forward from the elbow) and the hand's joints."""
    tw, tz = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    aw, ax, ay, az = quat_from_ypr(hand_ypr[0], hand_ypr[1], hand_ypr[2])
    qw = tw * aw - tz * az
    qx = tw * ax - tz * ay
    qy = tw * ay + tz * ax
    qz = tw * az + tz * aw
    hand_quat[0], hand_quat[1], hand_quat[2], hand_quat[3] = qw, qx, qy, qz
    elbow, forearm = joints[body["elbow_right"]], body["forearm"]
    dx, dy = _in_torso(cy, sy, forearm[0], forearm[1])
    wx, wy, wz = elbow[0] + dx, elbow[1] + dy, elbow[2] + forearm[2]
    _set3(joints[body["wrist_right"]], wx, wy, wz)
    offsets = body["hand_offsets"]
    for j in range(offsets.shape[0]):
        px, py, pz = quat_rotate(qw, qx, qy, qz, offsets[j, 0], offsets[j, 1], offsets[j, 2])
        _set3(joints[body["hand_joints"][j]], wx + px, wy + py, wz + pz)


def _skeleton(neck, quat, yaw, phase, walking, hand_ypr, body, joints, hand_quat):
    """Kinect v2 joints (world frame) and right-hand orientation of B users at M frames.

    Args:
        neck, quat, yaw, phase, walking: the body at the frames (:data:`evaluate_kernel`'s
            outputs there; ``walking`` bool), (B, M, 3), (B, M, 4), (B, M), (B, M), (B, M).
        hand_ypr: the hand's [yaw, pitch, roll] relative to the torso (rad), (B, M, 3).
        body: (1,) body geometry record (:data:`vrloco_env.user.motion._BODY`).
        joints: out, (B, M, 25, 3) m.
        hand_quat: out, hand frame -> world, (B, M, 4).
    """
    g = body[0]
    for b in numba.prange(yaw.shape[0]):  # users are independent (estimators.kernels.batch)
        for m in range(yaw.shape[1]):
            cy, sy = math.cos(yaw[b, m]), math.sin(yaw[b, m])
            nx, ny, nz = neck[b, m, 0], neck[b, m, 1], neck[b, m, 2]
            out = joints[b, m]
            _torso(out, g, nx, ny, nz, cy, sy)
            q, head = quat[b, m], g["head_offset"]
            hx, hy, hz = quat_rotate(q[0], q[1], q[2], q[3], head[0], head[1], head[2])
            _set3(out[g["head_joint"]], nx + hx, ny + hy, nz + hz)
            _legs(out, g, nx, ny, nz, cy, sy, phase[b, m], walking[b, m])
            _right_hand(out, g, yaw[b, m], cy, sy, hand_ypr[b, m], hand_quat[b, m])


skeleton_kernel = BatchKernel(_skeleton, parallel=False)
"""Kinect joints and hand orientation: ``skeleton_kernel(B)(...)`` (:func:`_skeleton`)."""
