"""``vrloco estimate``: run the head estimators on a recording — attitude, steps, virtual path.

The recording is read and checked by :mod:`agents.recordings` (a CSV file, a BROAD trial or an
Oxford step-counter folder; the formats, the units a CSV may be in and how each is found from
the data, and every check are described there).

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

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from agents.benchmark.step_matching import step_f1
from agents.recordings import (
    MAX_BRIDGE_S,
    Recording,
    Units,
    gap_threshold,
    read_recording,
    warn,
)
from estimators.attitude import estimate_attitude
from estimators.attitude.errors import orientation_errors
from estimators.locomotion.dead_reckoning import dead_reckon
from estimators.rotations import quat_to_ypr
from estimators.steps import detect_steps

__all__ = ["estimate_recording"]


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
    cuts = np.flatnonzero(d > gap_threshold(dt)) + 1
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
    (:func:`agents.benchmark.step_matching.match_step_times`, the benchmark's matching)."""
    from agents.benchmark.step_matching import match_step_times

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
    path: Path,
    out_dir: Path,
    step_length: float = 0.7,
    offline: bool = False,
    units: Units | None = None,
) -> dict:
    """Run the estimators on ``path``; write ``NAME_estimates.csv`` and ``.png`` in ``out_dir``.

    ``offline=True`` estimates the attitude with the forward-backward smoother of
    :func:`estimators.attitude.estimate_attitude` (the whole recording at every sample) instead
    of the causal filter; the steps and the path are the same either way. ``units``: the
    units of a CSV's columns (:class:`agents.recordings.units.Units`; default: each found from the
    data).

    Returns:
        A summary: name, samples, units (what the columns were read in: ``time``, ``acc``
        and, with a gyro, ``gyro``), steps, has_attitude, offline (the attitude is the
        smoother's), the output paths, and where the recording carries ground truth
        ``attitude_vs_reference`` (BROAD: total, inclination and heading RMSE in deg against
        ``opt_quat`` over the ``movement`` samples; the heading offset is removed first for 6D
        data) or ``steps_vs_foot_switches`` (Oxford: true and false positives, misses,
        precision, recall and F1 within +-0.2 s, :func:`agents.benchmark.step_matching.step_f1`).

    Raises:
        ValueError: a malformed recording, units that cannot be found or do not fit the data,
            or ``step_length`` outside [0.2, 1.5] m (the range of a person's step, as
            :class:`vrloco_env.config.EstimatorConfig` allows).
    """
    if (
        isinstance(step_length, bool)
        or not isinstance(step_length, int | float)
        or not (0.2 <= step_length <= 1.5)
    ):
        raise ValueError(f"step_length={step_length!r}: must be in [0.2, 1.5] m")
    rec = read_recording(path, units)
    gait = detect_steps(rec.t, rec.acc, params=rec.gait)
    n = rec.t.size
    steps = np.zeros(n)
    np.add.at(steps, gait.step_index, 1.0)
    walking = gait.state.astype(bool)
    result: dict = {
        "name": rec.name,
        "samples": n,
        "units": dict(rec.units or {}),
        "steps": int(gait.step_times.size),
    }
    if rec.gyr is not None:
        q = _attitude(rec, offline)
        ypr = quat_to_ypr(q)
        path_xy = dead_reckon(steps, ypr[:, 0], step_length)
        table = np.column_stack([rec.t, q, np.rad2deg(ypr), walking, steps, path_xy])
        header = "t,qw,qx,qy,qz,yaw_deg,pitch_deg,roll_deg,walking,step,x,y"
    else:
        warn(
            path,
            "no gyroscope: no attitude (the output has no attitude columns or plot); "
            "steps as usual, the path drawn along +x",
        )
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


def _plot(
    rec: Recording, ypr: NDArray | None, step_times: NDArray, path_xy: NDArray, png: Path
) -> None:
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
