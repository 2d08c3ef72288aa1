"""Statistics of head yaw and pitch traces: speeds, turns, intervals, stillness, pitch, nods.

One function family for every head trace, simulated or recorded, so that simulated users can be
compared with real people on the same numbers (:mod:`agents.experiments.head_behaviour`).
:func:`head_motion_stats` takes one trace, B traces of one length ``(B, T)``, or a list of traces
of any lengths, each with its sample times or one sampling rate; every trace is checked
(:func:`prepare_traces`), resampled to a common rate (10 Hz by default, the rate of the real
traces in ``$VRLOCO_DATA/head_traces``) and reduced to :class:`HeadMotionStats`. Statistics are
pooled over traces by concatenating their samples and events (never by averaging per-trace
percentiles); rates are per minute of all traces together.

Definitions (all angles in degrees after conversion, speeds in deg/s, at the resampled rate fs):

* **Yaw speed**: ``|yaw[k+1] - yaw[k]| * fs`` for every pair of consecutive samples (T - 1 per
  trace); the 50/75/90/95/99th percentiles (linear interpolation, :func:`numpy.percentile`).
* **Turn**: a maximal run of consecutive sample pairs whose yaw speed exceeds
  :data:`TURN_SPEED_DEG_S` (20 deg/s) with one sign (a reversal ends a turn and starts the next);
  its amplitude is the absolute yaw change from the run's first sample to its last, its start
  the time of its first sample. A turn cut by a trace's start or end counts with the part recorded.
  ``turns_per_min``: turns of amplitude >= 10, 20, 30 and 60 deg (:data:`TURN_CLASSES_DEG`) per
  minute.
* **Turn amplitude** quartiles (25/50/75th percentiles) and **inter-turn intervals** (the times
  between the starts of consecutive turns within one trace; 10/25/50/75/90th percentiles and the
  coefficient of variation, standard deviation over mean with ``ddof=0``) use the turns of at
  least :data:`MIN_TURN_DEG` (10 deg): a single fast sample pair is no gaze shift.
* **Still**: a sample pair with ``|yaw speed| < 5`` and ``|pitch speed| < 5`` deg/s
  (:data:`STILL_SPEED_DEG_S`); ``still_fraction`` is their share of all sample pairs.
* **Pitch range**: the 95th minus the 5th percentile of all pitch samples (pooled, so the
  differences between traces' mean pitch count too).
* **Nod-like event**: a pitch excursion of at least :data:`NOD_DEG` (5 deg) away and back within
  :data:`NOD_WINDOW_S` (1 s), in either direction: a local pitch maximum or minimum whose
  prominence (:func:`scipy.signal.find_peaks`) is >= 5 deg with its bases searched only within
  +-0.5 s of it (``wlen`` = 1 s). Up and down are not told apart because the real datasets'
  pitch signs are not documented (the simulator's pitch is positive nose down). So a single dip
  down and back counts once, and an oscillating nod (the simulated users' nods are sinusoids
  about the held pitch) counts twice per cycle, its trough and its crest. A slow look down
  (over more than 0.5 s each way) or a held change of pitch is no event. ``nods_per_min``:
  events per minute.

Undefined statistics are None (JSON ``null``): turn amplitudes without any turn of >= 10 deg,
interval statistics without two such turns in one trace.

What is checked, per trace (a ValueError naming the argument, the trace index and the rule):
times finite and strictly increasing; a sampling rate (1 / the median step) of at least
:data:`MIN_RATE_HZ` (5 Hz); no gap: no step longer than :data:`GAP_FACTOR` (1.5) times the
median step (split a trace at its gaps); at least :data:`MIN_DURATION_S` (10 s) long; every
sample finite (NaN and inf are never repaired); pitch within +-90 deg (a Z-Y-X Euler pitch); no
pitch jump faster than :data:`MAX_PITCH_SPEED_DEG_S` (1000 deg/s: pitch does not wrap, so such a
jump is a glitch or another angle convention). One repair is made, always: yaw is unwrapped
(:func:`numpy.unwrap`, a jump of more than 180 deg between samples is taken as a wrap at +-pi),
since recorded yaw is usually given in (-pi, pi]; :attr:`HeadMotionSamples.yaw_unwraps` counts
the wraps removed. Resampling is linear interpolation onto ``t0 + k / fs`` (no averaging: peak
speeds of faster recordings are kept as sampled at fs).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.signal import find_peaks

from estimators.validation import check_value

__all__ = [
    "GAP_FACTOR",
    "MAX_PITCH_SPEED_DEG_S",
    "MIN_DURATION_S",
    "MIN_RATE_HZ",
    "MIN_TURN_DEG",
    "NOD_DEG",
    "NOD_WINDOW_S",
    "STATS_KEYS",
    "STILL_SPEED_DEG_S",
    "TURN_CLASSES_DEG",
    "TURN_SPEED_DEG_S",
    "HeadMotionSamples",
    "HeadMotionStats",
    "head_motion_samples",
    "head_motion_stats",
    "prepare_traces",
]

TURN_SPEED_DEG_S = 20.0  #: deg/s: a turn is a run of yaw speed above this
TURN_CLASSES_DEG = (10.0, 20.0, 30.0, 60.0)  #: deg: turn amplitudes counted per minute
MIN_TURN_DEG = 10.0  #: deg: turns this large give the amplitude quartiles and the intervals
STILL_SPEED_DEG_S = 5.0  #: deg/s: still when yaw and pitch are both slower than this
NOD_DEG = 5.0  #: deg: the least excursion of a nod-like event
NOD_WINDOW_S = 1.0  #: s: a nod-like event goes and comes back within this
MIN_RATE_HZ = 5.0  #: Hz: the slowest sampling rate accepted, given or resampled to
GAP_FACTOR = 1.5  #: a step longer than this many median steps is a gap
MIN_DURATION_S = 10.0  #: s: the shortest trace accepted
MAX_PITCH_SPEED_DEG_S = 1000.0  #: deg/s: a faster pitch change is a jump (an error)
YAW_PERCENTILES = (50, 75, 90, 95, 99)
AMPLITUDE_PERCENTILES = (25, 50, 75)
INTERVAL_PERCENTILES = (10, 25, 50, 75, 90)

#: The keys of :meth:`HeadMotionStats.to_json`, in order.
STATS_KEYS = (
    "yaw_speed_p50_p75_p90_p95_p99",
    "turns_per_min",
    "turn_amplitude_p25_p50_p75",
    "interval_p10_p25_p50_p75_p90",
    "interval_cv",
    "still_fraction",
    "pitch_range_5_95_deg",
    "nods_per_min",
)


@dataclass(frozen=True)
class HeadMotionStats:
    """The statistics of a set of head traces (see the module docstring for each definition).

    Attributes:
        yaw_speed_p50_p75_p90_p95_p99: percentiles of |yaw speed| (deg/s).
        turns_per_min: turns of amplitude >= 10, 20, 30, 60 deg per minute.
        turn_amplitude_p25_p50_p75: quartiles of the amplitudes of turns >= 10 deg (deg); None
            without such a turn.
        interval_p10_p25_p50_p75_p90: percentiles of the intervals between the starts of
            consecutive turns >= 10 deg (s); None without an interval.
        interval_cv: the intervals' coefficient of variation; None without an interval.
        still_fraction: share of sample pairs with |yaw speed| and |pitch speed| < 5 deg/s.
        pitch_range_5_95_deg: 95th minus 5th percentile of pitch (deg).
        nods_per_min: nod-like events (pitch excursions of >= 5 deg and back within 1 s, either
            direction) per minute.
    """

    yaw_speed_p50_p75_p90_p95_p99: tuple[float, ...]
    turns_per_min: tuple[float, ...]
    turn_amplitude_p25_p50_p75: tuple[float, ...] | None
    interval_p10_p25_p50_p75_p90: tuple[float, ...] | None
    interval_cv: float | None
    still_fraction: float
    pitch_range_5_95_deg: float
    nods_per_min: float

    def to_json(self) -> dict[str, Any]:
        """The statistics as JSON values (lists, floats, None), keyed by :data:`STATS_KEYS`."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}


