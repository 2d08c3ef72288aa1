"""Matching detected steps to true ones: by heel-strike times or by counts per control step.

The env reports the true heel-strike times and the detector's estimated heel-strike times of each
step (``info["true_step_times"]``, ``info["detected_step_times"]``, episode time, inf-padded);
:func:`match_step_times` matches them one to one within +-0.2 s, Zhang 2021's tolerance
(:func:`step_f1`). The detector is causal and reports a step 0.135 s after it,
and the first step of a walking bout only with the second; matching the estimated heel-strike
times, not the reporting times, judges where a step was detected, not when.
:func:`match_step_counts` (counts per control step in a window) remains for recordings without
times.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from estimators.validation import check_numeric

__all__ = [
    "DEFAULT_LATE_STEPS",
    "STEP_TOLERANCE_S",
    "finite_times",
    "match_step_counts",
    "match_step_times",
    "step_f1",
    "step_window",
]

#: Default lateness (control steps) allowed between a heel strike and its detection: 0.2 s.
DEFAULT_LATE_STEPS = 2
#: Step matching tolerance (s), Zhang 2021's +-0.2 s.
STEP_TOLERANCE_S = 0.2


def step_f1(
    detected_times: ArrayLike, true_times: ArrayLike, tol: float = 0.2
) -> tuple[float, float, float]:
    """Precision, recall and F1 of detected steps against true steps.

    Matching is one-to-one: each true step is matched to at most one detection and vice versa,
    and only pairs at most ``tol`` seconds apart may match. Among such matchings we take one with
    the most pairs (and, among those, the least total time error): the Hungarian algorithm
    (``scipy.optimize.linear_sum_assignment``) on the cost |t_det - t_true|, with pairs beyond
    ``tol`` priced above any sum of allowed ones. Clusters of times separated by more than
    ``tol`` cannot share a pair, so each cluster is matched on its own (linear cost overall).

    Args:
        detected_times: detected step times (s), (D,).
        true_times: true step times (s), (T,).
        tol: largest allowed time error (s), > 0.

    Returns:
        ``(precision, recall, f1)``. Conventions for empty inputs: no detections gives precision
        1 (no false alarm); no true steps gives recall 1 (nothing missed); F1 is 1 only when both
        are empty and otherwise 2 P R / (P + R), 0 when P + R = 0.
    """
    det = check_numeric(detected_times, "detected_times").ravel()
    tru = check_numeric(true_times, "true_times").ravel()
    if not (np.all(np.isfinite(det)) and np.all(np.isfinite(tru))):
        raise ValueError("detected_times and true_times must be finite (s)")
    if not (math.isfinite(tol) and tol > 0.0):
        raise ValueError(f"tol must be > 0 s, got {tol!r}")
    if det.size == 0 and tru.size == 0:
        return 1.0, 1.0, 1.0
    matched = 0
    if det.size and tru.size:
        # No allowed pair spans a gap > tol in the merged, sorted times: match each cluster alone.
        times = np.concatenate([det, tru])
        is_det = np.concatenate([np.ones(det.size, bool), np.zeros(tru.size, bool)])
        order = np.argsort(times, kind="stable")
        times, is_det = times[order], is_det[order]
        cuts = np.flatnonzero(np.diff(times) > tol) + 1
        for seg_t, seg_d in zip(np.split(times, cuts), np.split(is_det, cuts), strict=True):
            dd, tr = seg_t[seg_d], seg_t[~seg_d]
            if dd.size == 0 or tr.size == 0:
                continue
            cost = np.abs(dd[:, None] - tr[None, :])
            allowed = cost <= tol
            big = 1.0 + tol * (min(dd.size, tr.size) + 1)
            r, c = linear_sum_assignment(np.where(allowed, cost, big))
            matched += int(np.count_nonzero(allowed[r, c]))
    precision = matched / det.size if det.size else 1.0
    recall = matched / tru.size if tru.size else 1.0
    f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    return float(precision), float(recall), float(f1)


def match_step_times(
    true_times: ArrayLike, detected_times: ArrayLike, tol: float = STEP_TOLERANCE_S
) -> tuple[int, int, int]:
    """(tp, fp, fn) of detected vs true heel-strike times matched one to one within ``tol`` s
    (:func:`step_f1`'s matching)."""
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


def finite_times(per_step: ArrayLike) -> NDArray[np.float64]:
    """The sorted finite times of per-step padded time arrays, (T, K)."""
    t = np.ravel(np.asarray(per_step, dtype=np.float64))
    return np.sort(t[np.isfinite(t)])


def step_window(reset_info: dict, dt: float) -> tuple[int, int]:
    """The step-matching window ``(late, early)`` in control steps of ``dt`` s, from an episode's
    reset info: a detection may come up to the step stage's report delay after its heel strike
    (Zhang 2021: gamma_t plus the detector's latency, a bout's first step being held until the
    second), and one control step early (a heel strike at a control-step boundary). See
    :mod:`agents.benchmark.metrics`."""
    late = math.ceil(float(reset_info["step_report_delay_s"]) / dt - 1e-9)
    return late, 1
