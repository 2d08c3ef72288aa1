"""The visual-inertial fusion of the helmet-tracking paper's experiment: the filter over a
trajectory, started at the first visual pose (:func:`fuse`), and the errors of its estimate
(:func:`fused_stats`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from agents.experiments.vio.metrics import error_series, error_stats
from agents.experiments.vio.settings import IMU_RATE_HZ
from agents.experiments.vio.trajectories import Trajectory
from agents.experiments.vio.visual import VisualRun
from estimators.head_pose.visual_inertial import VioConfig, VisualInertialFilter

__all__ = ["fuse"]


def fuse(traj: Trajectory, run: VisualRun, config: VioConfig) -> tuple[NDArray, NDArray, dict]:
    """The visual-inertial filter over the trajectory, started at the first visual pose.

    The filter is reset at the first frame with a pose: that pose, zero velocity (the user
    stands at the start), zero bias estimates (their uncertainty is the config's initial bias
    sigmas), and the IMU sample of that instant; it then runs over the remaining samples.

    Returns:
        ``(pos (N, 3), quat (N, 4), counters)``: the estimate after every IMU sample (NaN before
        the start sample), and the filter's frame counters with ``start`` (the first estimated
        sample).
    """
    n = traj.t.size
    first = np.flatnonzero(run.ok)
    pos = np.full((n, 3), np.nan)
    quat = np.full((n, 4), np.nan)
    if first.size == 0 or run.sample[first[0]] >= n - 1:
        return pos, quat, {"updates": 0, "rejected": 0, "forced": 0, "start": n}
    j0 = int(first[0])
    s0 = int(run.sample[j0])
    f = VisualInertialFilter(1, IMU_RATE_HZ, config)
    f.reset(run.position[j0], np.zeros(3), run.quat[j0], gyr=traj.gyr[s0], acc=traj.acc[s0])
    sel = run.sample > s0
    p, q, _ = f.process(
        traj.gyr[None, s0 + 1 :],
        traj.acc[None, s0 + 1 :],
        (run.sample[sel] - s0 - 1).astype(np.intp),
        run.position[None, sel],
        run.quat[None, sel],
        run.ok[None, sel],
    )
    pos[s0] = run.position[j0]
    quat[s0] = run.quat[j0]
    pos[s0 + 1 :] = p[0]
    quat[s0 + 1 :] = q[0]
    counters = {
        "updates": int(f.updates[0]),
        "rejected": int(f.rejected[0]),
        "forced": int(f.forced[0]),
        "start": s0,
    }
    return pos, quat, counters


def fused_stats(
    traj: Trajectory,
    pos: NDArray,
    quat: NDArray,
    start: int,
    lo: int = 0,
    hi: int | None = None,
    samples: bool = True,
) -> tuple:
    """Errors of a fused run over samples ``[max(lo, start), hi)``, and the full-length series
    (NaN before the start) for the figure."""
    n = traj.t.size
    hi = n if hi is None else hi
    ep, ea = np.full(n, np.nan), np.full(n, np.nan)
    if start < n:
        ep[start:], ea[start:] = error_series(
            pos[start:], quat[start:], traj.pos[start:], traj.quat[start:]
        )
    k = max(lo, start)
    return error_stats(ep[k:hi], ea[k:hi], samples=samples), (ep, ea)
