"""``vrloco estimate``: run the head estimators on a recording — attitude, steps, virtual path.

Inputs (chosen by what ``PATH`` is):

* a CSV file with a header row and these columns (any order, extra columns ignored):
  ``t`` time (s, increasing), ``ax, ay, az`` specific force (m/s^2; a level sensor at rest reads
  ``az = +9.81``), optionally ``gx, gy, gz`` angular rate (rad/s; without them there is no
  attitude) and ``mx, my, mz`` magnetic field (any fixed unit, e.g. uT). Sensor frame x forward,
  y left, z up for a head-worn unit. The file is UTF-8 text (a byte-order mark, as spreadsheets
  write, is skipped); UTF-16 text with a byte-order mark is decoded too; anything else (binary,
  UTF-16 without a mark, other encodings) is refused with an error naming the file. A missing
  value is written ``nan``.
* a BROAD trial (``.hdf5`` or ``.mat``, ../shared/data/README.md): its optical reference attitude
  ``opt_quat`` is compared with the estimate;
* an Oxford step-counter folder (``accelerometer.csv``: steps and the still/walk state; with no
  gyroscope there is no attitude, and the path is drawn along +x). Its foot switches
  (``stepcounter.csv``, when present) are compared with the detected steps.

Checks on every recording, each said in one line on stderr or raised as one ValueError naming
the file (and, for a CSV, the line and the column):

* units, the way the attitude filter guards them (:data:`estimators.attitude.MIN_ACC_NORM`,
  :data:`~estimators.attitude.MAX_GYR_NORM`): an accelerometer in g, a gyro in deg/s and a time
  in ms, us or ns are errors that say what was found and what to multiply by. A gyro is taken
  for deg/s when at least 10 samples and 1 % of them exceed 35 rad/s, or when the magnetometer's
  direction turns 35 to 95 times slower than the gyro says (57.3 for deg/s; fitted over the
  whole recording, :func:`gyro_to_field_ratio`). A recording whose head hardly turns, and a 6D
  one that never turns faster than 35 deg/s, cannot be told apart from rad/s data and pass.
* impossible samples: a gyro component beyond :data:`MAX_GYR_AXIS` (2000 deg/s), an accelerometer
  component beyond :data:`MAX_ACC_AXIS` (16 g), a field norm over :data:`MAX_MAG_RATIO` times the
  recording's median norm, or an infinite value, are treated as missing (a warning gives the
  count); an error when they are most of the rows.
* missing samples (NaN): a warning with the count and the longest run (s); the estimators bridge
  them (the attitude filter propagates without the missing sensor, the step detector
  interpolates the norm).
* gaps in the timestamps longer than :data:`GAP_INTERVALS` median intervals (and 0.1 s): a
  warning with the count and the longest gap's position and length; an error beyond
  :data:`MAX_GAP_S`, and so is a recording spanning more than :data:`MAX_SPAN_S`. The attitude
  filter treats a gap as missing samples, at most :data:`MAX_BRIDGE_S` of them.
* rows sharing a timestamp are one sample (their mean, said in one line); time running backwards,
  a row with more or fewer fields than the header and a non-numeric value are errors naming the
  line.

Irregular timestamps are resampled onto a uniform grid at the median rate (linear interpolation)
for the attitude filter, which assumes a fixed rate; the step detector takes the timestamps as
they are. The attitude is the causal filter's, or with ``--offline`` its forward-backward
smoother's (:func:`estimators.attitude.estimate_attitude`). Output: a CSV (``t, qw, qx, qy, qz,
yaw_deg, pitch_deg, roll_deg, walking, step, x, y``; without attitude ``t, walking, step, x,
y``) and a PNG with the attitude (when there is one), the specific-force norm with the detected
steps, and the path of eq (17). The summary that ``vrloco estimate`` prints (JSON) holds the
comparison with the ground truth where the recording carries one (:func:`estimate_recording`).
"""

from __future__ import annotations

