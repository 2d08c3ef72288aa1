"""The paired comparison of a technique with the baseline, on hand-made episodes."""

import math

import numpy as np
import pytest

from agents.benchmark.metrics import EpisodeStats
from agents.benchmark.paired import (
    BINARY_METRICS,
    MEAN_METRICS,
    compare_values,
    episode_values,
    paired_p_values,
    wilcoxon_p,
)


def _episode(seed, success=True, walked=10.0, elapsed=20.0, detected=()):
    true = np.arange(1.0, 11.0)  # ten heel strikes, one a second
    det = np.sort(np.concatenate([true, np.asarray(detected, dtype=float)]))
    z = np.zeros(200)
    return EpisodeStats(
        seed=seed,
        success=success,
        collisions=0 if success else 1,
        steps=200,
        elapsed_s=elapsed,
        walked_m=walked,
        shortest_m=8.0,
        true_counts=z.astype(np.int64),
        detected_counts=z.astype(np.int64),
        attitude_error_deg=z,
        hand_error_deg=z,
        heading_error_deg=z,
        true_step_times=true,
        detected_step_times=det,
    )


def test_an_episode_gives_the_values_a_row_averages():
    v = episode_values(_episode(0, walked=10.0, detected=(4.5, 7.5)))
    assert v["spl"] == pytest.approx(0.8)  # 8 m of 10 m walked
    assert v["phantom_steps_per_min"] == pytest.approx(2 / (20 / 60))
    assert v["missed_steps_per_min"] == 0.0
    assert math.isnan(episode_values(_episode(0, success=False))["time_to_goal_s"])


def test_paired_tests_find_a_consistent_difference_and_not_noise():
    base = [_episode(s, walked=10.0) for s in range(20)]
    same = [_episode(s, walked=10.0) for s in range(20)]
    res = paired_p_values(base, same)
    assert set(res) == {*BINARY_METRICS, *MEAN_METRICS}
    assert res["spl"]["p"] == 1.0 and res["success_rate"]["p"] == 1.0
    # every episode walks 1-20 cm farther and has one phantom step: both differ at p < 0.01
    rng = np.random.default_rng(0)
    worse = [_episode(s, walked=10.0 + rng.uniform(0.01, 0.2), detected=(5.5,)) for s in range(20)]
    res = paired_p_values(base, worse)
    assert res["spl"]["p"] < 0.01 and res["spl"]["diff"] < 0
    assert res["phantom_steps_per_min"]["p"] < 0.01 and res["phantom_steps_per_min"]["diff"] > 0
    # 8 of 20 episodes fail: the exact McNemar p is 2 / 2^8
    fails = [_episode(s, success=s >= 8) for s in range(20)]
    res = paired_p_values(base, fails)
    assert res["success_rate"]["p"] == pytest.approx(2 / 2**8)
    assert res["success_rate"]["diff"] == pytest.approx(-0.4)
    # time to goal is compared only where both succeeded
    assert res["time_to_goal_s"]["n"] == 12


def test_paired_tests_refuse_cells_of_different_seeds():
    with pytest.raises(ValueError, match="same seeds"):
        paired_p_values([_episode(0)], [_episode(1)])
    with pytest.raises(ValueError, match=r"as many baseline episodes \(1\) as others \(2\)"):
        compare_values([episode_values(_episode(0))], [episode_values(_episode(0))] * 2)


def test_a_resample_of_the_values_counts_each_drawn_pair_once_per_draw():
    """Values drawn with replacement (a bootstrap resample): every drawn pair counts, repeats
    too. The other technique fails every third seed where the baseline succeeds, so the exact
    McNemar p is 2 / 2^k over the k draws of those seeds."""
    base = [_episode(s) for s in range(12)]
    other = [_episode(s, success=s % 3 > 0) for s in range(12)]
    idx = np.random.default_rng(1).integers(0, 12, 30)
    got = compare_values(
        [episode_values(base[i]) for i in idx], [episode_values(other[i]) for i in idx]
    )
    k = int(np.sum(idx % 3 == 0))
    assert k >= 3
    assert got["success_rate"]["p"] == pytest.approx(2 / 2**k)
    assert got["success_rate"]["diff"] == pytest.approx(-k / 30)
    assert got["time_to_goal_s"]["n"] == 30 - k  # both succeeded


def _differences(rng, n, kind):
    if kind == "distinct":
        return rng.normal(0.3, 1.0, n)
    if kind == "ties":  # few distinct sizes, no zeros
        return rng.choice([-2.0, -1.0, 1.0, 2.0, 3.0], n)
    if kind == "zeros":  # distinct sizes and some zeros
        return rng.normal(0.3, 1.0, n) * (rng.random(n) < 0.7)
    return np.round(rng.normal(0.2, 1.0, n), 1)  # ties and zeros


@pytest.mark.parametrize("kind", ["distinct", "ties", "zeros", "both"])
def test_the_signed_rank_test_gives_scipys_p_values(kind):
    from scipy.stats import wilcoxon

    rng = np.random.default_rng(len(kind))
    # every regime of scipy's choice: exact (n <= 50, no ties or zeros), all sign assignments
    # (n <= 13 with ties or zeros), the normal approximation (the rest)
    # (scipy's and the uncompiled kernel's enumeration of 2^n assignments is slow near n = 13:
    # fewer repetitions there, and the uncompiled kernel checked once per n)
    for n in [*range(1, 16), 20, 30, 49, 50, 51, 70, 120]:
        reps = 2 if kind != "distinct" and 10 <= n <= 13 else 6
        for rep in range(reps):
            d = _differences(rng, n, kind)
            if not np.any(d):
                continue
            want = wilcoxon(d, zero_method="wilcox").pvalue
            assert abs(wilcoxon_p(d) - want) <= 1e-12, (kind, n, d)
            if rep == 0:
                assert abs(wilcoxon_p.py_func(d) - want) <= 1e-12, (kind, n, d)


def test_the_signed_rank_test_against_hand_counted_cases():
    # ranks 1..4, all positive: 1 of 16 sign assignments has R+ >= 10, two-sided 2/16
    assert wilcoxon_p(np.array([1.0, 2.0, 3.0, 4.0])) == pytest.approx(2 / 16, abs=1e-15)
    # the zero is dropped, |-1| and |1| share rank 1.5: R+ = 1.5 + 3 of the ranks (1.5, 1.5, 3);
    # the 8 sign assignments give R+ 0, 1.5, 1.5, 3, 3, 4.5, 4.5, 6: 3 of them >= 4.5, p = 2 * 3/8
    assert wilcoxon_p(np.array([0.0, -1.0, 1.0, 2.0])) == pytest.approx(0.75, abs=1e-15)
