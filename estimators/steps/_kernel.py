"""Compiled kernels of the step stages and the cadence; the classes that drive them are beside it.

* :data:`gait_kernel` — Zhang 2021's still/walk and step detector
  (:class:`estimators.steps.zhang2021.StepDetector`), and the stages of its family that
  :data:`nod_robust_kernel` (:class:`estimators.steps.nod_robust.NodRobustSteps`) shares: the
  running baseline, the causal mean filter, the centred-window maximum, Zhang 2021's bout rule and
  the still/walk state (:func:`running_baseline`, :func:`mean_filter`, :func:`window_max`,
  :func:`bout_rule`, :func:`walking`), over the per-stream state :data:`GAIT_STATE`
  (:func:`forget_streams` starts streams afresh);
* :data:`threshold_kernel` — the naive peak picker
  (:class:`estimators.steps.threshold.ThresholdSteps`);
* :data:`cadence_kernel` — the cadence from step events
  (:class:`estimators.steps.cadence.CadenceEstimator`).

Each kernel loops over streams outside and samples inside; its uncompiled ``py_func`` is the
readable reference. The detectors fill the ``(state, steps, peak_time)`` arrays that
:func:`empty_chunk` allocates, the fields of a :class:`estimators.stages.GaitChunk`.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.kernels import BatchKernel
from estimators.kernels.rotations import quat_rotate

__all__ = [
    "CADENCE_STATE",
    "GAIT_STATE",
    "LEE2018_STATE",
    "MAX_CADENCE",
    "NOD_ROBUST_STATE",
    "THRESHOLD_STATE",
    "bout_rule",
    "cadence_kernel",
    "empty_chunk",
    "forget_streams",
    "gait_kernel",
    "lee2018_kernel",
    "mean_filter",
    "nod_robust_kernel",
    "running_baseline",
    "threshold_kernel",
    "walking",
    "window_max",
]


def empty_chunk(batch_size: int, n: int) -> tuple[NDArray[np.int8], ...]:
    """Zeroed ``state`` and ``steps`` (B, n) int8 and a NaN ``peak_time`` (B, n, 2)."""
    return (
        np.zeros((batch_size, n), np.int8),
        np.zeros((batch_size, n), np.int8),
        np.full((batch_size, n, 2), np.nan),
    )


# ------------------------------------------------------------------------------------------------
# Zhang 2021's detector and the stages of its family.
# ------------------------------------------------------------------------------------------------


#: Per-stream scalars of :class:`StepDetector`'s kernel (its ring buffers, whose lengths follow
#: the rate, are (B, M) and (B, 2h + 1) arrays beside it): the last finite norm, the baseline
#: (m/s^2), the samples seen, the last peak, the pending first peak of a bout and the last step
#: (s; -inf / NaN: none).
GAIT_STATE = {
    "last_valid": (),
    "baseline": (),
    "n_seen": (),
    "last_peak": (),
    "pending": (),
    "last_step": (),
}


def forget_streams(
    state: NDArray, clock: NDArray[np.int64], sel: ArrayLike, gravity: float
) -> None:
    """Start the streams ``sel`` of a seed-000-family detector afresh: the :data:`GAIT_STATE`
    fields of ``state`` and their ``clock`` (samples since the reset)."""
    state["last_valid"][sel] = np.nan
    state["baseline"][sel] = gravity
    state["n_seen"][sel] = 0.0
    state["last_peak"][sel] = -np.inf
    state["pending"][sel] = np.nan
    state["last_step"][sel] = -np.inf
    clock[sel] = 0


# Stages shared by the detectors of Zhang 2021's family (:mod:`estimators.steps.zhang2021` and
# :mod:`estimators.steps.nod_robust`): ``s`` is a stream's state record, ``p`` the parameter
# record (a step-parameter dataclass's fields plus ``fs``, ``base_n`` and ``latency``).


@numba.njit(cache=True, inline="always")
def running_baseline(s, p, x):
    """Move the baseline toward sample ``x`` (after ``n_seen`` counted it): a cumulative mean,
    then an exponential one of ``base_n`` samples, within ``gravity +- baseline_limit``; a fixed
    gravity where ``base_n`` is 0."""
    if p["base_n"] > 0.0:
        alpha = max(1.0 / s["n_seen"], 1.0 / p["base_n"])
        g0 = s["baseline"] + alpha * (x - s["baseline"])
        g, lim = p["gravity"], p["baseline_limit"]
        s["baseline"] = min(max(g0, g - lim), g + lim)


@numba.njit(cache=True, inline="always")
def mean_filter(raw, smooth, k, x):
    """Sample ``x`` of global index ``k`` into the ring ``raw`` (M), and the mean of its last M
    samples into the ring ``smooth`` (causal mean filter)."""
    m = raw.size
    raw[k % m] = x
    s = 0.0
    for j in range(m):
        s += raw[j]
    smooth[k % smooth.size] = s / m


@numba.njit(cache=True, inline="always")
def window_max(smooth, c, h):
    """Is sample ``c`` of the ring ``smooth`` (2h + 1) the maximum of its centred window: strictly
    above the h samples before it, at least the h after it (a flat top gives one peak)?"""
    w = smooth.size
    v = smooth[c % w]
    for j in range(1, h + 1):
        if smooth[(c - j) % w] >= v or smooth[(c + j) % w] > v:
            return False
    return True


@numba.njit(cache=True, inline="always")
def bout_rule(s, p, t, steps, peak_t, i):
    """Zhang 2021's bout rule for a peak at ``t`` (s), confirmed at chunk sample ``i``: ignored
    within ``min_step_interval`` of the last peak; a step, with the pending first peak of the bout
    released beside it, within ``gamma_t``; else the pending first peak of a new bout. Fills row
    ``i`` of ``steps`` (n,) and ``peak_t`` (n, 2)."""
    dt = t - s["last_peak"]
    if dt >= p["min_step_interval"]:
        if dt <= p["gamma_t"]:
            steps[i] = 1
            peak_t[i, 0] = t
            if math.isfinite(s["pending"]):
                steps[i] = 2
                peak_t[i, 1] = s["pending"]
                s["pending"] = math.nan
            s["last_step"] = t
        else:
            s["pending"] = t
        s["last_peak"] = t


@numba.njit(cache=True, inline="always")
def walking(s, p, k):
    """The still (0) / walk (1) state at sample ``k``: walk until ``gamma_t`` after the last
    step's peak, on the peak time axis (``latency`` after the fact)."""
    return 1 if k / p["fs"] - p["latency"] - s["last_step"] <= p["gamma_t"] else 0


