"""A recording as the readers return it (:class:`Recording`: times, specific force, angular rate,
magnetic field, the gait parameters and any reference), its columns and their largest
readings, and how a reader or a check speaks: one line on stderr per warning (:func:`warn`), a
sample named by its row or time.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from estimators.rotations import (
    GRAVITY,
)
from estimators.steps.zhang2021 import GaitParams

__all__ = ["GAP_INTERVALS", "MAX_ACC_AXIS", "MAX_GYR_AXIS", "Recording", "gap_threshold", "warn"]


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


#: An interval longer than this many median intervals (and 0.1 s) is a gap in the recording.
GAP_INTERVALS = 10.0


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
            :func:`~agents.recordings.checks.check_recording`; ``t``, ``acc`` and ``gyr`` above are
            converted.
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


def _where(rec: Recording, i: int) -> str:
    """The position of sample ``i`` in words: its time and its line (CSV) or index."""
    pos = f"line {int(rec.line[i])}" if rec.line is not None else f"sample {i}"
    return f"t = {rec.t[i]:.6g} s ({pos})"
