"""The units of a recording's columns (:class:`Units`): each given, or found from the data
(``"auto"``), and a unit read other than the documented one said in one line; evidence
against the unit read, given or found, is a warning (see :mod:`agents.recordings`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from agents.recordings.record import MAX_ACC_AXIS, MAX_GYR_AXIS, Recording, gap_threshold, warn
from estimators.attitude.ekf import MAX_GYR_NORM
from estimators.rotations import (
    GRAVITY,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    quat_rotate,
)

__all__ = ["Units", "gyro_to_field_ratio", "tilt_spreads"]


#: Sample rates (Hz) of an IMU; a median interval outside them means t is not in seconds.
RATE_RANGE_HZ = (5.0, 10_000.0)


#: Samples needed before a unit is declared wrong (as the attitude filter's guard).
UNIT_MIN_COUNT = 10


#: Gyro/field turning ratios read as a gyro in deg/s: 57.3 expected, 50-59 measured on BROAD and
#: the simulator; rad/s data gives about 1, a magnetometer with an uncorrected hard-iron offset
#: more (its direction turns less).
DEG_RATIO_RANGE = (35.0, 95.0)


#: Gyro/field turning ratios read as a gyro in rad/s: 0.92-1.03 measured on the nine BROAD trials
#: (a magnet attached 2 cm away: 0.92), 0.99-1.0 on the simulator.
RAD_RATIO_RANGE = (0.5, 2.0)


#: Turning (RMS of ``|w x v|`` in the gyro's own numbers) the field fit needs to be evidence.
MIN_FIT_TURNING = 0.05


#: The tilt evidence (:func:`tilt_spreads`): windows (s) through which the gyro carries the
#: gravity direction, and the smoothing (s) of the specific force against steps and bumps.
TILT_WINDOW_S = 4.0


TILT_SMOOTH_S = 0.5


#: A unit is the tilt's choice when the other unit's spread is at least this many times its own
#: and :data:`TILT_MARGIN_DEG` more. Measured spreads (deg), right unit against wrong: simulated
#: head motions 0.9-1.7 against 5-90 (the wrong unit 3.5-48 times more), BROAD's rotation trials
#: 0.9-17 against 12-76; a sensor that hardly tilts (a level turn, stepping in place, BROAD's
#: translation and disturbance trials) gives nearly the same spread in both units: no choice.
TILT_RATIO = 2.0


TILT_MARGIN_DEG = 2.0


#: At most this many samples go into the tilt evidence (windows spread over a long recording).
MAX_TILT_SAMPLES = 1_000_000


#: With no evidence for either unit, ``auto`` reads a gyro as rad/s only if, read so, it turns the
#: sensor less than this (deg) within every :data:`TILT_WINDOW_S` window.
UNDECIDED_TURN_DEG = 10.0


#: The median norm (in g) of a head-worn recording's specific force averaged over
#: :data:`ACC_MEAN_S`: gravity, which averaging keeps (steps, bumps and a phone's
#: gravity-free "linear acceleration" average out).
ACC_MEDIAN_RANGE_G = (0.5, 2.0)


ACC_MEAN_S = 1.0


#: Units of ``t`` (:class:`Units`), in seconds.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


#: Units of ``ax, ay, az``, in m/s^2.
ACC_UNITS = {"m/s2": 1.0, "g": GRAVITY}


#: Units of ``gx, gy, gz``, in rad/s.
GYRO_UNITS = {"rad/s": 1.0, "deg/s": float(np.pi / 180.0)}


@dataclass(frozen=True)
class Units:
    """The units of a recording's columns; ``"auto"`` finds each from the data (module doc).

    Attributes:
        time: ``t``: ``"auto"`` or one of :data:`TIME_UNITS` (``s``, ``ms``, ``us``, ``ns``).
        acc: ``ax, ay, az``: ``"auto"`` or one of :data:`ACC_UNITS` (``m/s2``, ``g``).
        gyro: ``gx, gy, gz``: ``"auto"`` or one of :data:`GYRO_UNITS` (``rad/s``, ``deg/s``).
    """

    time: str = "auto"
    acc: str = "auto"
    gyro: str = "auto"

    def __post_init__(self) -> None:
        for name, allowed in (("time", TIME_UNITS), ("acc", ACC_UNITS), ("gyro", GYRO_UNITS)):
            value = getattr(self, name)
            if value != "auto" and value not in allowed:
                raise ValueError(
                    f"Units.{name}={value!r}: must be 'auto' or one of {', '.join(allowed)}"
                )

    def given(self) -> dict[str, str]:
        """The units given (not ``"auto"``), by field."""
        return {k: v for k, v in vars(self).items() if v != "auto"}


def _rate_units(dt: float) -> list[str]:
    """The units of :data:`TIME_UNITS` in which a median interval ``dt`` is an IMU's rate."""
    lo, hi = RATE_RANGE_HZ
    return [u for u, scale in TIME_UNITS.items() if dt > 0 and lo <= 1.0 / (dt * scale) <= hi]


