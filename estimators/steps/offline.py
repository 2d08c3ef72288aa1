"""Steps of whole recordings: Zhang 2021's detector run offline over one recording.

:func:`detect_steps` takes timestamps that may be irregular (a phone at ~405 Hz): the norm of the
specific force is averaged over the bins of a uniform grid at ``fs`` (:func:`bin_average`, the
exact mean of the linearly interpolated norm over each bin, an anti-alias box filter), then runs
through the streaming detector (:class:`estimators.steps.zhang2021.StepDetector`); the
still/walk state of the result is read from the bouts afterwards (non-causal).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.steps.zhang2021 import GaitParams, StepDetector
from estimators.validation import check_numeric

__all__ = ["GaitResult", "bin_average", "detect_steps"]


@dataclass
class GaitResult:
    """Steps and still/walk state of one recording (see :func:`detect_steps`).

    Attributes:
        step_times: estimated heel-strike times (s, the clock of the input ``t``), sorted, (S,).
        step_index: index of the input sample nearest each step, (S,).
        confirm_times: when a streaming detector would have reported each step (s), (S,).
        state: 0 still, 1 walk, per input sample, (n,) int8. Non-causal: walk from half a step
            interval before a bout's first step to half an interval after its last step (a bout:
            steps with neighbours at most ``gamma_t`` apart).
        fs: rate (Hz) of the uniform grid the detector ran at.
        params: the parameters used.
    """

    step_times: NDArray[np.float64]
    step_index: NDArray[np.intp]
    confirm_times: NDArray[np.float64]
    state: NDArray[np.int8]
    fs: float
    params: GaitParams


def bin_average(
    t: NDArray[np.float64], x: NDArray[np.float64], grid: NDArray[np.float64], fs: float
) -> NDArray[np.float64]:
    """Mean of the linearly interpolated x(t) over the bins [grid - 0.5/fs, grid + 0.5/fs]."""
    if t.size == 1:
        return np.full(grid.shape, x[0])
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (x[1:] + x[:-1]) * np.diff(t))])
    edges = np.clip(np.concatenate([grid - 0.5 / fs, [grid[-1] + 0.5 / fs]]), t[0], t[-1])
    width = np.diff(edges)
    mean = np.diff(np.interp(edges, t, cum)) / np.where(width > 0, width, 1.0)
    # A bin entirely outside [t0, t_end] (zero width after clipping) takes the nearest value.
    return np.where(width > 0, mean, np.interp(grid, t, x))


def detect_steps(
    t: ArrayLike,
    acc: ArrayLike,
    *,
    fs: float = 100.0,
    params: GaitParams | None = None,
    **overrides: float,
) -> GaitResult:
    """Detect the steps of one recording, offline.

    Args:
        t: sample timestamps (s), (n,), non-decreasing (irregular spacing allowed; samples
            sharing a timestamp are merged into their mean).
        acc: specific force (m/s^2), (n, 3); rows with a NaN are ignored (the norm is
            interpolated across them).
        fs: rate (Hz) of the uniform grid the norm is averaged onto before detection, in
            [10, 2000]; 100 Hz, the simulator's IMU rate, by default.
        params: detector parameters (defaults: :class:`GaitParams`, head-worn).
        **overrides: fields of :class:`GaitParams` replacing those of ``params``.

    Returns:
        A :class:`GaitResult`. Peaks in the last ``latency`` seconds are still evaluated: the
        stream is padded with the baseline after its end.

    Raises:
        ValueError: bad shapes, non-finite or decreasing timestamps, fewer than 2 valid
            samples, or an invalid parameter.
    """
    params = GaitParams() if params is None else params
    if not isinstance(params, GaitParams):
        raise ValueError(f"params must be a GaitParams, got {type(params).__name__}")
    if overrides:
        names = {f.name for f in dataclasses.fields(GaitParams)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise ValueError(f"unknown GaitParams field(s) {unknown}; choose from {sorted(names)}")
        params = dataclasses.replace(params, **overrides)
    tt = check_numeric(t, "t")
    a = check_numeric(acc, "acc")
    if tt.ndim != 1 or tt.size < 2:
        raise ValueError(f"t must have shape (n,) with n >= 2, got {tt.shape}")
    if a.shape != (tt.size, 3):
        raise ValueError(f"acc must have shape ({tt.size}, 3) to match t, got {a.shape}")
    if not np.all(np.isfinite(tt)):
        raise ValueError("t contains NaN or infinite timestamps")
    d = np.diff(tt)
    if np.any(d < 0.0):
        k = int(np.argmax(d < 0.0))
        raise ValueError(
            f"t runs backwards: t[{k + 1}]={float(tt[k + 1])!r} < t[{k}]={float(tt[k])!r} "
            "(timestamps must not decrease; equal ones are merged)"
        )
    norm = np.linalg.norm(a, axis=1)
    ok = np.isfinite(norm)
    if ok.sum() < 2:
        raise ValueError("acc must hold at least 2 finite samples")
    # Samples sharing a timestamp (a logger writing two rows for one tick) are one sample: the
    # mean of their finite norms.
    t_ok, norm_ok = tt[ok], norm[ok]
    if np.any(np.diff(t_ok) == 0.0):
        t_ok, inverse = np.unique(t_ok, return_inverse=True)
        norm_ok = np.bincount(inverse, weights=norm_ok) / np.bincount(inverse)
    if t_ok.size < 2 or t_ok[-1] <= t_ok[0]:
        raise ValueError("acc must hold finite samples at at least 2 distinct times")
    det = StepDetector(1, fs, params)
    grid = tt[0] + np.arange(int(np.floor((tt[-1] - tt[0]) * det.fs)) + 1) / det.fs
    x = bin_average(t_ok, norm_ok, grid, det.fs)
    out = det.update_norm(x[None, :])
    pad = det.h + det.m
    tail = det.update_norm(np.full((1, pad), det.baseline[0]))
    _, i0, p0 = out.events()
    _, i1, p1 = tail.events()
    peak = np.concatenate([p0, p1])
    conf = np.concatenate([out.sample_time[i0], tail.sample_time[i1]])
    order = np.argsort(peak)
    step_times = tt[0] + peak[order]
    confirm = tt[0] + conf[order]
    idx = np.clip(np.searchsorted(tt, step_times), 1, tt.size - 1)
    idx = np.where(np.abs(tt[idx - 1] - step_times) <= np.abs(tt[idx] - step_times), idx - 1, idx)
    return GaitResult(
        step_times=step_times,
        step_index=idx.astype(np.intp),
        confirm_times=confirm,
        state=_bout_state(tt, step_times, params.gamma_t),
        fs=det.fs,
        params=params,
    )


def _bout_state(
    t: NDArray[np.float64], steps: NDArray[np.float64], gamma_t: float
) -> NDArray[np.int8]:
    """Non-causal walk mask over times ``t`` from sorted step times (see GaitResult.state)."""
    state = np.zeros(t.size, dtype=np.int8)
    if steps.size < 2:
        return state
    gaps = np.diff(steps)
    breaks = np.flatnonzero(gaps > gamma_t)
    starts = np.concatenate([[0], breaks + 1])
    ends = np.concatenate([breaks, [steps.size - 1]])
    for s, e in zip(starts, ends, strict=True):  # one iteration per walking bout
        if e == s:
            continue
        half = 0.5 * float(np.median(gaps[s:e]))
        lo, hi = np.searchsorted(t, [steps[s] - half, steps[e] + half])
        state[lo:hi] = 1
    return state
