"""Stage 5 of the Kinect v2 frame loop (:mod:`vrloco_env.sensors.kinect._kernel`), compiled
(``numba.njit(cache=True)``): which bodies are tracked and their ids (:func:`_track`), the ids
kept unique among a user's bodies (:func:`_unique_ids`), and the ids of a reset for a batch of
users (:data:`unique_ids`).
"""

from __future__ import annotations

import numba
import numpy as np

from estimators.kernels.batch import BatchKernel
from vrloco_env.user import NUM_JOINTS

__all__ = ["unique_ids"]


@numba.njit(cache=True)
def _track(n_bodies, p, n_visible, facing, session, new_ids, tracked, fresh) -> None:
    """Stage 5, tracking: a body is detectable while at least ``min_visible_fraction`` of its
    joints are visible and it is turned no further than ``facing_lost_deg`` from the sensor
    (``facing`` (N,) deg, :func:`_facing`); it is tracked after ``acquire_frames`` consecutive
    detectable frames; one tracked again gets a fresh id (``new_ids`` (N,)), unique among the
    user's bodies. ``session`` = (acquired, prev_tracked, body_id), (N,) each, updated in place;
    fills ``tracked`` and ``fresh`` (N,)."""
    acquired, prev_tracked, body_id = session
    acq = int(p["acquire_frames"])
    for n in range(n_bodies):
        seen = n_visible[n] / NUM_JOINTS >= p["min_visible_fraction"]
        if seen and facing[n] <= p["facing_lost_deg"]:
            acquired[n] = min(acquired[n] + 1, acq)
        else:
            acquired[n] = 0
        tracked[n] = acquired[n] >= acq
        fresh[n] = tracked[n] and prev_tracked[n] == 0.0
        if fresh[n]:
            body_id[n] = new_ids[n]
        prev_tracked[n] = 1.0 if tracked[n] else 0.0
    _unique_ids(body_id[:n_bodies], fresh)


@numba.njit(cache=True)
def _unique_ids(ids: np.ndarray, fresh: np.ndarray) -> None:
    """Move a fresh id that equals another body's (not fresh, or fresh and earlier) to the next
    value, until the user's ids differ (as ``model._unique_ids`` does for a batch)."""
    n = ids.size
    if not fresh.any():  # the common case: no body (re)acquired in this frame
        return
    clash = np.zeros(n, dtype=np.bool_)
    while True:
        any_clash = False
        for j in range(n):
            clash[j] = False
            if not fresh[j]:
                continue
            for k in range(n):
                if k != j and ids[k] == ids[j] and (not fresh[k] or k < j):
                    clash[j] = True
                    any_clash = True
                    break
        if not any_clash:
            return
        for j in range(n):
            if clash[j]:
                ids[j] = ids[j] % (2**53) + 1


def _unique_rows(ids, fresh) -> None:
    """:func:`_unique_ids` on every row (user) of ``ids`` (B, N) in place; ``fresh`` (B, N)."""
    for b in numba.prange(ids.shape[0]):
        _unique_ids(ids[b], fresh[b])


#: The ids of a reset: ``unique_ids(B)(ids, fresh)``, :func:`_unique_ids` per user, in place.
unique_ids = BatchKernel(_unique_rows, parallel=False)