@dataclass(frozen=True)
class HeadMotionSamples:
    """The pooled samples and events behind :class:`HeadMotionStats` (for distances between
    distributions and figures). Angles in degrees, speeds in deg/s.

    Attributes:
        rate_hz: the rate the traces were resampled to.
        durations_s: each trace's duration after resampling, ``(T_i - 1) / rate_hz`` (s).
        yaw_speed: |yaw speed| of every sample pair, all traces (deg/s).
        pitch_speed: |pitch speed| likewise (deg/s).
        pitch: every pitch sample (deg).
        turn_amplitude: the amplitude of every turn (deg), any size.
        turn_trace: the trace index of each turn.
        intervals: the intervals between the starts of consecutive turns >= 10 deg within a
            trace (s).
        nods: nod-like events per trace.
        yaw_unwraps: yaw wraps at +-pi removed per trace (the one repair made).
    """

    rate_hz: float
    durations_s: NDArray[np.float64]
    yaw_speed: NDArray[np.float64]
    pitch_speed: NDArray[np.float64]
    pitch: NDArray[np.float64]
    turn_amplitude: NDArray[np.float64]
    turn_trace: NDArray[np.intp]
    intervals: NDArray[np.float64]
    nods: NDArray[np.intp]
    yaw_unwraps: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, np.intp))

    @property
    def minutes(self) -> float:
        """Minutes of all traces together."""
        return float(self.durations_s.sum()) / 60.0

    def turn_rates(self, min_amplitude_deg: float = MIN_TURN_DEG) -> NDArray[np.float64]:
        """Each trace's turns of at least ``min_amplitude_deg`` per minute."""
        big = self.turn_amplitude >= min_amplitude_deg
        counts = np.bincount(self.turn_trace[big], minlength=self.durations_s.size)
        return counts / (self.durations_s / 60.0)

    def stats(self) -> HeadMotionStats:
        """The statistics of these samples (see the module docstring)."""
        minutes = self.minutes
        amp = self.turn_amplitude
        big = amp[amp >= MIN_TURN_DEG]
        iv = self.intervals
        still = (self.yaw_speed < STILL_SPEED_DEG_S) & (self.pitch_speed < STILL_SPEED_DEG_S)
        p5, p95 = np.percentile(self.pitch, [5, 95])
        return HeadMotionStats(
            yaw_speed_p50_p75_p90_p95_p99=_floats(np.percentile(self.yaw_speed, YAW_PERCENTILES)),
            turns_per_min=tuple(float(np.sum(amp >= c)) / minutes for c in TURN_CLASSES_DEG),
            turn_amplitude_p25_p50_p75=(
                _floats(np.percentile(big, AMPLITUDE_PERCENTILES)) if big.size else None
            ),
            interval_p10_p25_p50_p75_p90=(
                _floats(np.percentile(iv, INTERVAL_PERCENTILES)) if iv.size else None
            ),
            interval_cv=float(np.std(iv) / np.mean(iv)) if iv.size else None,
            still_fraction=float(np.mean(still)),
            pitch_range_5_95_deg=float(p95 - p5),
            nods_per_min=float(self.nods.sum()) / minutes,
        )


