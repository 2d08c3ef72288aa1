"""Means and 95 % intervals of a cell's per-episode values, the same whatever the episodes'
order in memory or the number of worker processes."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["bootstrap_interval", "exact_mean", "finite_mean", "wilson_interval"]


def exact_mean(x: ArrayLike) -> float:
    """Mean with an exactly rounded sum (``math.fsum``): the same value whatever the order of
    the episodes' arrays in memory (numpy's pairwise SIMD sum can differ in the last bit with
    the alignment, which would make results depend on the number of worker processes).
    NaN for no values."""
    a = np.asarray(x, dtype=np.float64).ravel()
    return math.fsum(a.tolist()) / a.size if a.size else math.nan


def finite_mean(x: ArrayLike) -> float:
    """:func:`exact_mean` of the finite values (NaN for none)."""
    a = np.asarray(x, dtype=np.float64).ravel()
    return exact_mean(a[np.isfinite(a)])


def wilson_interval(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """The 95 % Wilson score interval of a rate ``successes / n`` (NaN, NaN for n = 0)."""
    if n == 0:
        return math.nan, math.nan
    p = successes / n
    den = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, centre - half), min(1.0, centre + half)


def bootstrap_interval(
    values: ArrayLike, resamples: int = 2000, seed: int = 0
) -> tuple[float, float]:
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
