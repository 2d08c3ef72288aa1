"""Reader for Kinect v2 skeleton recordings in the CSV layout of Microsoft's LabanotationSuite.

Layout (``../shared/data/kinect_laban/Ges01_wavehand.csv``, MIT licence, see the data README): one
row per frame, no header; the first field is the frame time in 100-ns ticks (the Kinect
``RelativeTime``, a ``TimeSpan``), then 25 joints x (x, y, z, trackingState) in Kinect v2
``JointType`` order, camera-space metres, tracking state 0 not tracked, 1 inferred, 2 tracked; the
row ends with a trailing comma (so 102 fields, the last empty).
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = ["KinectRecording", "read_kinect_csv"]

#: Length of one Kinect ``TimeSpan`` tick, s (.NET ``TimeSpan``: 100 ns).
TICK_SECONDS = 1e-7

NUM_JOINTS = 25


@dataclass
class KinectRecording:
    """A single-body Kinect v2 skeleton recording.

    Attributes:
        t: (M,) frame times, s, relative to the first frame (t[0] = 0).
        ticks: (M,) int64 raw frame times, 100-ns ticks.
        joints: (M, 25, 3) camera-space joint positions, m; NaN where the state is 0.
        state: (M, 25) int8 tracking states (0 not tracked, 1 inferred, 2 tracked).
    """

    t: NDArray[np.float64]
    ticks: NDArray[np.int64]
    joints: NDArray[np.float64]
    state: NDArray[np.int8]

    @property
    def rate_hz(self) -> float:
        """Mean frame rate, Hz."""
        return float((len(self.t) - 1) / (self.t[-1] - self.t[0])) if len(self.t) > 1 else np.nan


def read_kinect_csv(path: str | PathLike[str], num_joints: int = NUM_JOINTS) -> KinectRecording:
    """Read a LabanotationSuite Kinect v2 CSV.

    Args:
        path: the CSV file.
        num_joints: joints per row (25 for Kinect v2).

    Returns:
        :class:`KinectRecording`. Joints whose state is 0 (not tracked) are set to NaN, as the
        rest of vrloco expects.

    The file is ASCII text; a UTF-8 byte-order mark (a spreadsheet's) is skipped.

    Raises:
        FileNotFoundError: no such file.
        ValueError: a file that is not ASCII/UTF-8 text, or a malformed file, naming the line
            (1-based) and column (1-based field index):
            wrong field count, a non-numeric field, a tracking state outside {0, 1, 2}, a
            non-finite coordinate, non-increasing times, or no rows at all.
    """
    p = Path(path)
    n_fields = 1 + 4 * num_joints
    ticks: list[int] = []
    rows: list[list[float]] = []
    try:
        text = p.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise ValueError(
            f"{p.name}: not a text CSV (byte {err.start} is not ASCII/UTF-8: binary data or "
            "another encoding)"
        ) from None
    with io.StringIO(text, newline=None) as fh:
        for lineno, line in enumerate(fh, start=1):
            text = line.strip()
            if not text:
                continue
            fields = text.split(",")
            if fields[-1].strip() == "":
                fields = fields[:-1]  # the trailing comma
            if len(fields) != n_fields:
                raise ValueError(
                    f"{p.name}: line {lineno}: expected {n_fields} fields (time + {num_joints} "
                    f"joints x 4), got {len(fields)}"
                )
            try:
                tick = int(fields[0])
            except ValueError:
                raise ValueError(
                    f"{p.name}: line {lineno}, column 1: time must be an integer tick count, got "
                    f"{fields[0]!r}"
                ) from None
            vals = []
            for col, f in enumerate(fields[1:], start=2):
                try:
                    v = float(f)
                except ValueError:
                    raise ValueError(
                        f"{p.name}: line {lineno}, column {col}: not a number: {f!r}"
                    ) from None
                if (col - 2) % 4 == 3:
                    if v not in (0.0, 1.0, 2.0):
                        raise ValueError(
                            f"{p.name}: line {lineno}, column {col}: tracking state must be 0, 1 "
                            f"or 2, got {f!r}"
                        )
                elif not np.isfinite(v):
                    raise ValueError(
                        f"{p.name}: line {lineno}, column {col}: coordinate is not finite: {f!r}"
                    )
                vals.append(v)
            if ticks and tick <= ticks[-1]:
                raise ValueError(
                    f"{p.name}: line {lineno}, column 1: time {tick} does not increase (previous "
                    f"{ticks[-1]})"
                )
            ticks.append(tick)
            rows.append(vals)
    if not rows:
        raise ValueError(f"{p.name}: no data rows")
    data = np.asarray(rows, dtype=np.float64).reshape(len(rows), num_joints, 4)
    state = data[..., 3].astype(np.int8)
    joints = np.where((state > 0)[..., None], data[..., :3], np.nan)
    tk = np.asarray(ticks, dtype=np.int64)
    t = (tk - tk[0]) * TICK_SECONDS
    return KinectRecording(t=t, ticks=tk, joints=joints, state=state)