def _floats(values: NDArray[np.float64]) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


def head_motion_stats(
    yaw: Any,
    pitch: Any,
    *,
    times: Any = None,
    rate_hz: float | None = None,
    resample_hz: float = 10.0,
) -> HeadMotionStats:
    """The statistics of head traces (see the module docstring).

    Args:
        yaw: head yaw (rad): one trace (T,), B traces of one length (B, T), or a list of traces
            of any lengths. Wrapped at +-pi or continuous.
        pitch: head pitch (rad), shaped as ``yaw``; within +-pi/2.
        times: sample times (s): (T,) shared by every trace, (B, T), or a list with one array
            per trace. Give ``times`` or ``rate_hz``, not both.
        rate_hz: the sampling rate of every trace (samples from t = 0).
        resample_hz: the common rate the statistics are computed at (>= 5 Hz).

    Raises:
        ValueError: bad input (:func:`prepare_traces`), naming the argument, the trace and the
            rule.
    """
    return head_motion_samples(
        yaw, pitch, times=times, rate_hz=rate_hz, resample_hz=resample_hz
    ).stats()


def head_motion_samples(
    yaw: Any,
    pitch: Any,
    *,
    times: Any = None,
    rate_hz: float | None = None,
    resample_hz: float = 10.0,
) -> HeadMotionSamples:
    """The pooled samples and events of head traces (arguments as :func:`head_motion_stats`)."""
    traces, unwraps = prepare_traces(
        yaw, pitch, times=times, rate_hz=rate_hz, resample_hz=resample_hz
    )
    fs = float(resample_hz)
    wlen = round(NOD_WINDOW_S * fs) + 1  # the peak in the middle: +-0.5 s
    parts: dict[str, list[NDArray]] = {k: [] for k in ("vy", "vp", "p", "amp", "tr", "iv")}
    nods = np.zeros(len(traces), np.intp)
    durations = np.zeros(len(traces))
    for i, (y_rad, p_rad) in enumerate(traces):
        y, p = np.rad2deg(y_rad), np.rad2deg(p_rad)
        vy, vp = np.diff(y) * fs, np.diff(p) * fs
        sign = np.where(vy > TURN_SPEED_DEG_S, 1, np.where(vy < -TURN_SPEED_DEG_S, -1, 0))
        before = np.concatenate(([0], sign[:-1]))
        after = np.concatenate((sign[1:], [0]))
        starts = np.flatnonzero((sign != 0) & (sign != before))
        ends = np.flatnonzero((sign != 0) & (sign != after))  # last sample pair of each run
        amp = np.abs(y[ends + 1] - y[starts])
        parts["vy"].append(np.abs(vy))
        parts["vp"].append(np.abs(vp))
        parts["p"].append(p)
        parts["amp"].append(amp)
        parts["tr"].append(np.full(amp.size, i, np.intp))
        parts["iv"].append(np.diff(starts[amp >= MIN_TURN_DEG]) / fs)
        with warnings.catch_warnings():  # a plateau wider than the window: prominence 0
            warnings.filterwarnings("ignore", "some peaks have a prominence of 0")
            up, _ = find_peaks(p, prominence=NOD_DEG, wlen=wlen)
            down, _ = find_peaks(-p, prominence=NOD_DEG, wlen=wlen)
        nods[i] = up.size + down.size
        durations[i] = (y.size - 1) / fs
    return HeadMotionSamples(
        rate_hz=fs,
        durations_s=durations,
        yaw_speed=np.concatenate(parts["vy"]),
        pitch_speed=np.concatenate(parts["vp"]),
        pitch=np.concatenate(parts["p"]),
        turn_amplitude=np.concatenate(parts["amp"]),
        turn_trace=np.concatenate(parts["tr"]),
        intervals=np.concatenate(parts["iv"]),
        nods=nods,
        yaw_unwraps=unwraps,
    )