def _gait_run(norm, k0, prm, state, raw_buf, sm_buf, out):
    """Run the detector over a chunk ``norm`` (B, n) of specific-force norms (m/s^2).

    Streams outside, samples inside. ``k0`` (B,) is each stream's index of the chunk's first sample,
    counted from the stream's reset (sample k is at time k / fs); ``prm`` the (1,) parameter record
    (:class:`GaitParams`' fields, ``fs``, ``base_n``, the baseline time constant in samples, 0:
    fixed gravity, and ``latency``); ``state`` the (B,) records of :data:`GAIT_STATE` and the ring
    buffers ``raw_buf`` (B, M) and ``sm_buf`` (B, 2h + 1), updated in place; ``out`` the chunk's
    ``(state, steps, peak_time)`` arrays (B, n), (B, n), (B, n, 2), filled.
    """
    out_state, out_steps, out_peak_t = out
    p = prm[0]
    nb, n = norm.shape
    m = raw_buf.shape[1]
    h = (sm_buf.shape[1] - 1) // 2
    delay = 0.5 * (m - 1)
    for b in numba.prange(nb):
        s = state[b]
        raw, sm = raw_buf[b], sm_buf[b]
        for i in range(n):
            k = k0[b] + i
            x = norm[b, i]
            if not math.isfinite(x):
                x = s["last_valid"] if math.isfinite(s["last_valid"]) else p["gravity"]
            s["last_valid"] = x
            if s["n_seen"] == 0.0:  # fresh stream: start both filters and the baseline at x
                raw[:] = x
                sm[:] = x
                s["baseline"] = p["gravity"] if p["base_n"] <= 0.0 else x
            s["n_seen"] += 1.0
            running_baseline(s, p, x)
            mean_filter(raw, sm, k, x)
            # Is the sample h back a peak: the maximum of its centred window, gamma above the
            # baseline?
            if s["n_seen"] > h:
                c = k - h
                if sm[c % sm.size] - s["baseline"] >= p["gamma"] and window_max(sm, c, h):
                    bout_rule(s, p, (c - delay) / p["fs"], out_steps[b], out_peak_t[b], i)
            out_state[b, i] = walking(s, p, k)


