"""The camera calibration of the helmet-tracking paper's experiment: the pixel-noise scale at which
the ideal camera's visual-only error matches the paper's, on the development seeds
(:func:`calibrate_camera`; the value in use is
:data:`~agents.experiments.vio.settings.PIXEL_NOISE_SCALE`).
"""

from __future__ import annotations

import math

import numpy as np

from agents.experiments.vio.metrics import error_series, rms
from agents.experiments.vio.mismatch import Mismatch, make_setup
from agents.experiments.vio.settings import (
    CALIBRATION_DURATION_S,
    CALIBRATION_SEEDS,
    GROSS_ATT_DEG,
    GROSS_POS_M,
    PAPER,
    condition_spec,
    pnp_params,
)
from agents.experiments.vio.trajectories import simulate
from agents.experiments.vio.visual import camera_rng, capture_visual
from vrloco_env.sensors.camera import camera_spec

__all__ = ["calibrate_camera"]


def _calibration_error(scale: float, runs: list) -> tuple[float, float, float]:
    """Clean visual-only RMSE (m, deg) of the ideal camera at ``scale`` over the development
    runs (pooled frames) and the log of the geometric mean of their ratios to the paper's."""
    ep, ea = [], []
    for traj, setup, seed in runs:
        spec = condition_spec("ideal", scale)
        run = capture_visual(traj, spec, camera_rng(seed, 0), setup, pnp_params(spec), workers=2)
        e_p, e_a = error_series(
            run.position[run.ok],
            run.quat[run.ok],
            traj.pos[run.sample[run.ok]],
            traj.quat[run.sample[run.ok]],
        )
        good = (e_p <= GROSS_POS_M) & (e_a <= GROSS_ATT_DEG)
        ep.append(e_p[good])
        ea.append(e_a[good])
    pos, att = rms(np.concatenate(ep)), rms(np.concatenate(ea))
    paper = PAPER["visual_only"]["ideal"]
    return pos, att, 0.5 * (math.log(pos / paper["pos_m"]) + math.log(att / paper["att_deg"]))


def calibrate_camera(
    seeds: tuple[int, ...] = CALIBRATION_SEEDS,
    duration: float = CALIBRATION_DURATION_S,
    mismatch: Mismatch | None = None,
    iterations: int = 6,
) -> dict:
    """The pixel-noise scale at which the ideal camera's visual-only error matches the
    helmet-tracking paper's.

    The target is the paper's own visual-only accuracy (+-0.05 m, +-1 deg, ideal conditions),
    read as the RMSE without gross errors (the ``pos_clean_m`` / ``att_clean_deg`` of
    :func:`visual_stats`), on the walks of the development ``seeds`` with their mismatch draws.
    One parameter cannot hit two numbers: it zeroes the mean of ``log(pos / 0.05 m)`` and
    ``log(att / 1 deg)`` (secant steps on ``log(scale)``, from 1 and 4).

    Returns:
        ``{"pixel_noise_scale", "pixel_noise_px" (ideal camera), "pos_m", "att_deg", "seeds",
        "duration_s", "steps"}``: the last step's scale and its development-set errors.
    """
    runs = []
    for seed in seeds:
        setup = make_setup(seed, mismatch)
        runs.append((simulate("walk", duration, seed, setup), setup, seed))
    xs = [0.0, math.log(4.0)]
    fs = [_calibration_error(math.exp(x), runs) for x in xs]
    for _ in range(iterations):
        (x0, x1), (f0, f1) = xs[-2:], (fs[-2][2], fs[-1][2])
        if abs(f1) < 0.005 or f1 == f0:
            break
        x2 = min(max(x1 - f1 * (x1 - x0) / (f1 - f0), math.log(0.1)), math.log(100.0))
        xs.append(x2)
        fs.append(_calibration_error(math.exp(x2), runs))
    scale = math.exp(xs[-1])
    pos, att, _ = fs[-1]
    return {
        "pixel_noise_scale": scale,
        "pixel_noise_px": camera_spec("ideal").pixel_noise_px * scale,
        "pos_m": pos,
        "att_deg": att,
        "seeds": list(seeds),
        "duration_s": duration,
        "steps": [
            {"scale": math.exp(x), "pos_m": f[0], "att_deg": f[1]}
            for x, f in zip(xs, fs, strict=True)
        ],
    }
