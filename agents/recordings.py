"""Recordings for ``vrloco estimate``: the readers and the checks every recording goes through.

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

from estimators.attitude import MAX_GYR_NORM, MIN_ACC_NORM
from estimators.rotations import GRAVITY
from estimators.steps import GaitParams

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
    "gap_threshold",
    "gyro_to_field_ratio",
    "read_csv_recording",
    "read_recording",
    "warn",
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


def gap_threshold(dt: float) -> float:
    """The shortest interval (s) that counts as a gap, for a median interval ``dt``."""
    return max(GAP_INTERVALS * dt, 0.1)


def warn(path: Path | str, message: str) -> None:
    """Say ``message`` about the recording at ``path`` in one line on stderr."""
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
        warn(path, f"{repeated} rows repeat the previous row's timestamp; merged them into "
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
        from estimators.io.oxford import load_oxford, read_accelerometer

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
        from estimators.io.broad import load_broad

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
        warn(path, f"{n_bad} of {n} rows hold values beyond any IMU's range ({what}; "
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
        warn(path, f"{said}; nothing is estimated inside them (the attitude filter treats "
                    "them as missing samples, the step detector finds no step there)")  # fmt: skip
    if t[-1] - t[0] > MAX_SPAN_S:
        raise ValueError(
            f"{path}: the recording spans {t[-1] - t[0]:.6g} s, over the {MAX_SPAN_S / 3600:g} h "
            "limit; split it"
        )
    return rec
