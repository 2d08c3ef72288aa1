"""Recordings for ``vrloco estimate``: the readers and the checks every recording goes through.

Inputs (chosen by what ``PATH`` is):

* a CSV file with a header row and these columns (any order, extra columns ignored):
  ``t`` time (s, increasing), ``ax, ay, az`` specific force (m/s^2; a level sensor at rest reads
  ``az = +9.81``), optionally ``gx, gy, gz`` angular rate (rad/s; without them there is no
  attitude) and ``mx, my, mz`` magnetic field (any fixed unit, e.g. uT); other units of time,
  specific force and rate are read as :class:`Units` says (each found from the data by
  default). Sensor frame x forward,
  y left, z up for a head-worn unit. The file is UTF-8 text (a byte-order mark, as spreadsheets
  write, is skipped); UTF-16 text with a byte-order mark is decoded too; anything else (binary,
  UTF-16 without a mark, other encodings) is refused with an error naming the file. A missing
  value is written ``nan``.
* a BROAD trial (``.hdf5`` or ``.mat``, ``vrloco data fetch broad``): its optical reference attitude
  ``opt_quat`` is compared with the estimate;
* an Oxford step-counter folder (``accelerometer.csv``: steps and the still/walk state; with no
  gyroscope there is no attitude, and the path is drawn along +x). Its foot switches
  (``stepcounter.csv``, when present) are compared with the detected steps.

Checks on every recording, each said in one line on stderr or raised as one ValueError naming
the file (and, for a CSV, the line and the column):

* units (:class:`Units`, ``vrloco estimate --time-unit/--acc-unit/--gyro-unit``), each
  ``"auto"`` unless given; a unit read other than the documented one is said in one line, and
  the values are converted:

  - ``t``: ``auto`` takes the one of s, ms, us, ns in which the median interval is an IMU's
    rate (:data:`RATE_RANGE_HZ`, 5 Hz to 10 kHz); none, or more than one (a median interval of
    0.1-0.2, 100-200 or 1e5-2e5), is an error. A given unit must give such a rate.
  - accelerometer: ``auto`` reads m/s^2 when the median norm of the specific force averaged
    over 1 s (:data:`ACC_MEAN_S`) is 0.5 g to 2 g in m/s^2 (:data:`ACC_MEDIAN_RANGE_G`:
    gravity), g when it is 0.5 to 2; anything else is an error (gravity removed?), and so is a
    given unit that puts that norm outside 0.5 g to 2 g.
  - gyro: ``auto`` goes by the first of three kinds of evidence that decides: (1) the
    magnitude, deg/s when at least :data:`UNIT_MIN_COUNT` samples and 1 % of them exceed
    35 rad/s (:data:`estimators.attitude.MAX_GYR_NORM`, 2000 deg/s: no head turns so fast);
    (2) the magnetometer, whose direction turns 0.5-2 times (rad/s, :data:`RAD_RATIO_RANGE`) or
    35-95 times (deg/s, :data:`DEG_RATIO_RANGE`) slower than the gyro's numbers say
    (:func:`gyro_to_field_ratio`, over the whole recording, with at least
    :data:`MIN_FIT_TURNING` RMS of turning seen); (3) the accelerometer's tilt: the gravity
    direction, carried through 4 s windows by the gyro integrated in each unit, spreads at least
    :data:`TILT_RATIO` times, and :data:`TILT_MARGIN_DEG` more, in one unit than in the other
    (:func:`tilt_spreads`; the wrong unit spins gravity around wherever the head tilts). Where
    none decides (no magnetometer, or one that sees too little turning, and a sensor that
    hardly tilts, as in a level turn), ``auto`` reads rad/s only when the gyro, read as rad/s,
    turns the sensor less than :data:`UNDECIDED_TURN_DEG` (10 deg) within every 4 s window
    (both readings then give nearly the same attitude); otherwise it is an error asking for the
    unit. Evidence against the unit read, given or found, is a warning (one line).
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

from estimators.attitude.ekf import MAX_GYR_NORM
from estimators.rotations import (
    GRAVITY,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    quat_rotate,
)
from estimators.steps.zhang2021 import GaitParams

__all__ = [
    "GAP_INTERVALS",
    "MAX_ACC_AXIS",
    "MAX_BRIDGE_S",
    "MAX_GAP_S",
    "MAX_GYR_AXIS",
    "MAX_MAG_RATIO",
    "MAX_SPAN_S",
    "Recording",
    "Units",
    "check_recording",
    "gap_threshold",
    "gyro_to_field_ratio",
    "read_csv_recording",
    "read_recording",
    "tilt_spreads",
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
        units: the units the file's columns were read in (``time``, ``acc``, ``gyro``), set by
            :func:`check_recording`; ``t``, ``acc`` and ``gyr`` above are converted.
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
    units: dict[str, str] | None = None


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


def read_csv_recording(path: Path, units: Units | None = None) -> Recording:
    """Read and check the documented CSV format (see the module doc), its columns in ``units``
    (default: each found from the data).

    Raises:
        ValueError: one line naming the file (and the line and column where there is one): not
            a UTF-8/UTF-16 text file, a missing column, a malformed row, time running
            backwards, units that cannot be found or do not fit the data, or a recording that is
            mostly impossible values.
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
    return check_recording(rec, path, units)


def _format_units(path: Path, units: Units | None, kind: str) -> Units:
    """The fixed units of a BROAD trial or an Oxford recording (s, m/s^2, rad/s); a ValueError
    where ``units`` gives another (those are for CSV files)."""
    fixed = Units(time="s", acc="m/s2", gyro="rad/s")
    for name, value in (units or Units()).given().items():
        if value != getattr(fixed, name):
            raise ValueError(
                f"{path}: {kind} is in {getattr(fixed, name)} by its format; a {name} unit "
                f"({value!r}, --{name}-unit) applies to CSV files only"
            )
    return fixed