def _time_unit(rec: Recording, path: Path, unit: str) -> float:
    """Read ``t`` in ``unit`` (``"auto"``: the one unit giving an IMU's rate), converting it to
    seconds in place; returns the median interval (s). A ValueError where no unit, or more than
    one, fits, or where the given one does not."""
    raw = float(np.median(np.diff(rec.t)))
    fits = _rate_units(raw)
    lo, hi = RATE_RANGE_HZ
    rate = _hz(raw)
    imu = f"an IMU samples at {lo:g} Hz to {hi:g} Hz"
    if unit == "auto":
        if not fits:
            raise ValueError(
                f"{path}: t's median interval is {raw:.6g} ({rate} if t is in seconds), and in "
                f"no unit of {', '.join(TIME_UNITS)} is it an IMU's rate ({imu}): not "
                "timestamps?"
            )
        if len(fits) > 1:
            said = ", ".join(f"{1.0 / (raw * TIME_UNITS[u]):.4g} Hz in {u}" for u in fits)
            raise ValueError(
                f"{path}: t's median interval is {raw:.6g}: {said}; both are IMU rates, so the "
                f"unit cannot be told: pass --time-unit {' or '.join(fits)}"
            )
        unit = fits[0]
        if unit != "s":
            warn(
                path,
                f"read t in {unit} (its median interval {raw:.6g} is "
                f"{1.0 / (raw * TIME_UNITS[unit]):.4g} Hz in {unit}, "
                f"{rate} in s); pass --time-unit {unit} to say so",
            )
    elif unit not in fits:
        dt = raw * TIME_UNITS[unit]
        hint = f": t looks like {' or '.join(fits)} (--time-unit {fits[0]})" if fits else ""
        raise ValueError(
            f"{path}: read in {unit} (--time-unit {unit}), t's median interval is {dt:.6g} s "
            f"({_hz(dt)}), but {imu}{hint}"
        )
    if TIME_UNITS[unit] != 1.0:
        rec.t = rec.t * TIME_UNITS[unit]
    rec.units = {**(rec.units or {}), "time": unit}
    return raw * TIME_UNITS[unit]


def _hz(dt: float) -> str:
    return f"{1.0 / dt:.4g} Hz" if dt > 0 else "no rate"


