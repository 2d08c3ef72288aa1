"""The checks every recording goes through (:func:`check_recording`): its units
(:mod:`agents.recordings.units`), impossible samples, missing samples, gaps and repeated
timestamps (see :mod:`agents.recordings`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from agents.recordings.record import (
    GAP_INTERVALS,
    MAX_ACC_AXIS,
    MAX_GYR_AXIS,
    Recording,
    _where,
    gap_threshold,
    warn,
)
from agents.recordings.units import Units, _acc_unit, _gyro_unit, _time_unit

__all__ = ["MAX_BRIDGE_S", "MAX_GAP_S", "MAX_MAG_RATIO", "MAX_SPAN_S", "check_recording"]


#: A field norm above this many times the recording's median norm is impossible (the field is in
#: any unit; a magnet 2 cm from the sensor raises the norm 1.5-fold in BROAD's trial 33).
MAX_MAG_RATIO = 100.0


#: A gap longer than this (s) is an error: the file holds two sessions; split it.
MAX_GAP_S = 6 * 3600.0


#: A recording longer than this (s) is an error: the step detector works on a 100 Hz grid over
#: the whole span (a day: 8.6 million samples).
MAX_SPAN_S = 24 * 3600.0


#: The attitude filter sees at most this many seconds of missing samples across one gap (its
#: attitude variance is long saturated by then), so a long gap costs no memory.
MAX_BRIDGE_S = 60.0


def _runs(mask: NDArray[np.bool_]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Starts and (inclusive) ends of the runs of True in a 1-D mask."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1


def check_recording(rec: Recording, path: Path, units: Units | None = None) -> Recording:
    """Read the units, check impossible and missing samples and gaps of a recording (see the
    module doc); ``units``: the columns' units (default: each found from the data).

    ``t``, ``acc`` and ``gyr`` are converted to s, m/s^2 and rad/s and impossible samples become
    NaN (in place; ``rec.units`` says what was read); the warnings go to stderr, one line each.

    Raises:
        ValueError: the errors listed in the module doc, naming ``path``.
    """
    units = Units() if units is None else units
    n = rec.t.size
    if n < 2 or rec.t[-1] <= rec.t[0]:
        raise ValueError(f"{path}: needs samples at 2 distinct times at least, found {n} rows")
    dt = _time_unit(rec, path, units.time)
    t = rec.t
    _acc_unit(rec, path, units.acc)
    if rec.gyr is not None:
        # Samples some unit allows (|component| <= 2040, 2000 deg/s and 2 %): the evidence.
        possible_gyr = np.all(np.abs(rec.gyr) <= np.degrees(MAX_GYR_AXIS), axis=1)
        _gyro_unit(rec, path, units.gyro, possible_gyr)

    # Impossible samples (in the documented units) -> NaN.
    bad = {"acc": np.any(np.isinf(rec.acc) | (np.abs(rec.acc) > MAX_ACC_AXIS), axis=1)}
    if rec.gyr is not None:
        bad["gyro"] = np.any(np.isinf(rec.gyr) | (np.abs(rec.gyr) > MAX_GYR_AXIS), axis=1)
    if rec.mag is not None:
        with np.errstate(over="ignore", invalid="ignore"):
            mn = np.linalg.norm(rec.mag, axis=1)
        fin = np.isfinite(mn)
        med = float(np.median(mn[fin])) if fin.any() else 0.0
        bad["mag"] = np.any(np.isinf(rec.mag), axis=1) | (fin & (mn > MAX_MAG_RATIO * med))
    any_bad = np.logical_or.reduce(list(bad.values()))
    n_bad = int(any_bad.sum())
    if n_bad:
        what = ", ".join(f"{k} {int(v.sum())}" for k, v in bad.items() if v.any())
        limits = (
            f"|acc| > {MAX_ACC_AXIS:.1f} m/s^2 (16 g), |gyro| > {MAX_GYR_AXIS:.1f} rad/s "
            f"(2000 deg/s) on an axis, a field over {MAX_MAG_RATIO:g} times its median, or inf"
        )
        if 2 * n_bad > n:
            raise ValueError(
                f"{path}: {n_bad} of {n} rows hold values no IMU can read ({what}; {limits}): "
                "not IMU data in the documented units"
            )
        warn(
            path,
            f"{n_bad} of {n} rows hold values beyond any IMU's range ({what}; "
            f"{limits}, the first at {_where(rec, int(np.argmax(any_bad)))}); treated "
            "them as missing (NaN)",
        )
        for name, arr in (("acc", rec.acc), ("gyro", rec.gyr), ("mag", rec.mag)):
            if name in bad:
                arr[bad[name]] = np.nan

    # Missing samples (NaN in the file).
    nan = {"acc": np.any(np.isnan(rec.acc), axis=1) & ~bad["acc"]}
    for name, arr in (("gyro", rec.gyr), ("mag", rec.mag)):
        if arr is not None:
            nan[name] = np.any(np.isnan(arr), axis=1) & ~bad[name]
    any_nan = np.logical_or.reduce(list(nan.values()))
    if any_nan.any():
        starts, ends = _runs(np.logical_or(any_nan, any_bad))
        k = int(np.argmax(t[ends] - t[starts]))
        what = ", ".join(f"{name} {int(v.sum())}" for name, v in nan.items() if v.any())
        warn(
            path,
            f"{int(any_nan.sum())} of {n} rows have missing values (NaN: {what}); the longest "
            f"run of missing rows lasts {t[ends[k]] - t[starts[k]] + dt:.3g} s from "
            f"{_where(rec, int(starts[k]))}; the estimators bridge them",
        )
    if rec.gyr is not None and not np.isfinite(rec.gyr).all(axis=1).any():
        warn(path, "no row holds a gyro sample: treated as accelerometer-only data")
        rec.gyr = None
    if rec.mag is not None and not np.isfinite(rec.mag).all(axis=1).any():
        rec.mag = None
    n_acc = int(np.isfinite(rec.acc).all(axis=1).sum())
    if n_acc < 2:
        raise ValueError(f"{path}: {n_acc} rows hold an accelerometer sample; the steps need 2")

    # Gaps in the timestamps.
    d = np.diff(t)
    gap = d > gap_threshold(dt)
    if gap.any():
        k = int(np.argmax(np.where(gap, d, 0.0)))
        said = (
            f"{int(gap.sum())} gap(s) in the timestamps longer than {GAP_INTERVALS:g} sample "
            f"intervals; the longest lasts {d[k]:.6g} s, after {_where(rec, k)}"
        )
        if d[k] > MAX_GAP_S:
            raise ValueError(
                f"{path}: {said}, over the {MAX_GAP_S / 3600:g} h limit: the file holds more "
                "than one session; split it at the gap"
            )
        warn(
            path,
            f"{said}; nothing is estimated inside them (the attitude filter treats "
            "them as missing samples, the step detector finds no step there)",
        )
    if t[-1] - t[0] > MAX_SPAN_S:
        raise ValueError(
            f"{path}: the recording spans {t[-1] - t[0]:.6g} s, over the {MAX_SPAN_S / 3600:g} h "
            "limit; split it"
        )
    return rec