def prepare_traces(
    yaw: Any,
    pitch: Any,
    *,
    times: Any = None,
    rate_hz: float | None = None,
    resample_hz: float = 10.0,
) -> tuple[list[tuple[NDArray[np.float64], NDArray[np.float64]]], NDArray[np.intp]]:
    """Check head traces, unwrap their yaw and resample them to ``resample_hz`` (arguments as
    :func:`head_motion_stats`; the checks are the module docstring's).

    Returns:
        ``[(yaw, pitch), ...]`` per trace (rad, yaw unwrapped, sampled at ``t0 + k /
        resample_hz``), and the number of yaw wraps removed per trace.

    Raises:
        ValueError: naming the argument (``yaw[3]``, ``times[0]``, ``rate_hz``, ...) and the
            rule it breaks.
    """
    check_value("resample_hz", resample_hz, MIN_RATE_HZ, np.inf, "Hz")
    ys, single = _as_traces("yaw", yaw)
    ps, _ = _as_traces("pitch", pitch)
    if len(ps) != len(ys):
        raise ValueError(f"pitch: {len(ps)} traces, yaw has {len(ys)}: give one pitch per yaw")
    if (times is None) == (rate_hz is None):
        raise ValueError(
            "give the sample times (times=...) or the sampling rate (rate_hz=...), one of them"
        )
    if rate_hz is not None:
        check_value("rate_hz", rate_hz, MIN_RATE_HZ, np.inf, "Hz")
        ts = [np.arange(y.size) / float(rate_hz) for y in ys]
    else:
        ts = _as_times(times, ys)
    out = []
    unwraps = np.zeros(len(ys), np.intp)
    for i, (t, y, p) in enumerate(zip(ts, ys, ps, strict=True)):

        def name(arg: str, i: int = i) -> str:
            return arg if single else f"{arg}[{i}]"

        if not (y.size == p.size == t.size):
            raise ValueError(
                f"{name('yaw')}, {name('pitch')}, {name('times')}: {y.size}, {p.size} and "
                f"{t.size} samples: every trace needs one pitch and one time per yaw"
            )
        for arg, x in (("times", t), ("yaw", y), ("pitch", p)):
            bad = ~np.isfinite(x)
            if bad.any():
                j = int(np.argmax(bad))
                raise ValueError(
                    f"{name(arg)}: sample {j} is {x[j]}: every sample must be finite "
                    "(NaN and inf are not repaired)"
                )
        if t.size < 2:
            raise ValueError(f"{name('times')}: {t.size} sample(s): a trace needs at least two")
        step = np.diff(t)
        if (step <= 0).any():
            j = int(np.argmax(step <= 0))
            raise ValueError(
                f"{name('times')}: sample {j + 1} ({t[j + 1]:g} s) does not come after sample "
                f"{j} ({t[j]:g} s): times must increase strictly"
            )
        median = float(np.median(step))
        if 1.0 / median < MIN_RATE_HZ:
            raise ValueError(
                f"{name('times')}: a sampling rate of {1.0 / median:.3g} Hz (median step "
                f"{median:.3g} s): must be at least {MIN_RATE_HZ:g} Hz"
            )
        gap = step > GAP_FACTOR * median
        if gap.any():
            j = int(np.argmax(gap))
            raise ValueError(
                f"{name('times')}: a gap of {step[j]:.3g} s after sample {j} ({t[j]:g} s), more "
                f"than {GAP_FACTOR:g} x the median step ({median:.3g} s): split the trace at "
                "its gaps"
            )
        duration = float(t[-1] - t[0])
        if duration < MIN_DURATION_S:
            raise ValueError(
                f"{name('yaw')}: {duration:.3g} s long: a trace must last at least "
                f"{MIN_DURATION_S:g} s"
            )
        outside = np.abs(p) > np.pi / 2 + 1e-9
        if outside.any():
            j = int(np.argmax(outside))
            raise ValueError(
                f"{name('pitch')}: sample {j} is {np.rad2deg(p[j]):.1f} deg: pitch must lie in "
                "[-90, 90] deg (a Z-Y-X Euler pitch, in rad)"
            )
        pitch_speed = np.rad2deg(np.abs(np.diff(p))) / step
        jump = pitch_speed > MAX_PITCH_SPEED_DEG_S
        if jump.any():
            j = int(np.argmax(jump))
            raise ValueError(
                f"{name('pitch')}: a jump of {np.rad2deg(p[j + 1] - p[j]):.1f} deg between "
                f"samples {j} and {j + 1} ({pitch_speed[j]:.0f} deg/s): pitch must not change "
                f"faster than {MAX_PITCH_SPEED_DEG_S:g} deg/s (it does not wrap; a jump is a "
                "glitch or another angle convention)"
            )
        unwraps[i] = int(np.sum(np.abs(np.diff(y)) > np.pi))
        y = np.unwrap(y)
        n = int(np.floor(duration * resample_hz + 1e-6)) + 1
        grid = t[0] + np.arange(n) / float(resample_hz)
        out.append((np.interp(grid, t, y), np.interp(grid, t, p)))
    return out, unwraps


