"""Recordings for ``vrloco estimate``: the readers (:mod:`agents.recordings.readers`,
:mod:`agents.recordings.record`) and the checks every recording goes through
(:mod:`agents.recordings.checks`, :mod:`agents.recordings.units`); the estimate itself
(:mod:`agents.recordings.estimate`), the data sets (:mod:`agents.recordings.data`) and the
real head traces with their statistics (:mod:`agents.recordings.head_traces`,
:mod:`agents.recordings.head_motion_stats`).

Inputs (chosen by what ``PATH`` is):

* a CSV file with a header row and these columns (any order, extra columns ignored):
  ``t`` time (s, increasing), ``ax, ay, az`` specific force (m/s^2; a level sensor at rest reads
  ``az = +9.81``), optionally ``gx, gy, gz`` angular rate (rad/s; without them there is no
  attitude) and ``mx, my, mz`` magnetic field (any fixed unit, e.g. uT); other units of time,
  specific force and rate are read as :class:`~agents.recordings.units.Units` says (each found from
  the data by default). Sensor frame x forward,
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

* units (:class:`~agents.recordings.units.Units`, ``vrloco estimate
--time-unit/--acc-unit/--gyro-unit``), each
  ``"auto"`` unless given; a unit read other than the documented one is said in one line, and
  the values are converted:

  - ``t``: ``auto`` takes the one of s, ms, us, ns in which the median interval is an IMU's
    rate (:data:`~agents.recordings.units.RATE_RANGE_HZ`, 5 Hz to 10 kHz); none, or more than one (a
    median interval of 0.1-0.2, 100-200 or 1e5-2e5), is an error. A given unit must give such a
    rate.
  - accelerometer: ``auto`` reads m/s^2 when the median norm of the specific force averaged
    over 1 s (:data:`~agents.recordings.units.ACC_MEAN_S`) is 0.5 g to 2 g in m/s^2
    (:data:`~agents.recordings.units.ACC_MEDIAN_RANGE_G`: gravity), g when it is 0.5 to 2; anything
    else is an error (gravity removed?), and so is a given unit that puts that norm outside 0.5 g to
    2 g.
  - gyro: ``auto`` goes by the first of three kinds of evidence that decides: (1) the
    magnitude, deg/s when at least :data:`~agents.recordings.units.UNIT_MIN_COUNT` samples and 1 %
    of them exceed 35 rad/s (:data:`estimators.attitude.MAX_GYR_NORM`, 2000 deg/s: no head turns so
    fast); (2) the magnetometer, whose direction turns 0.5-2 times (rad/s,
    :data:`~agents.recordings.units.RAD_RATIO_RANGE`) or 35-95 times (deg/s,
    :data:`~agents.recordings.units.DEG_RATIO_RANGE`) slower than the gyro's numbers say
    (:func:`~agents.recordings.units.gyro_to_field_ratio`, over the whole recording, with at least
    :data:`~agents.recordings.units.MIN_FIT_TURNING` RMS of turning seen); (3) the accelerometer's
    tilt: the gravity direction, carried through 4 s windows by the gyro integrated in each unit,
    spreads at least :data:`~agents.recordings.units.TILT_RATIO` times, and
    :data:`~agents.recordings.units.TILT_MARGIN_DEG` more, in one unit than in the other
    (:func:`~agents.recordings.units.tilt_spreads`; the wrong unit spins gravity around wherever the
    head tilts). Where none decides (no magnetometer, or one that sees too little turning, and a
    sensor that hardly tilts, as in a level turn), ``auto`` reads rad/s only when the gyro, read as
    rad/s, turns the sensor less than :data:`~agents.recordings.units.UNDECIDED_TURN_DEG` (10 deg)
    within every 4 s window (both readings then give nearly the same attitude); otherwise it is an
    error asking for the unit. Evidence against the unit read, given or found, is a warning (one
    line).
* impossible samples: a gyro component beyond :data:`~agents.recordings.record.MAX_GYR_AXIS` (2000
deg/s), an accelerometer
  component beyond :data:`~agents.recordings.record.MAX_ACC_AXIS` (16 g), a field norm over
  :data:`~agents.recordings.checks.MAX_MAG_RATIO` times the recording's median norm, or an infinite
  value, are treated as missing (a warning gives the count); an error when they are most of the
  rows.
* missing samples (NaN): a warning with the count and the longest run (s); the estimators bridge
  them (the attitude filter propagates without the missing sensor, the step detector
  interpolates the norm).
* gaps in the timestamps longer than :data:`~agents.recordings.record.GAP_INTERVALS` median
intervals (and 0.1 s): a
  warning with the count and the longest gap's position and length; an error beyond
  :data:`~agents.recordings.checks.MAX_GAP_S`, and so is a recording spanning more than
  :data:`~agents.recordings.checks.MAX_SPAN_S`. The attitude filter treats a gap as missing samples,
  at most :data:`~agents.recordings.checks.MAX_BRIDGE_S` of them.
* rows sharing a timestamp are one sample (their mean, said in one line); time running backwards,
  a row with more or fewer fields than the header and a non-numeric value are errors naming the
  line.
"""

from agents.recordings.checks import (
    MAX_BRIDGE_S,
    MAX_GAP_S,
    MAX_MAG_RATIO,
    MAX_SPAN_S,
    check_recording,
)
from agents.recordings.readers import read_csv_recording, read_recording
from agents.recordings.record import (
    GAP_INTERVALS,
    MAX_ACC_AXIS,
    MAX_GYR_AXIS,
    Recording,
    gap_threshold,
    warn,
)
from agents.recordings.units import Units, gyro_to_field_ratio, tilt_spreads

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
