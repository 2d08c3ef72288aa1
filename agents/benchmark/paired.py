"""Paired comparison of techniques: every technique against a baseline on the same episodes.

The benchmark runs every technique of a (task, policy) pair on the same seeds, so episode ``i``
of two cells is the same room, the same user and the same intentions, sensed and estimated two
ways. Each metric is compared episode by episode:

* rates (success, collision, success without a collision): the exact McNemar test — a
  two-sided binomial test of the discordant pairs (episodes where one technique succeeded and
  the other did not) against 1/2
  (``scipy.stats.binomtest``; McNemar, Psychometrika 12, 1947; the exact form for small counts,
  Fagerland, Lydersen & Laake, BMC Med. Res. Methodol. 13:91, 2013);
* per-episode means (SPL, time to goal and path-length ratio where both succeeded, the
  walking-in-place measures, phantom and missed steps per minute, each episode's attitude and
  heading error RMS, hand-tracking availability): the two-sided Wilcoxon signed-rank test of
  the paired differences (Wilcoxon, Biometrics Bulletin 1, 1945), which assumes neither
  normality nor equal variances; episodes where either value is missing (NaN: no bout to
  measure) are left out of that pair. :func:`wilcoxon_p` computes it as
  ``scipy.stats.wilcoxon(d, zero_method="wilcox")`` does (its default ``method="auto"``, no
  continuity correction): zero differences are dropped and the others ranked by size (ties
  get their mean rank); with ``n`` pairs (zeros included) the p-value is exact — every sign
  assignment of the ranks counted — for ``n <= 50`` without ties or zeros and for ``n <= 13``
  with them, and otherwise the normal approximation with the tie correction of the variance.

A metric "differs" at :data:`ALPHA` (0.01). No correction for the many metrics and techniques
is applied; the p-values are in the output, so a reader can apply one (Holm, Bonferroni).
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from agents.benchmark.cell_statistics import exact_mean
from agents.benchmark.metrics import EpisodeStats
from agents.benchmark.step_matching import match_step_counts, match_step_times
from agents.benchmark.wip_measures import MOTION_KEYS

__all__ = [
    "ALPHA",
    "BINARY_METRICS",
    "MEAN_METRICS",
    "compare_values",
    "episode_values",
    "paired_p_values",
    "wilcoxon_p",
]

#: Significance level of the marks in the table.
ALPHA = 0.01
#: Per-episode 0/1 metrics (compared with the exact McNemar test).
BINARY_METRICS = ("success_rate", "collision_rate", "collision_free_success_rate")
#: Per-episode continuous metrics (compared with the Wilcoxon signed-rank test).
MEAN_METRICS = (
    "spl",
    "time_to_goal_s",
    "path_length_ratio",
    "phantom_steps_per_min",
    "missed_steps_per_min",
    "attitude_rmse_deg",
    "heading_error_rmse_deg",
    "hand_tracking_availability",
    *MOTION_KEYS,
)


def episode_values(e: EpisodeStats, late: int = 2, early: int = 2) -> dict[str, float]:
    """One episode's value of every metric of :data:`BINARY_METRICS` and :data:`MEAN_METRICS`
    (the quantities a benchmark row averages; NaN where the episode has none)."""
    if e.true_step_times is not None and e.detected_step_times is not None:
        _, fp, fn = match_step_times(e.true_step_times, e.detected_step_times)
    else:
        _, fp, fn = match_step_counts(e.true_counts, e.detected_counts, late, early)
    minutes = e.elapsed_s / 60.0
    hand = np.asarray(e.hand_error_deg, dtype=np.float64)
    out = {
        "success_rate": float(e.success),
        "collision_rate": float(e.collisions > 0),
        "collision_free_success_rate": float(e.success and e.collisions == 0),
        "spl": float(e.success) * e.shortest_m / max(e.shortest_m, e.walked_m),
        "time_to_goal_s": e.elapsed_s if e.success else math.nan,
        "path_length_ratio": e.walked_m / e.shortest_m if e.success else math.nan,
        "phantom_steps_per_min": fp / minutes if minutes > 0 else math.nan,
        "missed_steps_per_min": fn / minutes if minutes > 0 else math.nan,
        "attitude_rmse_deg": _rms(e.attitude_error_deg),
        "heading_error_rmse_deg": _rms(e.heading_error_deg),
        "hand_tracking_availability": float(np.isfinite(hand).mean()) if hand.size else math.nan,
    }
    for k in MOTION_KEYS:
        out[k] = math.nan if e.motion is None else float(e.motion[k])
    return out


def _rms(x: NDArray[np.float64]) -> float:
    """The root mean square of an episode's per-step errors (NaN for none)."""
    a = np.asarray(x, dtype=np.float64).ravel()
    return math.sqrt(exact_mean(a**2)) if a.size else math.nan