#: The compiled detector: ``gait_kernel(batch_size)(...)`` (see ``_gait_run``).
gait_kernel = BatchKernel(_gait_run, parallel=False)


# ------------------------------------------------------------------------------------------------
# The naive peak picker.
# ------------------------------------------------------------------------------------------------


#: Per-stream state of :func:`threshold_kernel`: the norms of the two previous samples (m/s^2),
#: the last step's time (s, -inf: none) and the samples seen.
THRESHOLD_STATE = {"prev2": (), "prev1": (), "last_step": (), "n_seen": ()}


def _threshold_run(acc, k0, prm, state, out):
    """Run the peak picker over a chunk ``acc`` (B, n, 3) of specific force (m/s^2).

    ``k0`` (B,) is each stream's index of the chunk's first sample, counted from the stream's
    reset (sample k is at time k / fs s);
    ``prm`` the (1,) parameter record (:class:`ThresholdParams`' fields, ``fs`` and ``level`` =
    gravity + threshold); ``state`` the (B,) records of :data:`THRESHOLD_STATE`, updated in place;
    ``out`` the chunk's ``(state, steps, peak_time)`` arrays (B, n), (B, n), (B, n, 2), filled
    (only column 0 of ``peak_time`` is used).
    """
    out_state, out_steps, out_peak_t = out
    p = prm[0]
    nb, n = acc.shape[0], acc.shape[1]
    for b in numba.prange(nb):
        s = state[b]
        x2, x1, last, seen = s["prev2"], s["prev1"], s["last_step"], s["n_seen"]
        for i in range(n):
            k = k0[b] + i
            x = math.sqrt(acc[b, i, 0] ** 2 + acc[b, i, 1] ** 2 + acc[b, i, 2] ** 2)
            if not math.isfinite(x):
                x = x1 if seen > 0 else p["gravity"]
            if seen == 0:  # fresh stream: no peak before its third sample
                x2 = x
                x1 = x
            seen += 1
            if x1 > x2 and x1 >= x and x1 > p["level"]:
                t = (k - 1) / p["fs"]
                if t - last >= p["refractory"]:
                    out_steps[b, i] = 1
                    out_peak_t[b, i, 0] = t
                    last = t
            out_state[b, i] = 1 if k / p["fs"] - last <= p["hold"] else 0
            x2 = x1
            x1 = x
        s["prev2"], s["prev1"], s["last_step"], s["n_seen"] = x2, x1, last, seen


#: The compiled peak picker: ``threshold_kernel(batch_size)(...)`` (see ``_threshold_run``).
threshold_kernel = BatchKernel(_threshold_run, parallel=False)


# ------------------------------------------------------------------------------------------------
# The world-vertical detector with the rotation veto.
# ------------------------------------------------------------------------------------------------


#: Per-stream scalars of :func:`nod_robust_kernel`: Zhang 2021's detector state
#: (:data:`estimators.steps._kernel.GAIT_STATE`), ``last_valid`` being the last usable vertical
#: specific force (its ring buffers, whose lengths follow the rate, are arrays beside it).
NOD_ROBUST_STATE = GAIT_STATE


