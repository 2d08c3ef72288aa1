"""Compiled kernels of the locomotion models: the cadence-proportional speed
(:class:`estimators.locomotion.cadence_speed.CadenceSpeed`, whose module docstring derives it),
head-tilt speed (:data:`head_tilt_kernel`) and the look-down toggle (:data:`look_down_kernel`).

:data:`cadence_kernel` runs one update of B users (loop over users inside), each along a cubic
ramp of its speed (:func:`_hermite`, integrated exactly by :func:`_hermite_area`); its uncompiled
``py_func`` is the readable reference. The users' state is a (B,) record array of
:data:`CADENCE_SPEED_STATE`. Eq (17) and the smooth filter are numpy, batched over users.
"""

from __future__ import annotations

import math

import numba

from estimators.kernels import BatchKernel

__all__ = [
    "CADENCE_SPEED_STATE",
    "MAX_RING",
    "PITCH_DRIVEN_STATE",
    "cadence_kernel",
    "head_tilt_kernel",
    "look_down_kernel",
]


#: Longest ring of the bout's last events (``cadence_window`` + 1 for the largest window).
MAX_RING = 17

#: Per-user state of :data:`cadence_kernel`. The cubic: start speed ``v0`` (m/s), start
#: acceleration ``a0`` (m/s^2), ``target`` speed and time ``elapsed`` on it (s); the bout:
#: ``active`` (0 / 1), step ``interval`` (s), ``last_event`` time (s), cumulative step count
#: ``cum`` and the ring of its last events' times ``ring_t`` (s) and counts ``ring_c`` (its first
#: ``cadence_window + 1`` entries; ``ring_len`` used, newest at ``ring_head``); the path:
#: ``bearing`` of the last event and last ``yaw`` (rad; ``yaw_known`` 0 / 1), position ``pos``
#: (m), distance ``dist`` (m) and the ``speed`` at the end of the last update (m/s); ``clock``:
#: the time since the reset (s).
CADENCE_SPEED_STATE = {
    "v0": (),
    "a0": (),
    "target": (),
    "elapsed": (),
    "active": (),
    "interval": (),
    "last_event": (),
    "cum": (),
    "ring_t": (MAX_RING,),
    "ring_c": (MAX_RING,),
    "ring_len": (),
    "ring_head": (),
    "bearing": (),
    "yaw": (),
    "yaw_known": (),
    "pos": (2,),
    "dist": (),
    "speed": (),
    "clock": (),
}


@numba.njit(cache=True)
def _hermite(v0: float, a0t: float, w: float, s: float) -> tuple[float, float]:
    """Speed and (acceleration x ramp_time) at phase ``s`` in [0, 1] of the cubic from speed
    ``v0``, acceleration x ramp_time ``a0t``, to ``w`` with zero acceleration."""
    s2 = s * s
    s3 = s2 * s
    v = v0 * (2.0 * s3 - 3.0 * s2 + 1.0) + a0t * (s3 - 2.0 * s2 + s) + w * (3.0 * s2 - 2.0 * s3)
    d = v0 * (6.0 * s2 - 6.0 * s) + a0t * (3.0 * s2 - 4.0 * s + 1.0) + w * (6.0 * s - 6.0 * s2)
    return v, d


@numba.njit(cache=True)
def _hermite_area(v0: float, a0t: float, w: float, s: float) -> float:
    """Integral over phase [0, s] of the cubic of :func:`_hermite` (multiply by ramp_time)."""
    s2 = s * s
    s3 = s2 * s
    s4 = s3 * s
    return (
        v0 * (0.5 * s4 - s3 + s)
        + a0t * (0.25 * s4 - 2.0 * s3 / 3.0 + 0.5 * s2)
        + w * (s3 - 0.5 * s4)
    )


