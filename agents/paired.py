"""Paired comparison of techniques: every technique against a baseline on the same episodes.

The benchmark runs every technique of a (task, policy) pair on the same seeds, so episode ``i``
of two cells is the same room, the same user and the same intentions, sensed and estimated two
ways. Each metric is compared episode by episode:

* rates (success, collision): the exact McNemar test — a two-sided binomial test of the
  discordant pairs (episodes where one technique succeeded and the other did not) against 1/2
  (``scipy.stats.binomtest``; McNemar, Psychometrika 12, 1947; the exact form for small counts,
  Fagerland, Lydersen & Laake, BMC Med. Res. Methodol. 13:91, 2013);
* per-episode means (SPL, time to goal where both succeeded, the walking-in-place measures,
  phantom and missed steps per minute, hand-tracking availability): the Wilcoxon signed-rank
  test of the paired differences (``scipy.stats.wilcoxon``, zero differences dropped, exact
  distribution for small samples), which assumes neither normality nor equal variances;
  episodes where either value is missing (NaN: no bout to measure) are left out of that pair.

A metric "differs" at :data:`ALPHA` (0.01). No correction for the many metrics and techniques
is applied; the p-values are in the output, so a reader can apply one (Holm, Bonferroni).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from agents.metrics import MOTION_KEYS, EpisodeStats, match_step_counts, match_step_times

__all__ = ["ALPHA", "BINARY_METRICS", "MEAN_METRICS", "episode_values", "paired_p_values"]

#: Significance level of the marks in the table.
ALPHA = 0.01
#: Per-episode 0/1 metrics (compared with the exact McNemar test).
BINARY_METRICS = ("success_rate", "collision_rate")
#: Per-episode continuous metrics (compared with the Wilcoxon signed-rank test).
MEAN_METRICS = ("spl", "time_to_goal_s", "phantom_steps_per_min", "missed_steps_per_min",
                "hand_tracking_availability", *MOTION_KEYS)  # fmt: skip


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
        "spl": float(e.success) * e.shortest_m / max(e.shortest_m, e.walked_m),
        "time_to_goal_s": e.elapsed_s if e.success else math.nan,
        "phantom_steps_per_min": fp / minutes if minutes > 0 else math.nan,
        "missed_steps_per_min": fn / minutes if minutes > 0 else math.nan,
        "hand_tracking_availability": float(np.isfinite(hand).mean()) if hand.size else math.nan,
    }
    for k in MOTION_KEYS:
        out[k] = math.nan if e.motion is None else float(e.motion[k])
    return out


def _mcnemar(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    from scipy.stats import binomtest

    n01 = int(np.sum((a == 0) & (b == 1)))
    n10 = int(np.sum((a == 1) & (b == 0)))
    if n01 + n10 == 0:
        return 1.0
    return float(binomtest(n01, n01 + n10, 0.5).pvalue)


def _wilcoxon(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    from scipy.stats import wilcoxon

    ok = np.isfinite(a) & np.isfinite(b)
    d = b[ok] - a[ok]
    if np.count_nonzero(d) == 0:
        return 1.0 if d.size else math.nan
    return float(wilcoxon(d, zero_method="wilcox").pvalue)


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
    out: dict[str, dict[str, Any]] = {}
    for key in (*BINARY_METRICS, *MEAN_METRICS):
        a = np.array([v[key] for v in va], dtype=np.float64)
        b = np.array([v[key] for v in vb], dtype=np.float64)
        ok = np.isfinite(a) & np.isfinite(b)
        p = _mcnemar(a, b) if key in BINARY_METRICS else _wilcoxon(a, b)
        out[key] = {"p": p, "diff": float(np.mean(b[ok] - a[ok])) if ok.any() else math.nan,
                    "n": int(ok.sum())}  # fmt: skip
    return out
