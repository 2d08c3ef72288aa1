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
* **step precision / recall / F1** — detected vs true steps, see :func:`match_step_counts`;
  NaN for a cell with neither (a user who never walked in place).
* **attitude RMSE** — root mean square of ``info["attitude_error_deg"]`` (the rotation angle
  between true and estimated head attitude) over every control step of every episode.
* **hand error** — mean of ``info["hand_error_deg"]`` over the control steps with a hand
  estimate, and the fraction of steps that had one.
* **walking in place** — start and stop latency, stop overshoot, false motion, yaw drift,
  yaw-rate mismatch, virtual jerk (:mod:`agents.benchmark.wip_measures`), means over the episodes.
* **play area** — ``boundary_violations`` and ``min_boundary_m`` per episode
  (:func:`agents.benchmark.wip_measures.play_area_measures`), means over the episodes.
* **collision causes** — every collision put down to one cause
  (:mod:`agents.benchmark.collision_causes`), summed over the episodes.
* **intervals** — each rate and mean with its 95 % interval (``<key>_ci``: Wilson for rates,
  bootstrap for means, :mod:`agents.benchmark.cell_statistics`).

Step F1: detected vs true heel-strike times matched one to one within +-0.2 s
(:mod:`agents.benchmark.step_matching`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from agents.benchmark.cell_statistics import (
    bootstrap_interval,
    exact_mean,
    finite_mean,
    wilson_interval,
)
from agents.benchmark.collision_causes import COLLISION_CAUSES, collision_causes
from agents.benchmark.step_matching import (
    DEFAULT_LATE_STEPS,
    finite_times,
    match_step_counts,
    match_step_times,
)
from agents.benchmark.wip_measures import (
    MOTION_KEYS,
    PLAY_AREA_KEYS,
    motion_measures,
    play_area_measures,
)

__all__ = [
    "STEP_KEYS",
    "TRACE_KEYS",
    "EpisodeRecorder",
    "EpisodeStats",
    "episode_stats",
    "spl",
    "summarize",
]


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
    return exact_mean(s * lo / np.maximum(lo, p))


def _prf(tp: int, fp: int, fn: int) -> tuple[float, float, float]:
    """Precision, recall, F1 of a cell's steps, with the conventions of
    :func:`agents.benchmark.step_matching.step_f1`, except that a cell with neither a true nor
    a detected step (a user who never walked in place, as with a technique that moves by head
    tilt) has nothing to score: NaN, not a perfect 1."""
    if tp + fp + fn == 0:
        return math.nan, math.nan, math.nan
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
#: The ``info`` keys kept per control step for the figures and the report's replays (the
#: headings, and what :func:`agents.benchmark.collision_causes.collision_causes` reads to give each
#: collision its cause).
TRACE_KEYS = (
    "position",
    "true_position",
    "true_ypr",
    "est_ypr",
    "true_step_times",
    "elapsed_time",
    "virtual_yaw",
    "heading_error_deg",
    "collision",
    "intent_walk",
    "detected_step_times",
    "walk_yaw_deg",
    "true_body_yaw_deg",
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
        trace: stacked trace arrays for figures and replays (the keys of :data:`TRACE_KEYS`),
            or None.
        start_position: the virtual start, prepended to the traced paths.
    """
    if trace is not None:
        trace = {k: np.asarray(v, dtype=np.float64) for k, v in trace.items()}
        trace["true_step_times"] = finite_times(trace["true_step_times"])
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
        true_step_times=finite_times(steps["true_step_times"]),
        detected_step_times=finite_times(steps["detected_step_times"]),
        attitude_error_deg=np.asarray(steps["attitude_error_deg"], dtype=np.float64),
        hand_error_deg=np.asarray(steps["hand_error_deg"], dtype=np.float64),
        heading_error_deg=np.asarray(steps["heading_error_deg"], dtype=np.float64),
        trace=trace,
        motion=motion_measures(steps, start_position) if "intent_walk" in steps else None,
        causes=collision_causes(steps) if "collision" in steps and "intent_walk" in steps else None,
        play_area=play_area_measures(steps) if "play_area_outside" in steps else None,
    )


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
    per_min = {
        "phantom_steps_per_min": np.asarray(fps) / minutes,
        "missed_steps_per_min": np.asarray(fns) / minutes,
    }
    motion = {
        k: np.array([math.nan if e.motion is None else e.motion[k] for e in episodes])
        for k in MOTION_KEYS
    }
    times = np.array([e.elapsed_s for e in episodes])[succ]
    area = {
        k: np.array([math.nan if e.play_area is None else e.play_area[k] for e in episodes])
        for k in PLAY_AREA_KEYS
    }
    row: dict[str, Any] = {
        "episodes": n,
        "success_rate": exact_mean(succ),
        "collision_rate": exact_mean(coll > 0),
        "collision_free_success_rate": exact_mean(succ & (coll == 0)),
        "spl": spl(succ, shortest, walked),
        "time_to_goal_s": exact_mean(times),
        "path_length_ratio": exact_mean((walked / shortest)[succ]),
        "step_precision": precision,
        "step_recall": recall,
        "step_f1": f1,
        "attitude_rmse_deg": math.sqrt(exact_mean(att**2)),
        "heading_error_rmse_deg": math.sqrt(exact_mean(head**2)),
        "hand_error_deg": exact_mean(hand[has_hand]),
        "hand_coverage": exact_mean(has_hand),
        "hand_tracking_availability": exact_mean(has_hand),
        "mean_collisions": exact_mean(coll),
        **{k: finite_mean(v) for k, v in per_min.items()},
        **{k: finite_mean(v) for k, v in motion.items()},
        **{k: finite_mean(v) for k, v in area.items()},
    }
    causes = [e.causes for e in episodes if e.causes is not None]
    row["collision_causes"] = (
        {c: sum(x[c] for x in causes) for c in COLLISION_CAUSES} if causes else None
    )
    row["success_rate_ci"] = wilson_interval(int(succ.sum()), n)
    row["collision_rate_ci"] = wilson_interval(int((coll > 0).sum()), n)
    spl_each = succ * shortest / np.maximum(shortest, walked)
    row["spl_ci"] = bootstrap_interval(spl_each)
    row["time_to_goal_s_ci"] = bootstrap_interval(times)
    hand_each = np.array(
        [
            np.isfinite(e.hand_error_deg).mean() if e.hand_error_deg.size else math.nan
            for e in episodes
        ]
    )
    row["hand_tracking_availability_ci"] = bootstrap_interval(hand_each)
    for k, v in (*per_min.items(), *motion.items(), *area.items()):
        row[f"{k}_ci"] = bootstrap_interval(v)
    return row
