"""``vrloco estimate``: run the head estimators on a recording — attitude, steps, virtual path.

Inputs (chosen by what ``PATH`` is):

* a CSV file with a header row and these columns (any order, extra columns ignored):
  ``t`` time (s, increasing), ``gx, gy, gz`` angular rate (rad/s), ``ax, ay, az`` specific force
  (m/s^2; a level sensor at rest reads ``az = +9.81``), and optionally ``mx, my, mz`` magnetic
  field (any fixed unit, e.g. uT). Sensor frame x forward, y left, z up for a head-worn unit.
* a BROAD trial (``.hdf5`` or ``.mat``, ../shared/data/README.md);
* an Oxford step-counter folder (``accelerometer.csv`` only: steps and the still/walk state; with
  no gyroscope there is no attitude, and the path is drawn along +x).

Irregular timestamps are resampled onto a uniform grid at the median rate (linear interpolation)
for the attitude filter, which assumes a fixed rate; the step detector takes the timestamps as
they are. Output: a CSV (``t, qw, qx, qy, qz, yaw_deg, pitch_deg, roll_deg, walking, step, x, y``)
and a PNG with the attitude, the specific-force norm with the detected steps, and the path of
eq (17). A malformed CSV gets one error naming the line and the column.
"""

from __future__ import annotations

import csv
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from estimators.attitude import estimate_attitude
from estimators.dead_reckoning import dead_reckon
from estimators.gait import GaitParams, detect_steps
from estimators.rotations import quat_to_ypr

__all__ = ["Recording", "estimate_recording", "read_recording"]

REQUIRED = ("t", "gx", "gy", "gz", "ax", "ay", "az")
OPTIONAL = ("mx", "my", "mz")


@dataclass
class Recording:
    """Samples of a head-worn IMU: times (s) and (N, 3) arrays; gyr/mag may be None."""

    name: str
    t: NDArray[np.float64]
    acc: NDArray[np.float64]
    gyr: NDArray[np.float64] | None
    mag: NDArray[np.float64] | None
    gait: GaitParams


def read_csv_recording(path: Path) -> Recording:
    """Read the documented CSV format, with errors naming the line and the column."""
    with path.open(newline="") as fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise ValueError(f"{path}: the file is empty; expected a header row") from None
        missing = [c for c in REQUIRED if c not in header]
        if missing:
            raise ValueError(
                f"{path}, line 1: missing column(s) {', '.join(missing)}; a CSV needs "
                f"{', '.join(REQUIRED)} (and optionally {', '.join(OPTIONAL)})"
            )
        cols = [c for c in (*REQUIRED, *OPTIONAL) if c in header]
        where = [header.index(c) for c in cols]
        rows = []
        for line, row in enumerate(reader, start=2):
            if not row or all(not x.strip() for x in row):
                continue
            values = []
            for name, j in zip(cols, where, strict=True):
                if j >= len(row):
                    raise ValueError(f"{path}, line {line}, column {j + 1} ({name}): missing")
                try:
                    values.append(float(row[j]))
                except ValueError:
                    raise ValueError(
                        f"{path}, line {line}, column {j + 1} ({name}): cannot read "
                        f"{row[j]!r} as a number"
                    ) from None
            rows.append(values)
    if len(rows) < 2:
        raise ValueError(f"{path}: needs at least 2 data rows, found {len(rows)}")
    data = np.asarray(rows)
    get = {c: data[:, k] for k, c in enumerate(cols)}
    t = get["t"]
    bad = np.flatnonzero(np.diff(t) < 0)
    if bad.size:
        raise ValueError(
            f"{path}, line {bad[0] + 3}, column {where[0] + 1} (t): time {t[bad[0] + 1]} runs "
            f"backwards after {t[bad[0]]}; timestamps must not decrease (s)"
        )
    repeated = int(np.sum(np.diff(t) == 0))
    if repeated:  # rows sharing a timestamp are one sample: their mean
        t_u, inverse = np.unique(t, return_inverse=True)
        counts = np.bincount(inverse)
        get = {c: np.bincount(inverse, weights=v) / counts for c, v in get.items()}
        get["t"] = t = t_u
        print(f"{path}: {repeated} rows repeat the previous row's timestamp; merged them into "
              "the mean of the rows sharing it", file=sys.stderr)  # fmt: skip
    acc = np.stack([get["ax"], get["ay"], get["az"]], -1)
    gyr = np.stack([get["gx"], get["gy"], get["gz"]], -1)
    mag = np.stack([get[c] for c in OPTIONAL], -1) if all(c in get for c in OPTIONAL) else None
    return Recording(path.stem, t, acc, gyr, mag, GaitParams())