import codecs
import csv
import io
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from estimators.attitude import MAX_GYR_NORM, MIN_ACC_NORM, estimate_attitude
from estimators.attitude_errors import orientation_errors
from estimators.dead_reckoning import dead_reckon
from estimators.gait import GaitParams, detect_steps, step_f1
from estimators.rotations import GRAVITY, quat_to_ypr

__all__ = [
    "GAP_INTERVALS",
    "MAX_ACC_AXIS",
    "MAX_BRIDGE_S",
    "MAX_GAP_S",
    "MAX_GYR_AXIS",
    "MAX_MAG_RATIO",
    "MAX_SPAN_S",
    "Recording",
    "check_recording",
    "estimate_recording",
    "gyro_to_field_ratio",
    "read_csv_recording",
    "read_recording",
]

REQUIRED = ("t", "ax", "ay", "az")
GYRO = ("gx", "gy", "gz")
MAGNETOMETER = ("mx", "my", "mz")
OPTIONAL = (*GYRO, *MAGNETOMETER)

#: Largest gyro reading on one axis (rad/s): 2000 deg/s, the widest full scale of MEMS gyros
#: (Bosch BMI160/BMI270, TDK ICM-42688 datasheets), plus 2 % for scale and rounding.
MAX_GYR_AXIS = float(np.radians(2000.0)) * 1.02
#: Largest accelerometer reading on one axis (m/s^2): 16 g, the widest full scale of the same
#: IMUs, plus 2 % (a logger may scale with 9.81 instead of 9.80665). BROAD's tapping trial peaks at
#: a norm of 15.9 g.
MAX_ACC_AXIS = 16.0 * GRAVITY * 1.02
#: A field norm above this many times the recording's median norm is impossible (the field is in
#: any unit; a magnet 2 cm from the sensor raises the norm 1.5-fold in BROAD's trial 33).
MAX_MAG_RATIO = 100.0
#: An interval longer than this many median intervals (and 0.1 s) is a gap in the recording.
GAP_INTERVALS = 10.0
#: A gap longer than this (s) is an error: the file holds two sessions; split it.
MAX_GAP_S = 6 * 3600.0
#: A recording longer than this (s) is an error: the step detector works on a 100 Hz grid over
#: the whole span (a day: 8.6 million samples).
MAX_SPAN_S = 24 * 3600.0
#: The attitude filter sees at most this many seconds of missing samples across one gap (its
#: attitude variance is long saturated by then), so a long gap costs no memory.
MAX_BRIDGE_S = 60.0
#: Sample rates (Hz) of an IMU; a median interval outside them means t is not in seconds.
RATE_RANGE_HZ = (5.0, 10_000.0)
#: Samples needed before a unit is declared wrong (as the attitude filter's guard).
UNIT_MIN_COUNT = 10
#: Gyro/field turning ratios read as a gyro in deg/s: 57.3 expected, 50-59 measured on BROAD and
#: the simulator; rad/s data gives about 1, a magnetometer with an uncorrected hard-iron offset
#: more (its direction turns less).
DEG_RATIO_RANGE = (35.0, 95.0)


@dataclass
class Recording:
    """Samples of a head-worn IMU: times (s) and (N, 3) arrays; gyr/mag may be None.

    Attributes:
        name: the output files' stem.
        t: sample times (s), (N,), strictly increasing.
        acc, gyr, mag: (N, 3) specific force (m/s^2), angular rate (rad/s) and magnetic field
            (any unit); NaN marks a missing sample.
        gait: step-detector parameters for the sensor's placement.
        line: the file line of each sample (CSV), for messages; None for other formats.
        ref_quat: (N, 4) reference attitude ``[w, x, y, z]`` sensor -> ENU (BROAD's optical
            ``opt_quat``, NaN where markers were lost), or None.
        ref_mask: (N,) samples the reference scores (BROAD's ``movement``), or None for all.
        ref_steps: true step times (s, the clock of ``t``) from foot switches, or None.
    """

    name: str
    t: NDArray[np.float64]
    acc: NDArray[np.float64]
    gyr: NDArray[np.float64] | None
    mag: NDArray[np.float64] | None
    gait: GaitParams
    line: NDArray[np.int64] | None = None
    ref_quat: NDArray[np.float64] | None = None
    ref_mask: NDArray[np.bool_] | None = None
    ref_steps: NDArray[np.float64] | None = None