def _cadence_speed_run(steps, yaw, bearing, step_length, dt, prm, state):
    """One update of ``dt`` s for B users (user i's interval starts at its own ``clock``, the time
    since its reset): ``steps``, ``yaw``,
    ``bearing`` and ``step_length`` (B,) as :meth:`CadenceSpeed.update` takes them, ``prm`` the
    (1,) record of :class:`CadenceSpeedParams`, ``state`` the (B,) records of
    :data:`CADENCE_SPEED_STATE`, updated in place."""
    p = prm[0]
    ramp_time = p["ramp_time"]
    window = int(p["cadence_window"]) + 1
    for i in numba.prange(steps.shape[0]):
        s = state[i]
        n = steps[i]
        time = s["clock"]
        v0, a0t, target = s["v0"], s["a0"] * ramp_time, s["target"]
        elapsed, interval = s["elapsed"], s["interval"]
        active = s["active"] != 0.0
        restart = False
        # 1. Events and timeouts, at the start of the interval.
        if active and time - s["last_event"] > p["stop_factor"] * interval:
            active = False  # stop timeout: the bout is over
            target = 0.0
            restart = True
        if n > 0.0:
            if not active:  # the bout's first event: no timing yet
                active = True
                s["cum"] = 0.0
                s["ring_len"] = 0.0
                s["ring_head"] = 0.0
                interval = p["default_step_interval"]
            else:
                s["cum"] += n
            ring_len = int(s["ring_len"])
            head = (int(s["ring_head"]) + 1) % window if ring_len > 0 else 0
            s["ring_t"][head] = time
            s["ring_c"][head] = s["cum"]
            ring_len = min(ring_len + 1, window)
            s["ring_head"], s["ring_len"] = head, ring_len
            if ring_len > 1:
                oldest = (head - ring_len + 1) % window
                span = time - s["ring_t"][oldest]
                count = s["cum"] - s["ring_c"][oldest]
                interval = min(max(span / count, p["min_step_interval"]), p["max_step_interval"])
            s["last_event"] = time
            s["bearing"] = bearing[i]
            target = step_length[i] / interval
            restart = True
        if restart:  # a new cubic from the current speed and acceleration
            v_now, d_now = _hermite(v0, a0t, s["target"], min(elapsed / ramp_time, 1.0))
            v0, a0t, elapsed = v_now, d_now, 0.0
        # 2. Move along the cubic over [elapsed, elapsed + dt], then at the target.
        s0 = min(elapsed / ramp_time, 1.0)
        s1 = min((elapsed + dt) / ramp_time, 1.0)
        ds = ramp_time * (_hermite_area(v0, a0t, target, s1) - _hermite_area(v0, a0t, target, s0))
        ds += target * max(0.0, elapsed + dt - max(elapsed, ramp_time))
        ds = max(ds, 0.0)
        elapsed += dt
        if elapsed >= ramp_time:
            v_end = target
        else:
            v_end = _hermite(v0, a0t, target, elapsed / ramp_time)[0]
        # 3. Position along the heading halfway through the interval.
        y1 = yaw[i]
        y0 = s["yaw"] if s["yaw_known"] != 0.0 else y1
        turn = y1 - y0
        half = 0.5 * math.atan2(math.sin(turn), math.cos(turn))
        ang = y0 + half + s["bearing"]
        s["pos"][0] += ds * math.cos(ang)
        s["pos"][1] += ds * math.sin(ang)
        s["dist"] += ds
        s["speed"] = max(v_end, 0.0)
        s["v0"], s["a0"], s["target"] = v0, a0t / ramp_time, target
        s["elapsed"], s["interval"], s["yaw"] = elapsed, interval, y1
        s["active"] = 1.0 if active else 0.0
        s["yaw_known"] = 1.0
        s["clock"] = time + dt


#: The compiled update: ``cadence_kernel(batch_size)(...)`` (see ``_cadence_speed_run``).
cadence_kernel = BatchKernel(_cadence_speed_run, parallel=False)


#: Per-user state of :data:`head_tilt_kernel` and :data:`look_down_kernel`: position ``pos`` (m),
#: distance ``dist`` (m), ``speed`` of the last update (m/s), last ``yaw`` (rad; ``yaw_known``
#: 0 / 1); the look-down toggle's auto-walk state ``moving`` (0 / 1) and whether the next look
#: down toggles it, ``armed`` (0 / 1).
PITCH_DRIVEN_STATE = {
    "pos": (2,),
    "dist": (),
    "speed": (),
    "yaw": (),
    "yaw_known": (),
    "moving": (),
    "armed": (),
}


@numba.njit(cache=True)
def _advance(state, i: int, yaw: float, distance: float) -> None:
    """Move user ``i`` of ``state`` by ``distance`` (m) along the yaw halfway between its last
    yaw and ``yaw`` (rad), and keep ``yaw`` as the last."""
    s = state[i]
    y0 = s["yaw"] if s["yaw_known"] != 0.0 else yaw
    turn = yaw - y0
    ang = y0 + 0.5 * math.atan2(math.sin(turn), math.cos(turn))
    s["pos"][0] += distance * math.cos(ang)
    s["pos"][1] += distance * math.sin(ang)
    s["dist"] += distance
    s["yaw"] = yaw
    s["yaw_known"] = 1.0


def _head_tilt_run(pitch, yaw, dt, prm, state):
    """One update of ``dt`` s for B users: the speed follows the (B,) estimated head ``pitch``
    (rad, positive nose down) past the dead zone, linearly up to full speed (the (1,) record of
    :class:`HeadTiltParams` in radians and m/s), along the (B,) ``yaw`` (rad); ``state`` the (B,)
    records of :data:`PITCH_DRIVEN_STATE`, updated in place."""
    p = prm[0]
    span = p["full_speed_pitch"] - p["dead_zone"]
    for i in numba.prange(pitch.shape[0]):
        s = state[i]
        tilt = min(max((pitch[i] - p["dead_zone"]) / span, 0.0), 1.0)
        s["speed"] = p["max_speed"] * tilt
        _advance(state, i, yaw[i], s["speed"] * dt)


#: The compiled update of :class:`~estimators.locomotion.head_tilt.HeadTilt`.
head_tilt_kernel = BatchKernel(_head_tilt_run, parallel=False)


def _look_down_run(pitch, yaw, dt, prm, state):
    """One update of ``dt`` s for B users: a look down to the (B,) estimated head ``pitch``
    (rad, positive nose down) at or past ``threshold`` toggles the auto-walk when ``armed``;
    the head has to come back above ``rearm`` to arm the next toggle (the (1,) record of
    :class:`LookDownParams` in radians and m/s). A walking user moves at ``speed`` along the
    (B,) ``yaw`` (rad); ``state`` the (B,) records of :data:`PITCH_DRIVEN_STATE`, updated in
    place."""
    p = prm[0]
    for i in numba.prange(pitch.shape[0]):
        s = state[i]
        if s["armed"] != 0.0 and pitch[i] >= p["threshold"]:
            s["moving"] = 1.0 - s["moving"]
            s["armed"] = 0.0
        elif s["armed"] == 0.0 and pitch[i] < p["rearm"]:
            s["armed"] = 1.0
        s["speed"] = p["speed"] * s["moving"]
        _advance(state, i, yaw[i], s["speed"] * dt)


#: The compiled update of :class:`~estimators.locomotion.look_down.LookDownToMove`.
look_down_kernel = BatchKernel(_look_down_run, parallel=False)