def read_recording(path: Path, units: Units | None = None) -> Recording:
    """A recording from a CSV file, a BROAD trial or an Oxford folder (see the module doc).

    ``units``: the CSV columns' units (default: each found from the data); a BROAD trial and an
    Oxford recording have theirs by their format (a different unit given is an error).
    """
    path = Path(path)
    if units is not None and not isinstance(units, Units):
        raise ValueError(f"units={units!r}: must be a Units (or None for 'auto' throughout)")
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
        fixed = _format_units(path, units, "an Oxford step-counter recording")
        rec = Recording(path.name, t, acc, None, None, GaitParams.neck_pouch(),
                        ref_steps=ref_steps)  # fmt: skip
        return check_recording(rec, path, fixed)
    if not path.is_file():
        raise ValueError(f"{path}: no such file or folder")
    if path.suffix.lower() in (".hdf5", ".h5", ".mat"):
        from estimators.io.broad import load_broad

        fixed = _format_units(path, units, "a BROAD trial")
        trial = load_broad(path)
        t = np.arange(trial.acc.shape[0]) / trial.fs
        rec = Recording(trial.name, t, trial.acc, trial.gyr, trial.mag, GaitParams(),
                        ref_quat=trial.quat, ref_mask=trial.movement)  # fmt: skip
        return check_recording(rec, path, fixed)
    return read_csv_recording(path, units)


# ------------------------------------------------------------------------------------------------
# Checks.
# ------------------------------------------------------------------------------------------------


def _where(rec: Recording, i: int) -> str:
    """The position of sample ``i`` in words: its time and its line (CSV) or index."""
    pos = f"line {int(rec.line[i])}" if rec.line is not None else f"sample {i}"
    return f"t = {rec.t[i]:.6g} s ({pos})"


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
            warn(path, f"read t in {unit} (its median interval {raw:.6g} is "
                        f"{1.0 / (raw * TIME_UNITS[unit]):.4g} Hz in {unit}, "
                        f"{rate} in s); pass --time-unit {unit} to say so")  # fmt: skip
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
            warn(path, f"read ax, ay, az in {unit} (the median norm of their {ACC_MEAN_S:g} s "
                        f"means, {median:.4g}, is gravity in {unit}); pass --acc-unit {unit} to "
                        "say so")  # fmt: skip
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
    t: NDArray[np.float64], gyr: NDArray[np.float64], acc: NDArray[np.float64],
) -> dict[str, float] | None:  # fmt: skip
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
        found.append(("gyro's magnitude", "deg/s", f"{big} of {rec.t.size} samples exceed "
                      f"{MAX_GYR_NORM:g} rad/s (2000 deg/s, beyond any head's turn)"))  # fmt: skip
    if rec.mag is not None:  # fitted on the samples possible in rad/s
        ok = np.all(np.abs(rec.gyr) <= MAX_GYR_AXIS, axis=1)
        ratio, rms = gyro_to_field_ratio(rec.t, np.where(ok[:, None], rec.gyr, np.nan), rec.mag)
        why = (f"its field turns {ratio:.3g} times slower than the gyro's numbers say (1 for "
               "rad/s, 57.3 for deg/s)")  # fmt: skip
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
            if (tilt[other] >= TILT_RATIO * tilt[unit]
                    and tilt[other] - tilt[unit] >= TILT_MARGIN_DEG):  # fmt: skip
                found.append(("accelerometer's tilt", unit, (
                    f"gravity, carried {TILT_WINDOW_S:g} s at a time by the gyro, spreads "
                    f"{tilt[unit]:.1f} deg read in {unit} but {tilt[other]:.1f} deg read in "
                    f"{other}")))  # fmt: skip
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
                warn(path, f"read gx, gy, gz in {unit}, as the {source} says ({why}); pass "
                            f"--gyro-unit {unit} to say so")  # fmt: skip
        elif tilt is not None and tilt["turn_deg"] >= UNDECIDED_TURN_DEG:
            fits = f"the recording is too short for the tilt ({2 * TILT_SMOOTH_S:g} s)"
            if np.isfinite(tilt["rad/s"]):
                fits = (f"the accelerometer's tilt fits both (gravity spreads "
                        f"{tilt['rad/s']:.1f} deg read in rad/s, {tilt['deg/s']:.1f} deg in "
                        "deg/s: the sensor hardly tilts)")  # fmt: skip
            raise ValueError(
                f"{path}: cannot tell whether gx, gy, gz are in rad/s or deg/s: none exceeds "
                f"{MAX_GYR_NORM:g} rad/s, {mag_said}, and {fits}, while read as rad/s the gyro "
                f"turns the sensor {tilt['turn_deg']:.0f} deg within {TILT_WINDOW_S:g} s (over "
                f"{UNDECIDED_TURN_DEG:g} deg): pass --gyro-unit rad/s or --gyro-unit deg/s"
            )
        else:
            unit = "rad/s"
    against = [f"the {source} says {other} ({why})" for source, other, why in found
               if other != unit]  # fmt: skip
    if against:
        warn(path, f"gx, gy, gz are read in {unit} ({'given' if given else 'found'}), but "
                    f"{' and '.join(against)}; check --gyro-unit")  # fmt: skip
    if GYRO_UNITS[unit] != 1.0:
        rec.gyr = rec.gyr * GYRO_UNITS[unit]
    rec.units = {**(rec.units or {}), "gyro": unit}


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