def _gap_threshold(dt: float) -> float:
    """The shortest interval (s) that counts as a gap, for a median interval ``dt``."""
    return max(GAP_INTERVALS * dt, 0.1)


def _warn(path: Path | str, message: str) -> None:
    print(f"{path}: {message}", file=sys.stderr)


def _decode(path: Path) -> str:
    """The file's text: UTF-8 (a BOM skipped) or UTF-16 with a BOM; otherwise a ValueError."""
    raw = path.read_bytes()
    utf16 = raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE))
    try:
        text = raw.decode("utf-16" if utf16 else "utf-8-sig")
    except UnicodeDecodeError as err:
        raise ValueError(
            f"{path}: not a UTF-8 text CSV (byte {err.start} cannot be decoded as "
            f"{'UTF-16' if utf16 else 'UTF-8'}: binary data or another encoding); save it as "
            "a UTF-8 CSV"
        ) from None
    if "\x00" in text:
        raise ValueError(
            f"{path}: not a UTF-8 text CSV (it holds NUL bytes: binary data, or UTF-16 without "
            "a byte-order mark); save it as a UTF-8 CSV"
        )
    return text


def _parse_csv(path: Path) -> tuple[list[str], NDArray[np.float64], NDArray[np.int64]]:
    """The columns used, their values (rows, columns) and each row's line in the file."""
    reader = csv.reader(io.StringIO(_decode(path), newline=""))
    try:
        header = [h.strip() for h in next(reader, [])]
        if not header:
            raise ValueError(f"{path}: the file is empty; expected a header row")
        missing = [c for c in REQUIRED if c not in header]
        if missing:
            hint = ""
            if len(header) == 1 and any(s in header[0] for s in ";\t"):
                hint = "; the header has no commas: the file must be comma-separated"
            raise ValueError(
                f"{path}, line 1: missing column(s) {', '.join(missing)}; a CSV needs "
                f"{', '.join(REQUIRED)} (and optionally {', '.join(OPTIONAL)}){hint}"
            )
        for group in (GYRO, MAGNETOMETER):
            have = [c for c in group if c in header]
            if have and len(have) < 3:
                raise ValueError(
                    f"{path}, line 1: column(s) {', '.join(c for c in group if c not in have)} "
                    f"missing; give all of {', '.join(group)} or none"
                )
        cols = [c for c in (*REQUIRED, *OPTIONAL) if c in header]
        twice = [c for c in cols if header.count(c) > 1]
        if twice:
            raise ValueError(f"{path}, line 1: column(s) {', '.join(twice)} appear twice")
        where = [header.index(c) for c in cols]
        rows: list[list[float]] = []
        lines: list[int] = []
        for row in reader:
            line = reader.line_num
            if not row or all(not x.strip() for x in row):
                continue
            while len(row) > len(header) and not row[-1].strip():
                row = row[:-1]  # trailing commas
            if len(row) != len(header):
                more = len(row) > len(header)
                raise ValueError(
                    f"{path}, line {line}: {len(row)} fields, but the header has "
                    f"{len(header)}" + ("; a comma inside a value?" if more else "")
                )
            values = []
            for name, j in zip(cols, where, strict=True):
                try:
                    values.append(float(row[j]))
                except ValueError:
                    raise ValueError(
                        f"{path}, line {line}, column {j + 1} ({name}): cannot read "
                        f"{row[j][:40]!r} as a number"
                    ) from None
            rows.append(values)
            lines.append(line)
    except csv.Error as err:
        raise ValueError(
            f"{path}, line {reader.line_num}: not a readable CSV row ({err})"
        ) from None
    if len(rows) < 2:
        raise ValueError(f"{path}: needs at least 2 data rows, found {len(rows)}")
    data = np.asarray(rows, dtype=np.float64)
    line_no = np.asarray(lines, dtype=np.int64)
    t = data[:, 0]
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(
            f"{path}, line {line_no[bad[0]]}, column {where[0] + 1} (t): time {t[bad[0]]} is not "
            "a finite number (s)"
        )
    bad = np.flatnonzero(np.diff(t) < 0)
    if bad.size:
        raise ValueError(
            f"{path}, line {line_no[bad[0] + 1]}, column {where[0] + 1} (t): time "
            f"{t[bad[0] + 1]} runs backwards after {t[bad[0]]}; timestamps must not decrease (s)"
        )
    return cols, data, line_no


