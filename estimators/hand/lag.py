"""The lag metric of the hand filters: how far an estimate trails its reference in time."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["estimate_lag"]


def estimate_lag(
    estimate: ArrayLike,
    reference: ArrayLike,
    rate_hz: float,
    max_lag_s: float = 0.5,
    axis: int = 0,
) -> NDArray[np.float64]:
    """Delay (s) of ``estimate`` behind ``reference``: the shift minimising their RMS difference.

    Shifts from 0 to ``max_lag_s`` are tried in steps of 1/10 frame (linear interpolation of the
    reference); NaN samples are ignored. Works per channel: the result has the shape of one time
    sample (e.g. (3,) for (M, 3) inputs with ``axis=0``).
    """
    est = np.moveaxis(np.asarray(estimate, dtype=np.float64), axis, 0)
    ref = np.moveaxis(np.asarray(reference, dtype=np.float64), axis, 0)
    if est.shape != ref.shape:
        raise ValueError(f"estimate and reference shapes differ: {est.shape} vs {ref.shape}")
    if not (rate_hz > 0 and max_lag_s >= 0):
        raise ValueError("rate_hz must be > 0 and max_lag_s >= 0")
    m = est.shape[0]
    flat_e = est.reshape(m, -1)
    flat_r = ref.reshape(m, -1)
    t = np.arange(m, dtype=np.float64)
    shifts = np.arange(0.0, max_lag_s * rate_hz + 1e-9, 0.1)  # frames
    cost = np.empty((shifts.size, flat_e.shape[1]))
    for i, sh in enumerate(shifts):  # a loop over candidate delays, not over the batch
        pos = t - sh
        i0 = np.floor(pos).astype(np.int64)
        frac = (pos - i0)[:, None]
        inside = (i0 >= 0)[:, None]
        lo = flat_r[np.clip(i0, 0, m - 1)]
        hi = flat_r[np.clip(i0 + 1, 0, m - 1)]
        shifted = np.where(inside, lo * (1.0 - frac) + hi * frac, np.nan)
        d = flat_e - shifted
        cost[i] = np.sqrt(np.nanmean(d * d, axis=0))
    best = shifts[np.nanargmin(cost, axis=0)] / rate_hz
    return best.reshape(est.shape[1:])
