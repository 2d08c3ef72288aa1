"""The visual poses of the helmet-tracking paper's experiment: frames captured by the run's true
camera on a trajectory and solved by PnP against the surveyed map (:func:`capture_visual`,
:class:`VisualRun`; the PnP spread over threads, :func:`_solve_all`), and their errors against
the truth (:func:`visual_stats`).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from agents.experiments.vio.metrics import error_series, error_stats, rms
from agents.experiments.vio.mismatch import Setup
from agents.experiments.vio.settings import GROSS_ATT_DEG, GROSS_POS_M, IMU_RATE_HZ
from agents.experiments.vio.trajectories import Trajectory
from estimators.head_pose.pnp import (
    REASON_BEHIND_CAMERA,
    REASON_OK,
    REASON_RANSAC_FAILED,
    REASON_TOO_FEW_INLIERS,
    REASON_TOO_FEW_LANDMARKS,
    solve_poses,
)
from vrloco_env.batch_rng import BatchRng
from vrloco_env.head_tracking import PnpParams, camera_intrinsics, frame_triggers, pnp_mount
from vrloco_env.sensors.camera import CameraSpec, HeadCamera

__all__ = ["VisualRun", "capture_visual", "visual_stats"]

_PNP_BLOCK = 600  # frames per PnP job (5 s at 120 Hz)
_CAPTURE_BLOCK = 1200  # frames per capture call (bounds the (N, K) arrays)


@dataclass(frozen=True)
class VisualRun:
    """The frames of one camera over (part of) a trajectory and their PnP poses (M frames).

    Attributes:
        sample: (M,) IMU sample index of each frame's trigger (its time stamp).
        position: (M, 3) m, NaN without a pose. quat: (M, 4). ok: (M,) bool.
        reason: (M,) int8 failure code (``estimators.head_pose.pnp.REASON_*``).
        n_visible, n_extracted, n_correct: (M,) landmark counts per frame.
    """

    sample: NDArray[np.intp]
    position: NDArray[np.float64]
    quat: NDArray[np.float64]
    ok: NDArray[np.bool_]
    reason: NDArray[np.int8]
    n_visible: NDArray[np.int64]
    n_extracted: NDArray[np.int64]
    n_correct: NDArray[np.int64]

    def select(self, keep: NDArray[np.bool_]) -> VisualRun:
        """The frames where ``keep`` (M,) is True."""
        return VisualRun(*(getattr(self, f)[keep] for f in VisualRun.__dataclass_fields__))

    @staticmethod
    def concatenate(runs: list[VisualRun]) -> VisualRun:
        """The frames of several runs, in the given order."""
        return VisualRun(
            *(np.concatenate([getattr(r, f) for r in runs]) for f in VisualRun.__dataclass_fields__)
        )


def _solve_block(args: tuple) -> tuple:
    """PnP on a block of frames (runs in a worker thread): ``args`` = (the map's landmarks
    (K, 3), matched landmark ids and pixels of the extracted features of all frames,
    concatenated, features per frame, nominal spec, pnp)."""
    landmarks, ids, pixels, per_frame, spec, pnp = args
    cuts = np.cumsum(per_frame)[:-1]
    frames = list(zip(np.split(landmarks[ids], cuts), np.split(pixels, cuts), strict=True))
    mq, mo = pnp_mount(spec)
    res = solve_poses(
        frames,
        camera_intrinsics(spec),
        pnp.min_landmarks,
        pnp.reprojection_px,
        mount_quat=mq,
        mount_offset=mo,
    )
    return res.position, res.quat, res.ok, res.reason


@dataclass
class _Capture:
    """Frames of one camera, captured; their PnP still to do (``jobs`` for :func:`_solve_block`)."""

    sample: NDArray[np.intp]
    counts: NDArray[np.int64]  # (3, M) visible, extracted, correct
    jobs: list


def _capture(
    traj: Trajectory,
    spec: CameraSpec,
    rng: BatchRng,
    setup: Setup,
    pnp: PnpParams,
    first_sample: int,
) -> _Capture:
    """Frames triggered at or after ``first_sample`` by the nominal camera ``spec``: imaged by the
    setup's true camera at the trigger plus the time offset, solved against the setup's map."""
    idx = frame_triggers(0, traj.t.size, IMU_RATE_HZ, spec.rate_hz)
    idx = idx[(idx >= first_sample) & (idx + setup.offset_samples < traj.t.size)]
    cam = HeadCamera(setup.true_camera(spec), rng)
    m = idx.size
    counts = np.zeros((3, m), np.int64)
    jobs = []
    for a in range(0, m, _CAPTURE_BLOCK):
        j = idx[a : a + _CAPTURE_BLOCK] + setup.offset_samples  # the instant actually imaged
        fr = cam.capture(
            traj.t[j],
            traj.pos[None, j],
            traj.quat[None, j],
            traj.omega[None, j],
            setup.landmarks,
            normals=setup.normals,
        )
        counts[:, a : a + j.size] = fr.n_visible[0], fr.n_extracted[0], fr.n_correct[0]
        for b in range(0, j.size, _PNP_BLOCK):
            ext = fr.extracted[0, b : b + _PNP_BLOCK]
            jobs.append(
                (
                    setup.map_landmarks,
                    fr.matched_id[0, b : b + _PNP_BLOCK][ext],
                    fr.pixels[0, b : b + _PNP_BLOCK][ext],
                    ext.sum(axis=1),
                    spec,
                    pnp,
                )
            )
    return _Capture(idx, counts, jobs)


def _assemble(cap: _Capture, results: list) -> VisualRun:
    if results:
        pos, quat, ok, reason = (np.concatenate(x) for x in zip(*results, strict=True))
    else:
        pos, quat = np.zeros((0, 3)), np.zeros((0, 4))
        ok, reason = np.zeros(0, bool), np.zeros(0, np.int8)
    return VisualRun(cap.sample, pos, quat, ok, reason, *cap.counts)


def capture_visual(
    traj: Trajectory,
    spec: CameraSpec,
    rng: BatchRng,
    setup: Setup,
    pnp: PnpParams = PnpParams(),  # noqa: B008  (frozen)
    first_sample: int = 0,
    workers: int = 1,
) -> VisualRun:
    """Capture the frames triggered at or after ``first_sample`` and solve their poses.

    Args:
        traj: the trajectory (its true pose is what the camera sees).
        spec: the nominal camera (the PnP's intrinsics); the images come from
            ``setup.true_camera(spec)``. rng: its random stream (one user).
        setup: the run's truth and nominal values (:func:`make_setup`).
        pnp: PnP settings.
        first_sample: IMU sample from which frames are taken (the clock starts at sample 0).
        workers: threads for the PnP (the poses do not depend on it).
    """
    if not (isinstance(workers, int) and workers >= 1):
        raise ValueError(f"workers must be an int >= 1, got {workers!r}")
    cap = _capture(traj, spec, rng, setup, pnp, first_sample)
    return _assemble(cap, _solve_all({"run": cap}, workers)["run"])


def visual_stats(run: VisualRun, traj: Trajectory) -> dict:
    """Errors of the visual poses against the truth at their time stamps (package docstring)."""
    ep, ea = error_series(
        run.position[run.ok],
        run.quat[run.ok],
        traj.pos[run.sample[run.ok]],
        traj.quat[run.sample[run.ok]],
    )
    names = {
        REASON_OK: "ok",
        REASON_TOO_FEW_LANDMARKS: "too_few_landmarks",
        REASON_RANSAC_FAILED: "ransac_failed",
        REASON_TOO_FEW_INLIERS: "too_few_inliers",
        REASON_BEHIND_CAMERA: "behind_camera",
    }
    out = {
        "frames": int(run.ok.size),
        "availability": float(run.ok.mean()) if run.ok.size else 0.0,
        "extraction": float(run.n_extracted.sum() / max(run.n_visible.sum(), 1)),
        "matching": float(run.n_correct.sum() / max(run.n_extracted.sum(), 1)),
        "visible_per_frame": float(run.n_visible.mean()) if run.ok.size else 0.0,
        "extracted_per_frame": float(run.n_extracted.mean()) if run.ok.size else 0.0,
        "outcomes": {n: int(np.count_nonzero(run.reason == code)) for code, n in names.items()},
    }
    out.update(error_stats(ep, ea, samples=False))
    gross = (ep > GROSS_POS_M) | (ea > GROSS_ATT_DEG)
    out.update(
        {
            "pos_median_m": float(np.median(ep)) if ep.size else float("nan"),
            "att_median_deg": float(np.median(ea)) if ea.size else float("nan"),
            "gross_fraction": float(gross.mean()) if ep.size else 0.0,
            "pos_clean_m": rms(ep[~gross]),
            "att_clean_deg": rms(ea[~gross]),
        }
    )
    return out


def camera_rng(seed: int, key: int) -> BatchRng:
    return BatchRng([np.random.default_rng([seed, 10 + key])])


#: Order in which the PnP jobs are handed to the workers: the slowest conditions (many frames
#: where RANSAC finds no consensus and runs all its iterations) first, for a balanced finish.
_SOLVE_ORDER = ("complex", "occlusion", "low_light", "noisy", "motion_blur", "ideal")


def _solve_all(caps: dict[str, _Capture], workers: int) -> dict[str, list]:
    """PnP of every captured frame, in ``workers`` threads (1: in this one).

    Threads, not processes: OpenCV releases the GIL inside ``solvePnPRansac``, where ~90 % of
    the time goes (2 threads: 1.8x on 2 cores), and threads need no pickling, no process start
    and no ``if __name__ == "__main__"`` guard in the caller's script. The RANSAC of each call
    is seeded by OpenCV itself, so the poses do not depend on ``workers``.
    """
    if workers == 1:
        return {c: [_solve_block(job) for job in cap.jobs] for c, cap in caps.items()}
    order = sorted(caps, key=lambda c: _SOLVE_ORDER.index(c) if c in _SOLVE_ORDER else -1)
    with ThreadPoolExecutor(workers) as pool:
        futures = {c: [pool.submit(_solve_block, job) for job in caps[c].jobs] for c in order}
        return {c: [f.result() for f in futures[c]] for c in caps}