def _nod_robust_run(acc, gyr, quat, k0, prm, state, v_buf, sm_buf, rot_buf, w_buf, out):
    """Run the detector over a chunk of n samples of B streams.

    Inputs (B, n, 3) specific force (m/s^2), (B, n, 3) gyro (rad/s), (B, n, 4) attitude ``[w, x, y,
    z]`` sensor -> world; ``k0`` (B,) each stream's index of the chunk's first sample, counted from
    the stream's reset (sample k is at time k / fs s); ``prm`` the (1,) parameter record
    (:class:`NodRobustParams`' fields, ``fs``, ``base_n``, the baseline time constant in samples, 0:
    fixed gravity, and ``latency``). State, updated in place: the (B,) records of
    :data:`NOD_ROBUST_STATE` and ring buffers of the vertical specific force ``v_buf`` (B, M), its
    mean ``sm_buf`` (B, 2h + 1), the rotation bound ``rot_buf`` (B, 2h + 1) and the world angular
    rate ``w_buf`` (B, M + 1, 3), all indexed by the sample's index modulo their length. ``out``:
    the chunk's ``(state, steps, peak_time)`` arrays (B, n), (B, n), (B, n, 2), filled.
    """
    out_state, out_steps, out_peak_t = out
    p = prm[0]
    nb, n = acc.shape[0], acc.shape[1]
    m = v_buf.shape[1]
    w = sm_buf.shape[1]
    h = (w - 1) // 2
    mw = w_buf.shape[1]  # M + 1
    delay = 0.5 * (m - 1)
    for b in numba.prange(nb):
        s = state[b]
        sm, rot, wb = sm_buf[b], rot_buf[b], w_buf[b]
        for i in range(n):
            k = k0[b] + i
            qw, qx, qy, qz = quat[b, i, 0], quat[b, i, 1], quat[b, i, 2], quat[b, i, 3]
            qn = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
            q_ok = math.isfinite(qn) and qn > 0.0
            if q_ok:
                qw, qx, qy, qz = qw / qn, qx / qn, qy / qn, qz / qn
            # 1. Vertical specific force in the world.
            ax, ay, az = acc[b, i, 0], acc[b, i, 1], acc[b, i, 2]
            if q_ok and math.isfinite(ax) and math.isfinite(ay) and math.isfinite(az):
                x = quat_rotate(qw, qx, qy, qz, ax, ay, az)[2]
            else:
                x = s["last_valid"] if math.isfinite(s["last_valid"]) else p["gravity"]
            s["last_valid"] = x
            # World angular rate (the previous one where this sample's is unusable).
            gx, gy, gz = gyr[b, i, 0], gyr[b, i, 1], gyr[b, i, 2]
            g_ok = q_ok and math.isfinite(gx) and math.isfinite(gy) and math.isfinite(gz)
            fresh = s["n_seen"] == 0.0
            wx = wy = wz = 0.0
            if g_ok:
                wx, wy, wz = quat_rotate(qw, qx, qy, qz, gx, gy, gz)
            elif not fresh:
                j = (k - 1) % mw
                wx, wy, wz = wb[j, 0], wb[j, 1], wb[j, 2]
            if fresh:  # start every filter at this sample
                v_buf[b] = x
                sm[:] = x
                rot[:] = 0.0
                for j in range(mw):
                    wb[j, 0], wb[j, 1], wb[j, 2] = wx, wy, wz
                s["baseline"] = p["gravity"] if p["base_n"] <= 0.0 else x
            s["n_seen"] += 1.0
            running_baseline(s, p, x)
            # 2. Mean filter (causal, M samples) into the peak window's ring buffer.
            mean_filter(v_buf[b], sm, k, x)
            # 3. Rotation bound over the same M samples: mean world rate, and the angular
            # acceleration from the rates at both ends of the window (M intervals apart).
            wb[k % mw, 0], wb[k % mw, 1], wb[k % mw, 2] = wx, wy, wz
            j0 = (k - m) % mw
            alx = (wx - wb[j0, 0]) * p["fs"] / m
            aly = (wy - wb[j0, 1]) * p["fs"] / m
            mx = my = mz = 0.0
            for j in range(1, m + 1):
                jj = (k - m + j) % mw
                mx += wb[jj, 0]
                my += wb[jj, 1]
                mz += wb[jj, 2]
            w_h = math.sqrt(mx * mx + my * my) / m
            rot[k % w] = p["lever_arm"] * (
                math.sqrt(alx * alx + aly * aly) + w_h * (w_h + abs(mz) / m)
            )
            # 4. Is the sample h back the maximum of its centred window, high enough, and higher
            # than the rotation can explain?
            if s["n_seen"] > h:
                c = k - h
                excess = sm[c % w] - s["baseline"]
                is_peak = excess >= p["gamma"] and window_max(sm, c, h)
                if is_peak:
                    for j in range(w):
                        if rot[j] >= excess:
                            is_peak = False
                if is_peak:  # 5. Zhang 2021's bout rule.
                    bout_rule(s, p, (c - delay) / p["fs"], out_steps[b], out_peak_t[b], i)
            out_state[b, i] = walking(s, p, k)


#: The compiled detector: ``nod_robust_kernel(batch_size)(...)`` (see ``_nod_robust_run``).
nod_robust_kernel = BatchKernel(_nod_robust_run, parallel=False)


# ------------------------------------------------------------------------------------------------
# Cadence from step events.
# ------------------------------------------------------------------------------------------------


#: Largest cadence reported (steps/s).
MAX_CADENCE = 4.0


#: Per-user state of :func:`cadence_kernel`: time since the last step (s, inf before any) and
#: the cadence (steps/s).
CADENCE_STATE = {"since_step": (), "cadence": ()}