def _smooth(x: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """Moving average of (N, k) rows over n samples (valid part only, N - n + 1 rows)."""
    c = np.cumsum(np.vstack([np.zeros((1, x.shape[1])), x]), axis=0)
    return (c[n:] - c[:-n]) / n


def gyro_to_field_ratio(
    t: NDArray[np.float64], gyr: NDArray[np.float64], ref: NDArray[np.float64]
) -> tuple[float, float]:
    """How much faster the gyro says the sensor turns than a world-fixed vector ``ref`` does.

    A vector fixed in the world (the magnetic field; gravity when there is no linear
    acceleration) turns in the sensor frame as ``dv/dt = -w x v``. With both smoothed over 0.2 s,
    ``k`` is the least-squares fit of ``dv/dt = -k (w x v)`` for the unit vector ``v``: about 1
    for a gyro in rad/s, 1/57.3 for one in deg/s. Rows with a non-finite value are dropped.

    Returns:
        ``(1 / k, rms)``: the ratio (inf when k <= 0) and the RMS of ``|w x v|`` (rad/s if the
        gyro is in rad/s): how much turning the fit saw. ``(nan, 0)`` with under 1 s of data.
    """
    ok = np.all(np.isfinite(gyr), axis=1) & np.all(np.isfinite(ref), axis=1)
    t, gyr, ref = t[ok], gyr[ok], ref[ok]
    if t.size < 3 or t[-1] - t[0] < 1.0:
        return float("nan"), 0.0
    n = max(1, int(np.rint(0.2 / float(np.median(np.diff(t))))))
    if t.size < 2 * n + 2:
        return float("nan"), 0.0
    v = _smooth(ref, n)
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    good = norm[:, 0] > 0
    v = v[good] / norm[good]
    w = _smooth(gyr, n)[good]
    ts = _smooth(t[:, None], n)[good, 0]
    if ts.size < 3 or np.any(np.diff(ts) <= 0):
        return float("nan"), 0.0
    dv = np.gradient(v, ts, axis=0)
    c = np.cross(w, v)
    cc = float(np.sum(c * c))
    if not np.isfinite(cc) or cc == 0.0:
        return float("nan"), 0.0
    k = -float(np.sum(dv * c)) / cc
    return (1.0 / k if k > 0 else float("inf")), float(np.sqrt(cc / c.shape[0]))


def _acc_unit(rec: Recording, path: Path, unit: str) -> None:
    """Read ``acc`` in ``unit`` (``"auto"``: by the median norm of its 1 s means, gravity's),
    converting it to m/s^2 in place; a ValueError where that norm is no unit's gravity."""
    ok = np.all(np.isfinite(rec.acc) & (np.abs(rec.acc) <= MAX_ACC_AXIS), axis=1)
    t, acc = rec.t[ok], rec.acc[ok]
    if t.size > 1:  # 1 s means: steps and bumps average out, gravity does not
        n = int(np.clip(np.rint(ACC_MEAN_S / float(np.median(np.diff(t)))), 1, t.size))
        acc = _smooth(acc, n)
    norm = np.linalg.norm(acc, axis=1)
    lo, hi = ACC_MEDIAN_RANGE_G
    band = f"{lo:g} g to {hi:g} g (gravity)"
    if norm.size == 0:  # nothing to go by: the count of readable rows is checked later
        rec.units = {**(rec.units or {}), "acc": "m/s2" if unit == "auto" else unit}
        if unit != "auto":
            rec.acc = rec.acc * ACC_UNITS[unit]
        return
    median = float(np.median(norm))
    fits = [u for u, scale in ACC_UNITS.items() if lo <= median * scale / GRAVITY <= hi]
    if unit == "auto":
        if not fits:
            raise ValueError(
                f"{path}: the median norm of the specific force averaged over {ACC_MEAN_S:g} s "
                f"is {median:.4g}, neither in m/s^2 nor in g within {band}: gravity removed "
                f"(linear acceleration)? ax, ay, az must hold gravity: a sensor at rest reads "
                f"{GRAVITY} m/s^2 (1 g)"
            )
        unit = fits[0]
        if unit != "m/s2":
            warn(
                path,
                f"read ax, ay, az in {unit} (the median norm of their {ACC_MEAN_S:g} s "
                f"means, {median:.4g}, is gravity in {unit}); pass --acc-unit {unit} to "
                "say so",
            )
    elif unit not in fits:
        hint = f": ax, ay, az look like {fits[0]} (--acc-unit {fits[0]})" if fits else ""
        raise ValueError(
            f"{path}: read in {unit} (--acc-unit {unit}), the median norm of the specific "
            f"force averaged over {ACC_MEAN_S:g} s is {median * ACC_UNITS[unit]:.4g} m/s^2, not "
            f"{band}{hint}"
        )
    if ACC_UNITS[unit] != 1.0:
        rec.acc = rec.acc * ACC_UNITS[unit]
    rec.units = {**(rec.units or {}), "acc": unit}


def _integrate_windows(t: NDArray, gyr: NDArray, dt_gap: float) -> NDArray[np.float64]:
    """The orientation of each window's sensor relative to its first sample, (W, M, 4), from the
    gyro rates ``gyr`` (W, M, 3) at times ``t`` (W, M): a prefix product of the per-sample
    rotations (log2 M batched products; intervals longer than ``dt_gap`` are not integrated)."""
    dt = np.diff(t, axis=1, prepend=t[:, :1])
    dt[dt > dt_gap] = 0.0
    q = quat_from_rotvec(gyr * dt[..., None])
    k = 1
    while k < q.shape[1]:
        q = np.concatenate([q[:, :k], quat_multiply(q[:, :-k], q[:, k:])], axis=1)
        k *= 2
    return quat_normalize(q)


def tilt_spreads(
    t: NDArray[np.float64],
    gyr: NDArray[np.float64],
    acc: NDArray[np.float64],
) -> dict[str, float] | None:
    """The accelerometer's tilt against the gyro read in each unit of :data:`GYRO_UNITS`.

    The recording is cut into windows of :data:`TILT_WINDOW_S`; in each, the gyro (its numbers
    read in a unit) is integrated from the window's first sample, the specific force is turned
    into that first sample's frame and smoothed over :data:`TILT_SMOOTH_S` (steps and bumps
    average out), and its direction's RMS angle from its mean is the window's spread. Gravity
    stays put in the right unit; the wrong one spins it around wherever the sensor tilts (57.3
    times too fast, or too slow). Rows with a non-finite value are dropped; a long recording
    gives at most :data:`MAX_TILT_SAMPLES` samples, in windows spread over it.

    Returns:
        ``{unit: spread}`` (deg, the RMS over the windows; NaN with under two smoothing spans
        of data) for each gyro unit, with ``"none"`` (the sensor frame: the tilt the
        accelerometer sees) and ``"turn_deg"``: the largest turn (deg) of the gyro read as
        rad/s within a window (the whole recording where it is shorter than one): the norm of
        its rates integrated from the window's start, which back-and-forth motions cancel and
        a turn past 180 deg does not. None with fewer than 2 rows.
    """
    ok = np.all(np.isfinite(gyr), axis=1) & np.all(np.isfinite(acc), axis=1)
    t, gyr, acc = t[ok], gyr[ok], acc[ok]
    if t.size < 2:
        return None
    dt = float(np.median(np.diff(t)))
    n_smooth = max(1, int(np.rint(TILT_SMOOTH_S / dt)))
    m = max(1, min(int(np.rint(TILT_WINDOW_S / dt)), t.size))
    windows = np.arange(t.size // m)
    every = -(-windows.size * m // MAX_TILT_SAMPLES)
    pick = (windows[::every][:, None] * m + np.arange(m)).ravel()
    shape = (-1, m)
    tw, gw, aw = t[pick].reshape(shape), gyr[pick].reshape(*shape, 3), acc[pick].reshape(*shape, 3)

    def spread(q: NDArray | None) -> float:
        if m < 2 * n_smooth:
            return float("nan")
        f = aw if q is None else quat_rotate(q, aw)
        c = np.cumsum(np.concatenate([np.zeros_like(f[:, :1]), f], axis=1), axis=1)
        f = c[:, n_smooth:] - c[:, :-n_smooth]
        u = f / np.maximum(np.linalg.norm(f, axis=-1, keepdims=True), 1e-12)
        mean = u.mean(axis=1, keepdims=True)
        mean /= np.maximum(np.linalg.norm(mean, axis=-1, keepdims=True), 1e-12)
        ang = np.arccos(np.clip(np.sum(u * mean, axis=-1), -1.0, 1.0))
        return float(np.degrees(np.sqrt(np.mean(ang**2))))

    out = {"none": spread(None)}
    gap = gap_threshold(dt)
    for unit, scale in GYRO_UNITS.items():
        out[unit] = spread(_integrate_windows(tw, gw * scale, gap))
    dt_w = np.diff(tw, axis=1, prepend=tw[:, :1])
    dt_w[dt_w > gap] = 0.0
    turn = np.linalg.norm(np.cumsum(gw * dt_w[..., None], axis=1), axis=-1)
    out["turn_deg"] = float(np.degrees(turn.max()))
    return out


def _gyro_evidence(
    rec: Recording, possible: NDArray[np.bool_]
) -> tuple[list[tuple[str, str, str]], dict | None, str]:
    """What the data says about the gyro's unit: ``(source, unit, why)`` for each source that
    decides (magnitude, magnetometer, tilt; module doc), the tilt spreads, and in words why the
    magnetometer does not decide (where it does not)."""
    assert rec.gyr is not None
    found = []
    mag_said = "no magnetometer"
    gyr_norm = np.linalg.norm(rec.gyr, axis=1)
    big = int(np.sum(possible & (gyr_norm > MAX_GYR_NORM)))
    if big >= UNIT_MIN_COUNT and 100 * big >= rec.t.size:
        found.append(
            (
                "gyro's magnitude",
                "deg/s",
                f"{big} of {rec.t.size} samples exceed "
                f"{MAX_GYR_NORM:g} rad/s (2000 deg/s, beyond any head's turn)",
            )
        )
    if rec.mag is not None:  # fitted on the samples possible in rad/s
        ok = np.all(np.abs(rec.gyr) <= MAX_GYR_AXIS, axis=1)
        ratio, rms = gyro_to_field_ratio(rec.t, np.where(ok[:, None], rec.gyr, np.nan), rec.mag)
        why = (
            f"its field turns {ratio:.3g} times slower than the gyro's numbers say (1 for "
            "rad/s, 57.3 for deg/s)"
        )
        mag_said = "the magnetometer's field turns too little to compare"
        if rms > MIN_FIT_TURNING:
            mag_said = f"the magnetometer fits neither unit ({why})"
            for unit, (lo, hi) in (("deg/s", DEG_RATIO_RANGE), ("rad/s", RAD_RATIO_RANGE)):
                if lo <= ratio <= hi:
                    found.append(("magnetometer", unit, why))
    acc = np.where(np.all(np.abs(rec.acc) <= MAX_ACC_AXIS, axis=1)[:, None], rec.acc, np.nan)
    tilt = tilt_spreads(rec.t, np.where(possible[:, None], rec.gyr, np.nan), acc)
    if tilt is not None:
        for unit, other in (("rad/s", "deg/s"), ("deg/s", "rad/s")):
            if (
                tilt[other] >= TILT_RATIO * tilt[unit]
                and tilt[other] - tilt[unit] >= TILT_MARGIN_DEG
            ):
                found.append(
                    (
                        "accelerometer's tilt",
                        unit,
                        (
                            f"gravity, carried {TILT_WINDOW_S:g} s at a time by the gyro, spreads "
                            f"{tilt[unit]:.1f} deg read in {unit} but {tilt[other]:.1f} deg "
                            f"read in {other}"
                        ),
                    )
                )
    return found, tilt, mag_said


def _gyro_unit(rec: Recording, path: Path, unit: str, possible: NDArray[np.bool_]) -> None:
    """Read ``gyr`` in ``unit`` (``"auto"``: by the evidence, module doc), converting it to rad/s
    in place; a warning (one line) where evidence goes against the unit read, a ValueError where
    ``auto`` has nothing to go by and the units would give different attitudes."""
    assert rec.gyr is not None
    found, tilt, mag_said = _gyro_evidence(rec, possible)
    given = unit != "auto"
    if not given:
        if found:
            source, unit, why = found[0]
            if unit != "rad/s":
                warn(
                    path,
                    f"read gx, gy, gz in {unit}, as the {source} says ({why}); pass "
                    f"--gyro-unit {unit} to say so",
                )
        elif tilt is not None and tilt["turn_deg"] >= UNDECIDED_TURN_DEG:
            fits = f"the recording is too short for the tilt ({2 * TILT_SMOOTH_S:g} s)"
            if np.isfinite(tilt["rad/s"]):
                fits = (
                    f"the accelerometer's tilt fits both (gravity spreads "
                    f"{tilt['rad/s']:.1f} deg read in rad/s, {tilt['deg/s']:.1f} deg in "
                    "deg/s: the sensor hardly tilts)"
                )
            raise ValueError(
                f"{path}: cannot tell whether gx, gy, gz are in rad/s or deg/s: none exceeds "
                f"{MAX_GYR_NORM:g} rad/s, {mag_said}, and {fits}, while read as rad/s the gyro "
                f"turns the sensor {tilt['turn_deg']:.0f} deg within {TILT_WINDOW_S:g} s (over "
                f"{UNDECIDED_TURN_DEG:g} deg): pass --gyro-unit rad/s or --gyro-unit deg/s"
            )
        else:
            unit = "rad/s"
    against = [
        f"the {source} says {other} ({why})" for source, other, why in found if other != unit
    ]
    if against:
        warn(
            path,
            f"gx, gy, gz are read in {unit} ({'given' if given else 'found'}), but "
            f"{' and '.join(against)}; check --gyro-unit",
        )
    if GYRO_UNITS[unit] != 1.0:
        rec.gyr = rec.gyr * GYRO_UNITS[unit]
    rec.units = {**(rec.units or {}), "gyro": unit}
