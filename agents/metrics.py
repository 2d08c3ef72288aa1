"""Benchmark metrics: navigation success and efficiency, step detection, estimation errors.

Per episode the benchmark keeps an :class:`EpisodeStats` (built step by step by
:class:`EpisodeRecorder` from the env's ``info``); :func:`summarize` turns a list of them into one
row of the benchmark table. The definitions:

* **success rate** — fraction of episodes with ``info["is_success"]`` at their end (Avoid counts
  only collision-free arrivals, the task's own rule).
* **collision rate** — fraction of episodes with at least one collision (a blocked step).
* **collision-free success rate** — fraction of episodes that succeed with no collision.
* **SPL** — success weighted by path length, Anderson et al. 2018 ("On Evaluation of Embodied
  Navigation Agents", arXiv:1807.06757, eq. 1): ``mean_i S_i * l_i / max(p_i, l_i)`` with ``l_i``
  the shortest path (``info["shortest_path"]``, the layout's planned length) and ``p_i`` the
  path walked by the virtual body (``info["walked"]``).
* **time to goal** — mean episode time (s) of the successful episodes.
* **path-length ratio** — mean ``walked / shortest`` of the successful episodes (failed ones
  would mix in how long the user wandered before the time limit).
* **step precision / recall / F1** — detected vs true steps, see :func:`match_step_counts`.
* **attitude RMSE** — root mean square of ``info["attitude_error_deg"]`` (the rotation angle
  between true and estimated head attitude) over every control step of every episode.
* **hand error** — mean of ``info["hand_error_deg"]`` over the control steps with a hand
  estimate, and the fraction of steps that had one.
* **play area** — from ``info["play_area_outside"]`` and ``info["play_area_boundary_m"]`` (the
  walking-in-place user's physical spot in the tracked space, :mod:`vrloco_env.user.play_area`):
  ``boundary_violations``, the times per episode the user crosses from inside the area to outside
  (the episode starts inside, at the centre), and ``min_boundary_m``, the episode's smallest
  distance to the nearest edge (negative: it went outside); a row gives their means over the
  episodes (:func:`play_area_measures`).

Step F1. The env reports the true heel-strike times and the detector's estimated heel-strike
times of each step (``info["true_step_times"]``, ``info["detected_step_times"]``, episode time,
inf-padded); they are matched one to one within +-0.2 s, seed 000's tolerance
(:func:`match_step_times`, :func:`estimators.gait.step_f1`). The detector is causal and
reports a step 0.135 s after it, and the first step of a walking bout only with the second;
matching the estimated heel-strike times, not the reporting times, judges where a step was
detected, not when. :func:`match_step_counts` (counts per control step in a window) remains for
recordings without times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.gait import step_f1

__all__ = [
    "CAUSE_WINDOW_S",
    "COLLISION_CAUSES",
    "DEFAULT_LATE_STEPS",
    "HEADING_BOUND_DEG",
    "MOTION_KEYS",
    "PLAY_AREA_KEYS",
    "STEERING_BOUND_DEG",
    "STEP_KEYS",
    "TRACE_KEYS",
    "EpisodeRecorder",
    "EpisodeStats",
    "bootstrap_interval",
    "collision_causes",
    "episode_stats",
    "match_step_counts",
    "match_step_times",
    "motion_measures",
    "play_area_measures",
    "spl",
    "summarize",
    "wilson_interval",
]

#: Default lateness (control steps) allowed between a heel strike and its detection: 0.2 s.
DEFAULT_LATE_STEPS = 2
#: Step matching tolerance (s), seed 000's +-0.2 s.
STEP_TOLERANCE_S = 0.2


def _array(name: str, x: ArrayLike, dtype: Any = np.float64) -> NDArray:
    a = np.asarray(x, dtype=dtype)
    if a.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional (one entry per episode), got {a.shape}")
    return a


def spl(success: ArrayLike, shortest: ArrayLike, walked: ArrayLike) -> float:
    """Success weighted by path length (Anderson et al. 2018, eq. 1), averaged over episodes.

    Args:
        success: 1/True for successful episodes, (N,).
        shortest: shortest path length of each episode (m), > 0, (N,).
        walked: path length walked (m), >= 0, (N,).

    Returns:
        SPL in [0, 1]; NaN for no episodes.

    Raises:
        ValueError: mismatched lengths, a non-positive shortest path or a negative walked length.
    """
    s = _array("success", success).astype(bool)
    lo = _array("shortest", shortest)
    p = _array("walked", walked)
    if not (s.shape == lo.shape == p.shape):
        raise ValueError(
            f"success, shortest, walked must have one length, got {s.shape}, {lo.shape}, {p.shape}"
        )
    if s.size == 0:
        return math.nan
    if not np.all(np.isfinite(lo) & (lo > 0.0)):
        raise ValueError("shortest must be finite and > 0 m")
    if not np.all(np.isfinite(p) & (p >= 0.0)):
        raise ValueError("walked must be finite and >= 0 m")
    return _mean(s * lo / np.maximum(lo, p))


def match_step_times(
    true_times: ArrayLike, detected_times: ArrayLike, tol: float = STEP_TOLERANCE_S
) -> tuple[int, int, int]:
    """(tp, fp, fn) of detected vs true heel-strike times matched one to one within ``tol`` s
    (:func:`estimators.gait.step_f1`'s matching)."""
    true = np.asarray(true_times, dtype=np.float64)
    det = np.asarray(detected_times, dtype=np.float64)
    _, recall, _ = step_f1(det, true, tol=tol)
    tp = round(recall * true.size) if true.size else 0
    return tp, int(det.size - tp), int(true.size - tp)


def match_step_counts(
    true_counts: ArrayLike,
    detected_counts: ArrayLike,
    late: int = DEFAULT_LATE_STEPS,
    early: int = DEFAULT_LATE_STEPS,
) -> tuple[int, int, int]:
    """Match true and detected steps given as counts per control step.

    A detection at control step ``k`` may match one true step at ``j`` with
    ``k - late <= j <= k + early``; each step matches at most once (greedy in time order, a
    maximum matching for this window).

    Args:
        true_counts: true heel strikes per control step, (T,) non-negative integers.
        detected_counts: detected steps per control step, (T,) non-negative integers.
        late: how many control steps a detection may come after its heel strike.
        early: how many control steps a detection may come before it.

    Returns:
        ``(true_positives, false_positives, false_negatives)``.

    Raises:
        ValueError: different lengths, negative or non-integer counts, negative windows.
    """
    t = np.asarray(true_counts)
    d = np.asarray(detected_counts)
    if t.ndim != 1 or d.shape != t.shape:
        raise ValueError(
            f"true_counts and detected_counts must be (T,) arrays of one length, "
            f"got {t.shape} and {d.shape}"
        )
    for name, a in (("true_counts", t), ("detected_counts", d)):
        if a.size and (np.any(a < 0) or np.any(a != np.round(a)) or not np.all(np.isfinite(a))):
            raise ValueError(f"{name} must hold non-negative integers")
    if late < 0 or early < 0:
        raise ValueError(f"late and early must be >= 0 control steps, got {late}, {early}")
    idx = np.arange(t.size)
    true_ev = np.repeat(idx, t.astype(np.int64))
    det_ev = np.repeat(idx, d.astype(np.int64))
    tp = 0
    i = 0
    for k in det_ev:  # both sorted: a two-pointer sweep
        while i < true_ev.size and true_ev[i] < k - late:
            i += 1
        if i < true_ev.size and true_ev[i] <= k + early:
            tp += 1
            i += 1
    return tp, int(det_ev.size - tp), int(true_ev.size - tp)


def _mean(x: ArrayLike) -> float:
    """Mean with an exactly rounded sum (``math.fsum``): the same value whatever the order of
    the episodes' arrays in memory (numpy's pairwise SIMD sum can differ in the last bit with
    the alignment, which would make results depend on the number of worker processes).
    NaN for no values."""
    a = np.asarray(x, dtype=np.float64).ravel()
    return math.fsum(a.tolist()) / a.size if a.size else math.nan


def _prf(tp: int, fp: int, fn: int) -> tuple[float, float, float]:
    """Precision, recall, F1 with the conventions of :func:`estimators.gait.step_f1`."""
    if tp + fp + fn == 0:
        return 1.0, 1.0, 1.0
    precision = tp / (tp + fp) if tp + fp else 1.0
    recall = tp / (tp + fn) if tp + fn else 1.0
    f1 = 2 * precision * recall / (precision + recall) if precision + recall else 0.0
    return precision, recall, f1


@dataclass
class EpisodeStats:
    """What one episode contributes to the metrics.

    Attributes:
        seed: the episode's seed.
        success: ``info["is_success"]`` at the end.
        collisions: blocked steps in the episode.
        steps: control steps taken.
        elapsed_s: episode time (s).
        walked_m: path length of the virtual body (m).
        shortest_m: shortest path length (m).
        true_counts: true heel strikes per control step.
        detected_counts: detected steps per control step.
        attitude_error_deg: attitude error per control step (deg).
        hand_error_deg: hand orientation error per control step (deg, NaN without estimate).
        heading_error_deg: virtual minus true heading per control step (deg).
        true_step_times: true heel-strike times of the episode (s), or None.
        detected_step_times: the detector's heel-strike estimates (s), or None (then the step
            F1 falls back to :func:`match_step_counts`).
        trace: optional per-step arrays for figures (see :class:`EpisodeRecorder`).
        motion: the episode's walking-in-place measures (:func:`motion_measures`), or None.
        causes: the cause of each of the episode's collisions, counted
            (:func:`collision_causes`), or None when the ``info`` lacks what it needs.
        play_area: the episode's play-area measures (:func:`play_area_measures`), or None.
    """

    seed: int
    success: bool
    collisions: int
    steps: int
    elapsed_s: float
    walked_m: float
    shortest_m: float
    true_counts: NDArray[np.int64]
    detected_counts: NDArray[np.int64]
    attitude_error_deg: NDArray[np.float64]
    hand_error_deg: NDArray[np.float64]
    heading_error_deg: NDArray[np.float64]
    true_step_times: NDArray[np.float64] | None = None
    detected_step_times: NDArray[np.float64] | None = None
    trace: dict[str, Any] | None = field(default=None)
    motion: dict[str, float] | None = field(default=None)
    causes: dict[str, int] | None = field(default=None)
    play_area: dict[str, float] | None = field(default=None)


#: The ``info`` keys an episode's stats are built from, per control step.
STEP_KEYS = (
    "true_steps",
    "detected_steps",
    "true_step_times",
    "detected_step_times",
    "attitude_error_deg",
    "hand_error_deg",
    "heading_error_deg",
    "intent_walk",
    "intent_turn",
    "position",
    "true_position",
    "virtual_yaw",
    "true_ypr",
    "elapsed_time",
    "collision",
    "walk_yaw_deg",
    "true_body_yaw_deg",
    "play_area_boundary_m",
    "play_area_outside",
)
#: The ``info`` keys kept per control step for the figures.
TRACE_KEYS = (
    "position",
    "true_position",
    "true_ypr",
    "est_ypr",
    "true_step_times",
    "elapsed_time",
)


class EpisodeRecorder:
    """Collects an episode's ``info`` dicts (single env) into :class:`EpisodeStats`.

    Args:
        seed: the episode's seed.
        reset_info: the ``info`` from ``reset`` (for ``shortest_path``).
        trace: also keep per-step traces (positions, attitude, step times) for figures.
    """

    def __init__(self, seed: int, reset_info: dict, trace: bool = False) -> None:
        if "shortest_path" not in reset_info:
            raise ValueError("reset_info must hold 'shortest_path' (the env's reset info)")
        self.seed = int(seed)
        self.shortest = float(reset_info["shortest_path"])
        self.keep_trace = trace
        self._rows: dict[str, list] = {k: [] for k in STEP_KEYS}
        self._trace: dict[str, list] = {k: [] for k in TRACE_KEYS}
        self._last: dict | None = None

    def add(self, info: dict) -> None:
        """Record one step's ``info``."""
        for k, rows in self._rows.items():
            rows.append(info[k])
        if self.keep_trace:
            for k, rows in self._trace.items():
                rows.append(np.array(info[k], dtype=np.float64, copy=True))
        self._last = info

    def finish(self, start_position: ArrayLike | None = None) -> EpisodeStats:
        """The episode's stats (``start_position``: the virtual start, for the trace)."""
        if self._last is None:
            raise RuntimeError("no step recorded: call add(info) after each env.step")
        steps = {k: np.asarray(v) for k, v in self._rows.items()}
        trace = None
        if self.keep_trace:
            trace = {k: np.asarray(v) for k, v in self._trace.items()}
        return episode_stats(self.seed, self.shortest, steps, self._last, trace, start_position)


def episode_stats(
    seed: int,
    shortest: float,
    steps: dict[str, NDArray],
    last: dict,
    trace: dict[str, NDArray] | None = None,
    start_position: ArrayLike | None = None,
) -> EpisodeStats:
    """:class:`EpisodeStats` from one episode's per-step arrays.

    Args:
        seed: the episode's seed.
        shortest: its shortest path (m).
        steps: the ``info`` values of every control step stacked, (T, ...) per key (the keys
            :class:`EpisodeRecorder` keeps).
        last: the last step's ``info`` (``is_success``, ``collisions``, ``elapsed_time``,
            ``walked``), scalars.
        trace: stacked trace arrays for figures (``position``, ``true_position``, ``true_ypr``,
            ``est_ypr``, ``true_step_times``, ``elapsed_time``), or None.
        start_position: the virtual start, prepended to the traced paths.
    """
    if trace is not None:
        trace = {k: np.asarray(v, dtype=np.float64) for k, v in trace.items()}
        trace["true_step_times"] = _finite_times(trace["true_step_times"])
        if start_position is not None:
            s = np.asarray(start_position, dtype=np.float64)[None]
            trace["position"] = np.concatenate([s, trace["position"]])
            trace["true_position"] = np.concatenate([s, trace["true_position"]])
    return EpisodeStats(
        seed=int(seed),
        success=bool(last["is_success"]),
        collisions=int(last["collisions"]),
        steps=len(steps["true_steps"]),
        elapsed_s=float(last["elapsed_time"]),
        walked_m=float(last["walked"]),
        shortest_m=float(shortest),
        true_counts=np.asarray(steps["true_steps"], dtype=np.int64),
        detected_counts=np.asarray(steps["detected_steps"], dtype=np.int64),
        true_step_times=_finite_times(steps["true_step_times"]),
        detected_step_times=_finite_times(steps["detected_step_times"]),
        attitude_error_deg=np.asarray(steps["attitude_error_deg"], dtype=np.float64),
        hand_error_deg=np.asarray(steps["hand_error_deg"], dtype=np.float64),
        heading_error_deg=np.asarray(steps["heading_error_deg"], dtype=np.float64),
        trace=trace,
        motion=motion_measures(steps, start_position) if "intent_walk" in steps else None,
        causes=collision_causes(steps) if "collision" in steps and "intent_walk" in steps
        else None,
        play_area=play_area_measures(steps) if "play_area_outside" in steps else None,
    )


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


#: The causes a collision is put down to, in the order they are tested: the first that holds is
#: the cause (:func:`collision_causes`).
COLLISION_CAUSES = ("phantom_step", "stop_latency", "heading_error", "steering", "policy")
#: The detected steps that may have carried the body into a collision: those reported in the
#: control steps of the last second (eq 17 moves the body with the step it reports; the smooth
#: filter of seed 001 spreads a step over about 0.5 s).
CAUSE_WINDOW_S = 1.0
#: A heading error (virtual minus true head yaw) beyond this (deg) is the cause: at 10 deg a
#: 0.7 m step lands 0.12 m to the side, more than the scripted users' 0.1 m margin (engineering
#: choice).
HEADING_BOUND_DEG = 10.0
#: The walking direction (the steering stage's yaw) farther than this (deg) from the direction
#: the body faces (the true torso yaw in the virtual room) is the cause: the body was walked
#: where it was not facing, e.g. where the head looked (engineering choice, as the heading bound).
STEERING_BOUND_DEG = 10.0


def collision_causes(steps: dict[str, NDArray]) -> dict[str, int]:
    """How many of an episode's collisions (``info["collision"]``) go to each cause of
    :data:`COLLISION_CAUSES`, from its stacked ``info`` values. A collision's cause is the first
    that holds at its control step:

    * ``phantom_step``: a step the detector reported in the last :data:`CAUSE_WINDOW_S` has no
      true heel strike within :data:`STEP_TOLERANCE_S` of its estimated time;
    * ``stop_latency``: the user meant to stand (``intent_walk`` false), the body still moved;
    * ``heading_error``: ``|info["heading_error_deg"]|`` beyond :data:`HEADING_BOUND_DEG`;
    * ``steering``: the walking direction (``info["walk_yaw_deg"]``) beyond
      :data:`STEERING_BOUND_DEG` from the true torso direction (``info["true_body_yaw_deg"]``),
      both in the virtual room (tested only where the ``info`` has them);
    * ``policy``: none of these — sensing did what perfect sensing would have, and the user
      walked into the obstacle.
    """
    out = dict.fromkeys(COLLISION_CAUSES, 0)
    hit = np.asarray(steps["collision"], dtype=bool).ravel()
    if not hit.any():
        return out
    n = hit.size
    t_end = np.asarray(steps["elapsed_time"], dtype=np.float64).ravel()
    intent = np.asarray(steps["intent_walk"], dtype=bool).ravel()
    heading = np.asarray(steps["heading_error_deg"], dtype=np.float64).ravel()
    strikes = _finite_times(steps["true_step_times"])
    detected = np.asarray(steps["detected_step_times"], dtype=np.float64).reshape(n, -1)
    steer = None
    if "walk_yaw_deg" in steps and "true_body_yaw_deg" in steps:
        walk = np.asarray(steps["walk_yaw_deg"], dtype=np.float64).ravel()
        body = np.asarray(steps["true_body_yaw_deg"], dtype=np.float64).ravel()
        steer = np.rad2deg(np.abs(_wrap(np.deg2rad(walk - body))))
    for k in np.flatnonzero(hit):
        recent = detected[(t_end > t_end[k] - CAUSE_WINDOW_S - 1e-9) & (t_end <= t_end[k])]
        recent = recent[np.isfinite(recent)]
        if strikes.size:
            gap = np.abs(recent[:, None] - strikes[None, :]).min(axis=1)
        else:
            gap = np.full(recent.size, np.inf)
        if np.any(gap > STEP_TOLERANCE_S):
            cause = "phantom_step"
        elif not intent[k]:
            cause = "stop_latency"
        elif abs(heading[k]) > HEADING_BOUND_DEG:
            cause = "heading_error"
        elif steer is not None and steer[k] > STEERING_BOUND_DEG:
            cause = "steering"
        else:
            cause = "policy"
        out[cause] += 1
    return out


#: A user counts as standing this long (s) after their last true heel strike: the stop itself
#: (the detector's delay, a smoothing filter's ramp-down) is the stop latency, not false motion.
STANDING_SETTLE_S = 3.0
#: The virtual body counts as moving in a control step that carries it farther than this (m).
MOVING_M = 1e-6


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
    * ``standing_min``: the minutes of standing the false-motion rate is over.
    """
    intent = np.asarray(steps["intent_walk"], dtype=bool).ravel()
    t_end = np.asarray(steps["elapsed_time"], dtype=np.float64).ravel()
    n = intent.size
    nan = math.nan
    out = dict.fromkeys(("start_latency_s", "stop_latency_s", "stop_overshoot_m",
                         "false_motion_m_per_min", "yaw_drift_deg_per_min",
                         "yaw_rate_mismatch_deg_s", "virtual_jerk_m_s3"), nan)  # fmt: skip
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
    strikes = _finite_times(steps["true_step_times"])
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
    for key, vals in (("start_latency_s", starts), ("stop_latency_s", stops),
                      ("stop_overshoot_m", overshoots)):  # fmt: skip
        if vals:
            out[key] = _mean(vals)
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
        d_err = np.rad2deg(np.abs(_wrap(np.diff(err))))[still[1:]]
        out["yaw_drift_deg_per_min"] = math.fsum(d_err.tolist()) / (d_err.size * dt / 60.0)
    if n > 1:
        v_rate = _wrap(np.diff(np.asarray(steps["virtual_yaw"], np.float64).ravel())) / dt
        true_yaw = np.deg2rad(np.asarray(steps["true_ypr"], np.float64).reshape(n, 3)[:, 0])
        t_rate = _wrap(np.diff(true_yaw)) / dt
        out["yaw_rate_mismatch_deg_s"] = math.degrees(math.sqrt(_mean((v_rate - t_rate) ** 2)))
    if path.shape[0] >= 4:
        jerk = np.diff(path, n=3, axis=0) / dt**3
        out["virtual_jerk_m_s3"] = math.sqrt(_mean((jerk**2).sum(axis=1)))
    return out


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def wilson_interval(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """The 95 % Wilson score interval of a rate ``successes / n`` (NaN, NaN for n = 0)."""
    if n == 0:
        return math.nan, math.nan
    p = successes / n
    den = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, centre - half), min(1.0, centre + half)


def bootstrap_interval(values: ArrayLike, resamples: int = 2000,
                       seed: int = 0) -> tuple[float, float]:  # fmt: skip
    """The 95 % percentile bootstrap interval of the mean of ``values`` (NaN entries left out;
    NaN, NaN without values). Seeded: the same values give the same interval."""
    x = np.asarray(values, dtype=np.float64).ravel()
    x = x[np.isfinite(x)]
    if x.size == 0:
        return math.nan, math.nan
    if x.size == 1:
        return float(x[0]), float(x[0])
    rng = np.random.default_rng(seed)
    means = x[rng.integers(0, x.size, size=(resamples, x.size))].mean(axis=1)
    lo, hi = np.percentile(means, [2.5, 97.5])
    return float(lo), float(hi)


def _finite_times(per_step: ArrayLike) -> NDArray[np.float64]:
    """The sorted finite times of per-step padded time arrays, (T, K)."""
    t = np.ravel(np.asarray(per_step, dtype=np.float64))
    return np.sort(t[np.isfinite(t)])


def summarize(
    episodes: list[EpisodeStats], late: int = DEFAULT_LATE_STEPS, early: int = DEFAULT_LATE_STEPS
) -> dict[str, float | int]:
    """One benchmark row from a cell's episodes (see the module docstring for definitions).

    Args:
        episodes: the cell's episodes.
        late, early: the step-matching window (control steps), :func:`match_step_counts`.

    Returns:
        ``episodes``, ``success_rate``, ``collision_rate``, ``collision_free_success_rate``,
        ``spl``, ``time_to_goal_s``, ``path_length_ratio``, ``step_precision``, ``step_recall``,
        ``step_f1``, ``attitude_rmse_deg``, ``heading_error_rmse_deg``, ``hand_error_deg``,
        ``hand_coverage``, ``mean_collisions``, ``boundary_violations`` and ``min_boundary_m``
        (means over the episodes that report them), ``collision_causes`` (collisions per cause of
        :data:`COLLISION_CAUSES`, summed over the episodes; None without the ``info`` it
        needs). Means over no values are NaN.
    """
    n = len(episodes)
    if n == 0:
        raise ValueError("episodes must hold at least one EpisodeStats")
    succ = np.array([e.success for e in episodes])
    coll = np.array([e.collisions for e in episodes])
    shortest = np.array([e.shortest_m for e in episodes])
    walked = np.array([e.walked_m for e in episodes])
    tp = fp = fn = 0
    fps, fns = [], []
    for e in episodes:
        if e.true_step_times is not None and e.detected_step_times is not None:
            a, b, c = match_step_times(e.true_step_times, e.detected_step_times)
        else:
            a, b, c = match_step_counts(e.true_counts, e.detected_counts, late, early)
        tp, fp, fn = tp + a, fp + b, fn + c
        fps.append(b)
        fns.append(c)
    precision, recall, f1 = _prf(tp, fp, fn)
    att = np.concatenate([e.attitude_error_deg for e in episodes])
    head = np.concatenate([e.heading_error_deg for e in episodes])
    hand = np.concatenate([e.hand_error_deg for e in episodes])
    has_hand = np.isfinite(hand)

    minutes = np.array([e.elapsed_s / 60.0 for e in episodes])
    per_min = {"phantom_steps_per_min": np.asarray(fps) / minutes,
               "missed_steps_per_min": np.asarray(fns) / minutes}  # fmt: skip
    motion = {k: np.array([math.nan if e.motion is None else e.motion[k] for e in episodes])
              for k in MOTION_KEYS}  # fmt: skip
    times = np.array([e.elapsed_s for e in episodes])[succ]
    area = {k: np.array([math.nan if e.play_area is None else e.play_area[k] for e in episodes])
            for k in PLAY_AREA_KEYS}  # fmt: skip
    row: dict[str, Any] = {
        "episodes": n,
        "success_rate": _mean(succ),
        "collision_rate": _mean(coll > 0),
        "collision_free_success_rate": _mean(succ & (coll == 0)),
        "spl": spl(succ, shortest, walked),
        "time_to_goal_s": _mean(times),
        "path_length_ratio": _mean((walked / shortest)[succ]),
        "step_precision": precision,
        "step_recall": recall,
        "step_f1": f1,
        "attitude_rmse_deg": math.sqrt(_mean(att**2)),
        "heading_error_rmse_deg": math.sqrt(_mean(head**2)),
        "hand_error_deg": _mean(hand[has_hand]),
        "hand_coverage": _mean(has_hand),
        "hand_tracking_availability": _mean(has_hand),
        "mean_collisions": _mean(coll),
        **{k: _nanmean(v) for k, v in per_min.items()},
        **{k: _nanmean(v) for k, v in motion.items()},
        **{k: _nanmean(v) for k, v in area.items()},
    }
    causes = [e.causes for e in episodes if e.causes is not None]
    row["collision_causes"] = ({c: sum(x[c] for x in causes) for c in COLLISION_CAUSES}
                               if causes else None)  # fmt: skip
    row["success_rate_ci"] = wilson_interval(int(succ.sum()), n)
    row["collision_rate_ci"] = wilson_interval(int((coll > 0).sum()), n)
    spl_each = succ * shortest / np.maximum(shortest, walked)
    row["spl_ci"] = bootstrap_interval(spl_each)
    row["time_to_goal_s_ci"] = bootstrap_interval(times)
    hand_each = np.array([np.isfinite(e.hand_error_deg).mean() if e.hand_error_deg.size else
                          math.nan for e in episodes])  # fmt: skip
    row["hand_tracking_availability_ci"] = bootstrap_interval(hand_each)
    for k, v in (*per_min.items(), *motion.items(), *area.items()):
        row[f"{k}_ci"] = bootstrap_interval(v)
    return row


#: The per-episode walking-in-place measures a row averages (:func:`motion_measures`).
MOTION_KEYS = ("start_latency_s", "stop_latency_s", "stop_overshoot_m", "false_motion_m_per_min",
               "yaw_drift_deg_per_min", "yaw_rate_mismatch_deg_s", "virtual_jerk_m_s3")  # fmt: skip


def _nanmean(x: ArrayLike) -> float:
    """:func:`_mean` of the finite values (NaN for none)."""
    a = np.asarray(x, dtype=np.float64).ravel()
    return _mean(a[np.isfinite(a)])