def _as_traces(arg: str, x: Any) -> tuple[list[NDArray[np.float64]], bool]:
    """``x`` as a list of 1-D float arrays, and whether it was one trace (T,)."""
    if isinstance(x, np.ndarray) or not isinstance(x, Sequence) or (len(x) and np.ndim(x[0]) == 0):
        try:
            a = np.asarray(x, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(
                f"{arg}: must be numbers (rad), (T,), (B, T) or a list of (T_i,) traces"
            ) from None
        if a.ndim == 1:
            return [a], True
        if a.ndim == 2 and a.shape[0] > 0:
            return list(a), False
        raise ValueError(
            f"{arg}: shape {a.shape}: must be (T,) or (B, T) with B >= 1 (or a list of traces)"
        )
    if len(x) == 0:
        raise ValueError(f"{arg}: no traces: give at least one")
    out = []
    for i, trace in enumerate(x):
        try:
            a = np.asarray(trace, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{arg}[{i}]: must be numbers (rad)") from None
        if a.ndim != 1:
            raise ValueError(f"{arg}[{i}]: shape {a.shape}: each trace must be 1-D (T_i,)")
        out.append(a)
    return out, False


def _as_times(times: Any, ys: list[NDArray[np.float64]]) -> list[NDArray[np.float64]]:
    """``times`` as one 1-D array per trace: (T,) shared, (B, T), or a list."""
    if isinstance(times, np.ndarray) or (
        isinstance(times, Sequence) and len(times) and np.ndim(times[0]) == 0
    ):
        t = np.asarray(times, dtype=np.float64)
        if t.ndim == 1:
            return [t] * len(ys)
        if t.ndim == 2 and t.shape[0] == len(ys):
            return list(t)
        raise ValueError(
            f"times: shape {t.shape}: must be (T,) shared by the {len(ys)} traces, "
            f"({len(ys)}, T) or a list of one array per trace"
        )
    ts, _ = _as_traces("times", times)
    if len(ts) != len(ys):
        raise ValueError(
            f"times: {len(ts)} arrays for {len(ys)} traces: give one per trace "
            "(or one shared array)"
        )
    return ts