def _mcnemar(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    from scipy.stats import binomtest

    n01 = int(np.sum((a == 0) & (b == 1)))
    n10 = int(np.sum((a == 1) & (b == 0)))
    if n01 + n10 == 0:
        return 1.0
    return float(binomtest(n01, n01 + n10, 0.5).pvalue)


@numba.njit(cache=True)
def wilcoxon_p(d):
    """Two-sided p-value of the Wilcoxon signed-rank test of the differences ``d`` (n,), finite,
    at least one of them nonzero (the test of the module docstring).

    Zeros are dropped; the ``m`` others are ranked by absolute value, tied values taking their
    mean rank (doubled ranks are integers). Exact (``n <= 50`` without ties or zeros, ``n <= 13``
    with them): the number of the ``2^m`` sign assignments whose rank sum of the positive
    differences is at most, and at least, the observed one, from the distribution of subset
    sums of the doubled ranks; p is twice the smaller share, at most 1. Otherwise ``z = (R+ -
    m (m + 1) / 4) / sqrt((m (m + 1) (2 m + 1) - sum(t^3 - t) / 2) / 24)`` over the tie groups'
    sizes ``t``, and ``p = 2 Phi(-|z|)``.
    """
    n = d.size
    a = np.abs(d[d != 0.0])
    m = a.size
    order = np.argsort(a, kind="mergesort")
    r2 = np.empty(m, np.int64)  # doubled mean ranks, in the order of ``a``
    ties = False
    tie_correct = 0.0
    s = 0
    while s < m:
        e = s + 1
        while e < m and a[order[e]] == a[order[s]]:
            e += 1
        c = e - s
        ties = ties or c > 1
        tie_correct += float(c) ** 3 - float(c)
        for k in range(s, e):
            r2[order[k]] = 2 * s + 1 + c  # 2 * ((s + 1) + (c - 1) / 2)
        s = e
    pos = d[d != 0.0] > 0.0
    obs2 = 0
    for k in range(m):
        if pos[k]:
            obs2 += r2[k]
    if n <= 50 and (n <= 13 or not (ties or m < n)):
        top = m * (m + 1)  # the largest doubled rank sum
        ways = np.zeros(top + 1)  # sign assignments per doubled rank sum (exact below 2^53)
        ways[0] = 1.0
        hi = 0
        for k in range(m):
            hi += r2[k]
            for v in range(hi, r2[k] - 1, -1):
                ways[v] += ways[v - r2[k]]
        below = ways[: obs2 + 1].sum()
        above = ways[obs2:].sum()
        total = 2.0**m
        return min(min(below / total, above / total) * 2.0, 1.0)
    count = float(m)
    mn = count * (count + 1.0) * 0.25
    se = count * (count + 1.0) * (2.0 * count + 1.0)
    se = math.sqrt((se - tie_correct / 2.0) / 24.0)
    z = (obs2 / 2.0 - mn) / se
    return math.erfc(abs(z) / math.sqrt(2.0))


def _wilcoxon(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    ok = np.isfinite(a) & np.isfinite(b)
    d = b[ok] - a[ok]
    if np.count_nonzero(d) == 0:
        return 1.0 if d.size else math.nan
    return float(wilcoxon_p(d))


def paired_p_values(
    baseline: list[EpisodeStats], other: list[EpisodeStats], late: int = 2, early: int = 2
) -> dict[str, dict[str, Any]]:
    """Each metric of ``other``'s episodes against ``baseline``'s, pair by pair.

    Args:
        baseline, other: the two cells' episodes, the same seeds in the same order.
        late, early: the step-matching window for episodes without step times.

    Returns:
        ``{metric: {"p": p-value (NaN where no pair has both values), "diff": mean of other
        minus baseline over the pairs with both values, "n": those pairs}}``.

    Raises:
        ValueError: the two lists are not the same seeds.
    """
    if [e.seed for e in baseline] != [e.seed for e in other]:
        raise ValueError("paired comparison needs the same seeds in the same order in both cells")
    va = [episode_values(e, late, early) for e in baseline]
    vb = [episode_values(e, late, early) for e in other]
    return compare_values(va, vb)


def compare_values(
    baseline: list[dict[str, float]], other: list[dict[str, float]]
) -> dict[str, dict[str, Any]]:
    """The tests of :func:`paired_p_values` on episodes' values (:func:`episode_values`, pair
    ``i`` of the two lists being the same seed), e.g. on a resample of a run's pairs.

    Raises:
        ValueError: lists of different lengths.
    """
    if len(baseline) != len(other):
        raise ValueError(
            f"paired comparison needs as many baseline episodes ({len(baseline)}) "
            f"as others ({len(other)})"
        )
    out: dict[str, dict[str, Any]] = {}
    for key in (*BINARY_METRICS, *MEAN_METRICS):
        a = np.array([v[key] for v in baseline], dtype=np.float64)
        b = np.array([v[key] for v in other], dtype=np.float64)
        ok = np.isfinite(a) & np.isfinite(b)
        p = _mcnemar(a, b) if key in BINARY_METRICS else _wilcoxon(a, b)
        out[key] = {
            "p": p,
            "diff": float(np.mean(b[ok] - a[ok])) if ok.any() else math.nan,
            "n": int(ok.sum()),
        }
    return out