def _cadence_run(steps, dt, prm, state):
    """One update of length ``dt`` (s) with ``steps`` (B,) new steps; ``prm`` the (1,) record of
    ``tau_s`` (s), ``state`` the (B,) records of :data:`CADENCE_STATE`, updated in place."""
    decay = math.exp(-dt / prm[0]["tau_s"])
    for b in numba.prange(steps.shape[0]):
        s = state[b]
        n = steps[b]
        since = s["since_step"] + dt
        if n > 0.0 and math.isfinite(since):
            c = n / max(since, dt)
        else:
            c = s["cadence"] * decay
        s["cadence"] = min(c, MAX_CADENCE)
        s["since_step"] = 0.0 if n > 0.0 else since


#: The compiled update: ``cadence_kernel(batch_size)(...)`` (see ``_cadence_run``).
cadence_kernel = BatchKernel(_cadence_run, parallel=False)


# ------------------------------------------------------------------------------------------------
# The Lee-2018-style detector: dips of the headset's pitch-compensated height.
# ------------------------------------------------------------------------------------------------

#: Per-stream scalars of :data:`lee2018_kernel`: the standing ``baseline`` height (m), whether a
#: dip is under way (``down``), its deepest point ``deepest`` (m below the baseline) and that
#: point's time ``deepest_t`` (s), the last step's time ``last_step`` (s; -inf: none) and the
#: samples seen ``n_seen``.
LEE2018_STATE = {
    "baseline": (),
    "down": (),
    "deepest": (),
    "deepest_t": (),
    "last_step": (),
    "n_seen": (),
}


def _lee2018_run(pos, quat, k0, prm, state, out):
    """Run the detector over a chunk: ``pos`` (B, n, 3) headset positions (m, z up) and ``quat``
    (B, n, 4) attitudes.

    The neck pivot's height is the headset's less the headset's offset from the pivot turned by
    the attitude (``prm``'s ``off_x``, ``off_y``, ``off_z`` in the head frame), so that tilting
    the head does not move it; its ``baseline`` follows it with the time constant ``baseline_s``.
    A dip starts when the pivot is ``dip_m`` below the baseline and ends when it is back within
    ``dip_m / 2``; its deepest point is a step, unless it comes less than ``min_interval_s``
    after the last step. Walk while the last step is at most ``hold_s`` old. ``k0`` (B,) is each
    stream's index of the chunk's first sample; ``state`` the (B,) records of
    :data:`LEE2018_STATE`; ``out`` the chunk's ``(state, steps, peak_time)`` arrays.
    """
    out_state, out_steps, out_peak_t = out
    p = prm[0]
    fs = p["fs"]
    alpha = 1.0 - math.exp(-1.0 / (fs * p["baseline_s"]))
    nb, n = pos.shape[0], pos.shape[1]
    for b in numba.prange(nb):
        s = state[b]
        base, down, deepest, deepest_t = s["baseline"], s["down"], s["deepest"], s["deepest_t"]
        last, seen = s["last_step"], s["n_seen"]
        for i in range(n):
            t = (k0[b] + i) / fs
            lift = quat_rotate(
                quat[b, i, 0],
                quat[b, i, 1],
                quat[b, i, 2],
                quat[b, i, 3],
                p["off_x"],
                p["off_y"],
                p["off_z"],
            )[2]
            h = pos[b, i, 2] - lift
            if not math.isfinite(h):
                out_state[b, i] = 1 if t - last <= p["hold_s"] else 0
                continue
            if seen == 0:
                base = h
            seen += 1
            dip = base - h
            if down == 0.0:
                if dip > p["dip_m"]:
                    down, deepest, deepest_t = 1.0, dip, t
            else:
                if dip > deepest:
                    deepest, deepest_t = dip, t
                if dip < 0.5 * p["dip_m"]:
                    down = 0.0
                    if deepest_t - last >= p["min_interval_s"]:
                        out_steps[b, i] = 1
                        out_peak_t[b, i, 0] = deepest_t
                        last = deepest_t
            base += alpha * (h - base)
            out_state[b, i] = 1 if t - last <= p["hold_s"] else 0
        s["baseline"], s["down"], s["deepest"], s["deepest_t"] = base, down, deepest, deepest_t
        s["last_step"], s["n_seen"] = last, seen


#: The compiled detector: ``lee2018_kernel(batch_size)(...)`` (see ``_lee2018_run``).
lee2018_kernel = BatchKernel(_lee2018_run, parallel=False)