def read_recording(path: Path) -> Recording:
    """A recording from a CSV file, a BROAD trial or an Oxford folder (see the module doc)."""
    path = Path(path)
    if path.is_dir():
        from estimators.io_oxford import load_oxford

        if not (path / "accelerometer.csv").is_file():
            raise ValueError(
                f"{path}: a folder, but not an Oxford step-counter recording (no "
                "accelerometer.csv); give a CSV file, a BROAD trial (.hdf5/.mat) or an Oxford "
                "recording's folder"
            )
        rec = load_oxford(path)
        return Recording(path.name, rec.t, rec.acc, None, None, GaitParams.neck_pouch())
    if not path.is_file():
        raise ValueError(f"{path}: no such file or folder")
    if path.suffix.lower() in (".hdf5", ".h5", ".mat"):
        from estimators.io_broad import load_broad

        trial = load_broad(path)
        t = np.arange(trial.acc.shape[0]) / trial.fs
        return Recording(trial.name, t, trial.acc, trial.gyr, trial.mag, GaitParams())
    return read_csv_recording(path)


def _uniform(t: NDArray, x: NDArray) -> tuple[NDArray, NDArray, float]:
    """Resample (N, 3) samples onto a uniform grid at the median rate."""
    dt = float(np.median(np.diff(t)))
    grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt)) + 1)
    return grid, np.stack([np.interp(grid, t, x[:, k]) for k in range(3)], -1), 1.0 / dt


def estimate_recording(path: Path, out_dir: Path, step_length: float = 0.7) -> dict:
    """Run the estimators on ``path``; write ``NAME_estimates.csv`` and ``.png`` in ``out_dir``.

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
    if rec.gyr is not None:
        irregular = np.ptp(np.diff(rec.t)) > 0.05 * np.median(np.diff(rec.t))
        if irregular:
            grid, gyr, fs = _uniform(rec.t, rec.gyr)
            acc = _uniform(rec.t, rec.acc)[1]
            mag = None if rec.mag is None else _uniform(rec.t, rec.mag)[1]
            q_grid = estimate_attitude(gyr, acc, mag, fs)
            q = np.stack([np.interp(rec.t, grid, q_grid[:, k]) for k in range(4)], -1)
            q /= np.linalg.norm(q, axis=-1, keepdims=True)
        else:
            fs = 1.0 / float(np.median(np.diff(rec.t)))
            q = estimate_attitude(rec.gyr, rec.acc, rec.mag, fs)
        ypr = quat_to_ypr(q)
    else:
        q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
        ypr = np.zeros((n, 3))
    path_xy = dead_reckon(steps, ypr[:, 0], step_length)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = out_dir / f"{rec.name}_estimates.csv"
    table = np.column_stack([rec.t, q, np.rad2deg(ypr), walking, steps, path_xy])
    np.savetxt(
        csv_path,
        table,
        delimiter=",",
        fmt="%.6f",
        header="t,qw,qx,qy,qz,yaw_deg,pitch_deg,roll_deg,walking,step,x,y",
        comments="",
    )
    png = out_dir / f"{rec.name}_estimates.png"
    _plot(rec, ypr, gait.step_times, path_xy, png)
    return {
        "name": rec.name,
        "samples": n,
        "steps": int(gait.step_times.size),
        "has_attitude": rec.gyr is not None,
        "csv": str(csv_path),
        "png": str(png),
    }


def _plot(rec: Recording, ypr: NDArray, step_times: NDArray, path_xy: NDArray, png: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(12, 7), constrained_layout=True)
    grid = fig.add_gridspec(2, 2, width_ratios=(2, 1))
    ax_att = fig.add_subplot(grid[0, 0])
    ax_f = fig.add_subplot(grid[1, 0], sharex=ax_att)
    ax_p = fig.add_subplot(grid[:, 1])
    for k, name in enumerate(("yaw", "pitch", "roll")):
        ax_att.plot(rec.t, np.rad2deg(ypr[:, k]), lw=0.8, label=name)
    ax_att.set_ylabel("attitude (deg)")
    ax_att.legend(fontsize=8)
    fn = np.linalg.norm(rec.acc, axis=-1)
    ax_f.plot(rec.t, fn, lw=0.6, color="k")
    ax_f.plot(
        step_times,
        np.interp(step_times, rec.t, fn),
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
    ax_p.set_title("eq (17) path")
    ax_p.set_xlabel("x (m)")
    ax_p.set_ylabel("y (m)")
    fig.suptitle(rec.name)
    fig.savefig(png, dpi=110)
    plt.close(fig)