def read_csv_recording(path: Path) -> Recording:
    """Read and check the documented CSV format (see the module doc).

    Raises:
        ValueError: one line naming the file (and the line and column where there is one): not
            a UTF-8/UTF-16 text file, a missing column, a malformed row, time not in seconds or
            running backwards, units off, or a recording that is mostly impossible values.
    """
    path = Path(path)
    cols, data, line = _parse_csv(path)
    t = data[:, 0]
    repeated = int(np.sum(np.diff(t) == 0))
    if repeated:  # rows sharing a timestamp are one sample: their mean (NaN where one is NaN)
        t_u, first, inverse = np.unique(t, return_index=True, return_inverse=True)
        counts = np.bincount(inverse)
        with np.errstate(invalid="ignore"):
            data = np.stack([np.bincount(inverse, weights=v) / counts for v in data.T], -1)
        data[:, 0] = t_u
        line = line[first]
        _warn(path, f"{repeated} rows repeat the previous row's timestamp; merged them into "
                    "the mean of the rows sharing it")  # fmt: skip
    get = {c: data[:, k] for k, c in enumerate(cols)}

    def xyz(names: tuple[str, ...]) -> NDArray[np.float64] | None:
        return np.stack([get[c] for c in names], -1) if names[0] in get else None

    rec = Recording(
        path.stem, data[:, 0], xyz(("ax", "ay", "az")), xyz(GYRO), xyz(MAGNETOMETER),
        GaitParams(), line=line,
    )  # fmt: skip
    return check_recording(rec, path)


