"""Walking-in-place measures of one episode, from its ``info`` alone: start and stop latency,
stop overshoot, false motion, yaw drift while standing, yaw-rate mismatch, virtual jerk, steering
error (:func:`motion_measures`), and the walking-in-place user's play area
(:func:`play_area_measures`).

The play area: from ``info["play_area_outside"]`` and ``info["play_area_boundary_m"]`` (the user's
physical spot in the tracked space, :mod:`vrloco_env.user.play_area`): ``boundary_violations``,
the times per episode the user crosses from inside the area to outside (the episode starts inside,
at the centre), and ``min_boundary_m``, the episode's smallest distance to the nearest edge
(negative: it went outside).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from agents.benchmark.cell_statistics import exact_mean
from agents.benchmark.step_matching import finite_times
from estimators.rotations import wrap_angle

__all__ = [
    "MOTION_KEYS",
    "MOVING_M",
    "PLAY_AREA_KEYS",
    "STANDING_SETTLE_S",
    "motion_measures",
    "play_area_measures",
    "steering_offsets_deg",
]

#: The per-episode walking-in-place measures a row averages (:func:`motion_measures`).
MOTION_KEYS = (
    "start_latency_s",
    "stop_latency_s",
    "stop_overshoot_m",
    "false_motion_m_per_min",
    "yaw_drift_deg_per_min",
    "yaw_rate_mismatch_deg_s",
    "virtual_jerk_m_s3",
    "steering_error_deg",
)


#: A user counts as standing this long (s) after their last true heel strike: the stop itself
#: (the detector's delay, a smoothing filter's ramp-down) is the stop latency, not false motion.
STANDING_SETTLE_S = 3.0
#: The virtual body counts as moving in a control step that carries it farther than this (m).
MOVING_M = 1e-6


def steering_offsets_deg(steps: dict[str, NDArray]) -> NDArray[np.float64] | None:
    """Per control step, the walking direction (``walk_yaw_deg``) minus the true torso direction
    (``true_body_yaw_deg``), wrapped into (-180, 180] deg; None without those keys."""
    if "walk_yaw_deg" not in steps or "true_body_yaw_deg" not in steps:
        return None
    walk = np.asarray(steps["walk_yaw_deg"], dtype=np.float64).ravel()
    body = np.asarray(steps["true_body_yaw_deg"], dtype=np.float64).ravel()
    return np.rad2deg(wrap_angle(np.deg2rad(walk - body)))


def motion_measures(
    steps: dict[str, NDArray], start_position: ArrayLike | None
) -> dict[str, float]:
    """Walking-in-place measures of one episode from its stacked ``info`` values (NaN where an
    episode gives no case to measure).

    Bouts are the runs of control steps in which the user means to step (``intent_walk``); a
    bout's true heel strikes are those from its start to the next bout's start.

    * ``start_latency_s`` (mean over bouts): from the bout's first true heel strike to the end
      of the first control step that moves the virtual body.
    * ``stop_latency_s``: from the bout's last true heel strike to the end of the last control
      step within :data:`STANDING_SETTLE_S` after it that moves the virtual body (negative when
      the body stopped before the last heel strike: its last steps were missed). Bouts the
      episode cuts short are left out: the next bout or the episode's end must come at least
      :data:`STANDING_SETTLE_S` after the last heel strike.
    * ``stop_overshoot_m``: how much farther the virtual body went than perfect sensing would
      have (``true_position``) from the bout's start to :data:`STANDING_SETTLE_S` after its
      last heel strike, when it went farther; 0 otherwise.
    * ``false_motion_m_per_min``: virtual metres moved per minute of standing (no intent to
      step, the last true heel strike :data:`STANDING_SETTLE_S` or more ago).
    * ``yaw_drift_deg_per_min``: change of the heading error (virtual minus true heading) per
      minute while the user means to stand still: neither stepping nor turning
      (``intent_turn``), the last true heel strike :data:`STANDING_SETTLE_S` or more ago.
    * ``yaw_rate_mismatch_deg_s``: RMS over the episode of the virtual yaw rate minus the true
      head yaw rate (the visual-vestibular conflict).
    * ``virtual_jerk_m_s3``: RMS magnitude of the third difference of the virtual positions over
      the control step cubed.
    * ``steering_error_deg``: RMS over the control steps that move the virtual body of the
      direction it moves in (``walk_yaw_deg``) minus the true torso direction
      (``true_body_yaw_deg``): how far the locomotion walks off where the body faces (head
      steering while the user looks aside; NaN without those keys or without a moving step).
    * ``standing_min``: the minutes of standing the false-motion rate is over.
    """
    intent = np.asarray(steps["intent_walk"], dtype=bool).ravel()
    t_end = np.asarray(steps["elapsed_time"], dtype=np.float64).ravel()
    n = intent.size
    nan = math.nan
    out = dict.fromkeys(
        (
            "start_latency_s",
            "stop_latency_s",
            "stop_overshoot_m",
            "false_motion_m_per_min",
            "yaw_drift_deg_per_min",
            "yaw_rate_mismatch_deg_s",
            "virtual_jerk_m_s3",
            "steering_error_deg",
        ),
        nan,
    )
    out["standing_min"] = 0.0
    if n == 0:
        return out
    dt = float(t_end[0])
    pos = np.asarray(steps["position"], dtype=np.float64).reshape(n, 2)
    true_pos = np.asarray(steps["true_position"], dtype=np.float64).reshape(n, 2)
    start = pos[0] if start_position is None else np.asarray(start_position, np.float64)[:2]
    path = np.concatenate([start[None], pos])
    true_path = np.concatenate([start[None], true_pos])
    moved = np.hypot(*np.diff(path, axis=0).T)
    true_moved = np.hypot(*np.diff(true_path, axis=0).T)
    strikes = finite_times(steps["true_step_times"])
    # bouts: runs of intent; each owns the steps up to the next run's start
    edges = np.flatnonzero(np.diff(np.concatenate([[0], intent.astype(np.int8), [0]])))
    runs = list(zip(edges[::2], edges[1::2], strict=True))
    starts, stops, overshoots = [], [], []
    for b, (r0, _) in enumerate(runs):
        r_next = runs[b + 1][0] if b + 1 < len(runs) else n
        t0, t1 = t_end[r0] - dt, (t_end[r_next] - dt) if r_next < n else t_end[-1]
        mine = strikes[(strikes > t0 - 1e-9) & (strikes <= t1 + 1e-9)]
        if mine.size == 0:
            continue
        idx = np.arange(r0, r_next)
        moving = idx[moved[idx] > MOVING_M]
        if moving.size:
            starts.append(t_end[moving[0]] - mine[0])
        if t1 - mine[-1] < STANDING_SETTLE_S:  # cut short: no stop to measure
            continue
        stop_window = idx[t_end[idx] <= mine[-1] + STANDING_SETTLE_S + 1e-9]
        stopping = stop_window[moved[stop_window] > MOVING_M]
        if stopping.size:
            stops.append(t_end[stopping[-1]] - mine[-1])
        over = moved[stop_window].sum() - true_moved[stop_window].sum()
        overshoots.append(max(0.0, float(over)))
    for key, vals in (
        ("start_latency_s", starts),
        ("stop_latency_s", stops),
        ("stop_overshoot_m", overshoots),
    ):
        if vals:
            out[key] = exact_mean(vals)
    # standing: no intent, the last true heel strike long enough ago
    last = np.searchsorted(strikes, t_end, side="right") - 1
    if strikes.size:
        since = np.where(last >= 0, t_end - strikes[np.maximum(last, 0)], np.inf)
    else:
        since = np.full(n, np.inf)
    standing = ~intent & (since >= STANDING_SETTLE_S)
    minutes = standing.sum() * dt / 60.0
    out["standing_min"] = float(minutes)
    if minutes > 0:
        out["false_motion_m_per_min"] = math.fsum(moved[standing].tolist()) / minutes
    err = np.deg2rad(np.asarray(steps["heading_error_deg"], dtype=np.float64).ravel())
    turning = np.asarray(steps.get("intent_turn", np.zeros(n, bool)), dtype=bool).ravel()
    still = standing & ~turning
    if n > 1 and still[1:].any():
        d_err = np.rad2deg(np.abs(wrap_angle(np.diff(err))))[still[1:]]
        out["yaw_drift_deg_per_min"] = math.fsum(d_err.tolist()) / (d_err.size * dt / 60.0)
    if n > 1:
        v_rate = wrap_angle(np.diff(np.asarray(steps["virtual_yaw"], np.float64).ravel())) / dt
        true_yaw = np.deg2rad(np.asarray(steps["true_ypr"], np.float64).reshape(n, 3)[:, 0])
        t_rate = wrap_angle(np.diff(true_yaw)) / dt
        out["yaw_rate_mismatch_deg_s"] = math.degrees(math.sqrt(exact_mean((v_rate - t_rate) ** 2)))
    if path.shape[0] >= 4:
        jerk = np.diff(path, n=3, axis=0) / dt**3
        out["virtual_jerk_m_s3"] = math.sqrt(exact_mean((jerk**2).sum(axis=1)))
    walking = moved > MOVING_M
    off = steering_offsets_deg(steps)
    if off is not None and walking.any():
        out["steering_error_deg"] = math.sqrt(exact_mean(off[walking] ** 2))
    return out


#: The per-episode play-area measures a row averages (:func:`play_area_measures`).
PLAY_AREA_KEYS = ("boundary_violations", "min_boundary_m")


def play_area_measures(steps: dict[str, NDArray]) -> dict[str, float]:
    """An episode's play-area measures from its per-step ``info`` arrays.

    Args:
        steps: ``play_area_outside`` (T,) bool and ``play_area_boundary_m`` (T,) (m).

    Returns:
        ``boundary_violations``: crossings from inside the area to outside (the episode
        starts inside); ``min_boundary_m``: the smallest distance to the nearest edge (m,
        negative outside; NaN for an empty episode).
    """
    outside = np.asarray(steps["play_area_outside"], dtype=bool).ravel()
    margin = np.asarray(steps["play_area_boundary_m"], dtype=np.float64).ravel()
    before = np.concatenate([[False], outside[:-1]])
    return {
        "boundary_violations": float(np.count_nonzero(outside & ~before)),
        "min_boundary_m": float(margin.min()) if margin.size else math.nan,
    }