def read_recording(path: Path) -> Recording:
    """A recording from a CSV file, a BROAD trial or an Oxford folder (see the module doc)."""
    path = Path(path)
    if path.is_dir():
        from estimators.io_oxford import load_oxford, read_accelerometer

        if not (path / "accelerometer.csv").is_file():
            raise ValueError(
                f"{path}: a folder, but not an Oxford step-counter recording (no "
                "accelerometer.csv); give a CSV file, a BROAD trial (.hdf5/.mat) or an Oxford "
                "recording's folder"
            )
        if (path / "stepcounter.csv").is_file():
            ox = load_oxford(path)
            t, acc, ref_steps = ox.t, ox.acc, ox.step_times
        else:
            t, acc, _ = read_accelerometer(path)
            ref_steps = None
        rec = Recording(path.name, t, acc, None, None, GaitParams.neck_pouch(),
                        ref_steps=ref_steps)  # fmt: skip
        return check_recording(rec, path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file or folder")
    if path.suffix.lower() in (".hdf5", ".h5", ".mat"):
        from estimators.io_broad import load_broad

        trial = load_broad(path)
        t = np.arange(trial.acc.shape[0]) / trial.fs
        rec = Recording(trial.name, t, trial.acc, trial.gyr, trial.mag, GaitParams(),
                        ref_quat=trial.quat, ref_mask=trial.movement)  # fmt: skip
        return check_recording(rec, path)
    return read_csv_recording(path)


# ------------------------------------------------------------------------------------------------
# Checks.
# ------------------------------------------------------------------------------------------------


def _where(rec: Recording, i: int) -> str:
    """The position of sample ``i`` in words: its time and its line (CSV) or index."""
    pos = f"line {int(rec.line[i])}" if rec.line is not None else f"sample {i}"
    return f"t = {rec.t[i]:.6g} s ({pos})"


def _check_rate(rec: Recording, path: Path) -> float:
    """The median interval (s); a ValueError when it is no IMU's rate (t not in seconds)."""
    dt = float(np.median(np.diff(rec.t)))
    lo, hi = RATE_RANGE_HZ
    if dt <= 0.0 or not lo <= 1.0 / dt <= hi:
        rate = f"{1.0 / dt:.3g} Hz" if dt > 0 else "no rate"
        msg = (
            f"{path}: t's median interval is {dt:.6g} ({rate} if t is in seconds), but an IMU "
            f"samples at {lo:g} Hz to {hi:g} Hz"
        )
        for unit, scale in (("milliseconds", 1e-3), ("microseconds", 1e-6),
                            ("nanoseconds", 1e-9)):  # fmt: skip
            if dt > 0 and lo <= 1.0 / (dt * scale) <= hi:
                msg += (
                    f": t looks like {unit} ({1.0 / (dt * scale):.4g} Hz); divide it by "
                    f"{1.0 / scale:g} to get seconds"
                )
                break
        else:
            msg += "; t must be in seconds"
        raise ValueError(msg)
    return dt


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


def _check_units(rec: Recording, path: Path, possible_gyr: NDArray[np.bool_]) -> None:
    """Accelerometer in g or gyro in deg/s: a ValueError saying what to multiply by."""
    acc_norm = np.linalg.norm(rec.acc, axis=1)
    fin = np.isfinite(acc_norm) & np.all(np.abs(rec.acc) <= MAX_ACC_AXIS, axis=1)
    small = int(np.sum(acc_norm[fin] < MIN_ACC_NORM))
    if small >= UNIT_MIN_COUNT and 2 * small > int(fin.sum()):
        raise ValueError(
            f"{path}: ax, ay, az must be in m/s^2, but the specific-force norm is below "
            f"{MIN_ACC_NORM:g} m/s^2 in {small} of {int(fin.sum())} samples (about 1 means g "
            f"units; a sensor at rest reads {GRAVITY} m/s^2): multiply them by {GRAVITY}"
        )
    if rec.gyr is None:
        return
    gyr_norm = np.linalg.norm(rec.gyr, axis=1)
    big = int(np.sum(possible_gyr & (gyr_norm > MAX_GYR_NORM)))
    if big >= UNIT_MIN_COUNT and 100 * big >= rec.t.size:
        raise ValueError(
            f"{path}: gx, gy, gz must be in rad/s, but {big} of {rec.t.size} samples exceed "
            f"{MAX_GYR_NORM:g} rad/s (2000 deg/s, beyond any head's turn): deg/s data? Multiply "
            f"them by pi/180 = {np.pi / 180:.6f} (np.radians)"
        )
    if rec.mag is not None:  # slow deg/s data: fitted on the samples possible in rad/s
        ok = np.all(np.abs(rec.gyr) <= MAX_GYR_AXIS, axis=1)
        ratio, rms = gyro_to_field_ratio(rec.t, np.where(ok[:, None], rec.gyr, np.nan), rec.mag)
        lo, hi = DEG_RATIO_RANGE
        if rms > 0.1 and lo <= ratio <= hi:
            raise ValueError(
                f"{path}: gx, gy, gz must be in rad/s, but the gyro turns {ratio:.1f} times "
                "faster than the magnetometer's field does (57.3 for deg/s): deg/s data? "
                f"Multiply them by pi/180 = {np.pi / 180:.6f} (np.radians)"
            )


def _runs(mask: NDArray[np.bool_]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Starts and (inclusive) ends of the runs of True in a 1-D mask."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1


def check_recording(rec: Recording, path: Path) -> Recording:
    """Check units, impossible and missing samples and gaps of a recording (see the module doc).

    Impossible samples become NaN (in place); the warnings go to stderr, one line each.

    Raises:
        ValueError: the errors listed in the module doc, naming ``path``.
    """
    t = rec.t
    n = t.size
    if n < 2 or t[-1] <= t[0]:
        raise ValueError(f"{path}: needs samples at 2 distinct times at least, found {n} rows")
    dt = _check_rate(rec, path)
    # Gyro samples some unit allows (|component| <= 2040, 2000 deg/s and 2 %): deg/s evidence.
    possible_gyr = None
    if rec.gyr is not None:
        possible_gyr = np.all(np.abs(rec.gyr) <= np.degrees(MAX_GYR_AXIS), axis=1)
    _check_units(rec, path, possible_gyr if possible_gyr is not None else np.ones(n, bool))

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
        _warn(path, f"{n_bad} of {n} rows hold values beyond any IMU's range ({what}; "
                    f"{limits}, the first at {_where(rec, int(np.argmax(any_bad)))}); treated "
                    "them as missing (NaN)")  # fmt: skip
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
        _warn(
            path,
            f"{int(any_nan.sum())} of {n} rows have missing values (NaN: {what}); the longest "
            f"run of missing rows lasts {t[ends[k]] - t[starts[k]] + dt:.3g} s from "
            f"{_where(rec, int(starts[k]))}; the estimators bridge them",
        )
    if rec.gyr is not None and not np.isfinite(rec.gyr).all(axis=1).any():
        _warn(path, "no row holds a gyro sample: treated as accelerometer-only data")
        rec.gyr = None
    if rec.mag is not None and not np.isfinite(rec.mag).all(axis=1).any():
        rec.mag = None
    n_acc = int(np.isfinite(rec.acc).all(axis=1).sum())
    if n_acc < 2:
        raise ValueError(f"{path}: {n_acc} rows hold an accelerometer sample; the steps need 2")

    # Gaps in the timestamps.
    d = np.diff(t)
    gap = d > _gap_threshold(dt)
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
        _warn(path, f"{said}; nothing is estimated inside them (the attitude filter treats "
                    "them as missing samples, the step detector finds no step there)")  # fmt: skip
    if t[-1] - t[0] > MAX_SPAN_S:
        raise ValueError(
            f"{path}: the recording spans {t[-1] - t[0]:.6g} s, over the {MAX_SPAN_S / 3600:g} h "
            "limit; split it"
        )
    return rec


# ------------------------------------------------------------------------------------------------
# Estimation.
# ------------------------------------------------------------------------------------------------


def _attitude(rec: Recording, offline: bool = False) -> NDArray[np.float64]:
    """Quaternions at ``rec.t``: the EKF at the median rate, gaps filled with missing samples;
    with ``offline`` its forward-backward smoother (:func:`estimate_attitude`)."""
    assert rec.gyr is not None
    d = np.diff(rec.t)
    dt = float(np.median(d))
    if np.ptp(d) <= 0.05 * dt:
        return estimate_attitude(rec.gyr, rec.acc, rec.mag, 1.0 / dt, offline=offline)
    cuts = np.flatnonzero(d > _gap_threshold(dt)) + 1
    segments = np.split(np.arange(rec.t.size), cuts)
    series = [x for x in (rec.gyr, rec.acc, rec.mag) if x is not None]
    grids, pieces, spans = [], [[] for _ in series], []
    start = 0
    for k, seg in enumerate(segments):
        ts = rec.t[seg]
        grid = ts[0] + dt * np.arange(int(np.floor((ts[-1] - ts[0]) / dt)) + 1)
        for piece, x in zip(pieces, series, strict=True):
            piece.append(np.stack([np.interp(grid, ts, x[seg, j]) for j in range(3)], -1))
        grids.append(grid)
        spans.append((start, start + grid.size))
        start += grid.size
        if k + 1 < len(segments):  # the gap: missing samples, at most MAX_BRIDGE_S of them
            gap = rec.t[segments[k + 1][0]] - ts[-1]
            fill = min(max(int(np.rint(gap / dt)) - 1, 0), int(np.ceil(MAX_BRIDGE_S / dt)))
            for piece in pieces:
                piece.append(np.full((fill, 3), np.nan))
            start += fill
    arrays = [np.concatenate(p) for p in pieces]
    mag = arrays[2] if rec.mag is not None else None
    q_grid = estimate_attitude(arrays[0], arrays[1], mag, 1.0 / dt, offline=offline)
    q = np.empty((rec.t.size, 4))
    for seg, grid, (a, b) in zip(segments, grids, spans, strict=True):
        q[seg] = np.stack([np.interp(rec.t[seg], grid, q_grid[a:b, j]) for j in range(4)], -1)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _compare_attitude(rec: Recording, q: NDArray[np.float64]) -> dict:
    """RMSE of the estimate against the recording's reference attitude (BROAD's metric)."""
    assert rec.ref_quat is not None
    mask = np.ones(rec.t.size, bool) if rec.ref_mask is None else rec.ref_mask
    err = orientation_errors(q, rec.ref_quat, mask, align_heading=rec.mag is None)
    return {
        "reference": "opt_quat (optical motion capture), the samples BROAD scores",
        "samples": err["n_samples"],
        "total_rmse_deg": round(err["total_rmse_deg"], 3),
        "inclination_rmse_deg": round(err["inclination_rmse_deg"], 3),
        "heading_rmse_deg": round(err["heading_rmse_deg"], 3),
        "heading_aligned": rec.mag is None,
    }


def _compare_steps(rec: Recording, step_times: NDArray[np.float64], tol: float = 0.2) -> dict:
    """Detected steps against the foot-switch heel strikes, matched within +-tol s
    (:func:`agents.metrics.match_step_times`, the benchmark's matching)."""
    from agents.metrics import match_step_times

    assert rec.ref_steps is not None
    truth = rec.ref_steps
    precision, recall, f1 = step_f1(step_times, truth, tol)
    hits, false_positives, misses = match_step_times(truth, step_times, tol)
    return {
        "reference": "foot switches (stepcounter.csv), rising edges",
        "tolerance_s": tol,
        "true_steps": int(truth.size),
        "true_positives": hits,
        "false_positives": false_positives,
        "misses": misses,
        "precision": round(precision, 4),
        "recall": round(recall, 4),
        "f1": round(f1, 4),
    }


def estimate_recording(
    path: Path, out_dir: Path, step_length: float = 0.7, offline: bool = False
) -> dict:
    """Run the estimators on ``path``; write ``NAME_estimates.csv`` and ``.png`` in ``out_dir``.

    ``offline=True`` estimates the attitude with the forward-backward smoother of
    :func:`estimators.attitude.estimate_attitude` (the whole recording at every sample) instead
    of the causal filter; the steps and the path are the same either way.

    Returns:
        A summary: name, samples, steps, has_attitude, offline (the attitude is the
        smoother's), the output paths, and where the recording carries ground truth
        ``attitude_vs_reference`` (BROAD: total, inclination and heading RMSE in deg against
        ``opt_quat`` over the ``movement`` samples; the heading offset is removed first for 6D
        data) or ``steps_vs_foot_switches`` (Oxford: true and false positives, misses,
        precision, recall and F1 within +-0.2 s, :func:`estimators.gait.step_f1`).

    Raises:
        ValueError: a malformed recording, or ``step_length`` outside [0.2, 1.5] m (the range
            of a person's step, as :class:`vrloco_env.config.EstimatorConfig` allows).
    """
    if isinstance(step_length, bool) or not isinstance(step_length, int | float) or not (
        0.2 <= step_length <= 1.5
    ):
        raise ValueError(f"step_length={step_length!r}: must be in [0.2, 1.5] m")
    rec = read_recording(path)
    gait = detect_steps(rec.t, rec.acc, params=rec.gait)
    n = rec.t.size
    steps = np.zeros(n)
    np.add.at(steps, gait.step_index, 1.0)
    walking = gait.state.astype(bool)
    result: dict = {"name": rec.name, "samples": n, "steps": int(gait.step_times.size)}
    if rec.gyr is not None:
        q = _attitude(rec, offline)
        ypr = quat_to_ypr(q)
        path_xy = dead_reckon(steps, ypr[:, 0], step_length)
        table = np.column_stack([rec.t, q, np.rad2deg(ypr), walking, steps, path_xy])
        header = "t,qw,qx,qy,qz,yaw_deg,pitch_deg,roll_deg,walking,step,x,y"
    else:
        _warn(path, "no gyroscope: no attitude (the output has no attitude columns or plot); "
                    "steps as usual, the path drawn along +x")  # fmt: skip
        q = ypr = None
        path_xy = dead_reckon(steps, np.zeros(n), step_length)
        table = np.column_stack([rec.t, walking, steps, path_xy])
        header = "t,walking,step,x,y"
    result["has_attitude"] = q is not None
    result["offline"] = bool(offline) and q is not None  # the attitude is the smoother's
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = out_dir / f"{rec.name}_estimates.csv"
    np.savetxt(csv_path, table, delimiter=",", fmt="%.6f", header=header, comments="")
    png = out_dir / f"{rec.name}_estimates.png"
    _plot(rec, ypr, gait.step_times, path_xy, png)
    result["csv"] = str(csv_path)
    result["png"] = str(png)
    if rec.ref_quat is not None and q is not None:
        result["attitude_vs_reference"] = _compare_attitude(rec, q)
    if rec.ref_steps is not None:
        result["steps_vs_foot_switches"] = _compare_steps(rec, gait.step_times)
    return result


def _plot(rec: Recording, ypr: NDArray | None, step_times: NDArray, path_xy: NDArray,
          png: Path) -> None:  # fmt: skip
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(12, 7), constrained_layout=True)
    rows = 2 if ypr is not None else 1
    grid = fig.add_gridspec(rows, 2, width_ratios=(2, 1))
    ax_f = fig.add_subplot(grid[rows - 1, 0])
    ax_p = fig.add_subplot(grid[:, 1])
    if ypr is not None:
        ax_att = fig.add_subplot(grid[0, 0], sharex=ax_f)
        for k, name in enumerate(("yaw", "pitch", "roll")):
            ax_att.plot(rec.t, np.rad2deg(ypr[:, k]), lw=0.8, label=name)
        ax_att.set_ylabel("attitude (deg)")
        ax_att.legend(fontsize=8)
    fn = np.linalg.norm(rec.acc, axis=-1)
    ok = np.isfinite(fn)
    ax_f.plot(rec.t, fn, lw=0.6, color="k")
    ax_f.plot(
        step_times,
        np.interp(step_times, rec.t[ok], fn[ok]),
        "v",
        color="tab:red",
        ms=4,
        label=f"detected steps ({step_times.size})",
    )
    ax_f.set_ylabel("|f| (m/s²)")
    ax_f.set_xlabel("time (s)")
    ax_f.legend(fontsize=8)
    ax_p.plot(path_xy[:, 0], path_xy[:, 1], color="tab:blue")
    ax_p.set_aspect("equal", adjustable="datalim")
    ax_p.set_title("eq (17) path" + ("" if ypr is not None else " (no attitude: along +x)"))
    ax_p.set_xlabel("x (m)")
    ax_p.set_ylabel("y (m)")
    fig.suptitle(rec.name)
    fig.savefig(png, dpi=110)
    plt.close(fig)
