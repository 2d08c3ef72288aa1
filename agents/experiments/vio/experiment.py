"""The helmet-tracking paper's experiment in one call (:func:`run_vio`): the IMU-only runs, the
visual-only and fused runs of every condition on the walk, adaptive against fixed R, the targets,
and the table, JSON and figure (:mod:`agents.experiments.vio`).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

from agents.experiments.vio.fusion import fuse, fused_stats
from agents.experiments.vio.mismatch import Mismatch, make_setup
from agents.experiments.vio.report import format_table, vio_figure
from agents.experiments.vio.settings import (
    CALIBRATION_SEEDS,
    CAMERA_RATE_HZ,
    IMU_PRESET,
    IMU_RATE_HZ,
    NOISY_FACTOR,
    PAPER,
    PIXEL_NOISE_SCALE,
    ROTATION_RATE_DEG_S,
    TARGETS,
    VISUAL_CONDITIONS,
    WALK_CADENCE,
    WALK_RADIUS_M,
    WINDOW_S,
    condition_spec,
    filter_config,
    pnp_params,
)
from agents.experiments.vio.trajectories import STRIDE_M, imu_only, simulate
from agents.experiments.vio.visual import (
    VisualRun,
    _assemble,
    _capture,
    _solve_all,
    camera_rng,
    visual_stats,
)
from vrloco_env.sensors.camera import camera_spec

__all__ = ["run_vio"]


def run_vio(
    json_path: Path | None = None,
    duration: float = 120.0,
    seed: int = 0,
    out_dir: Path | None = None,
    workers: int = 2,
    verbose: bool = True,
    mismatch: Mismatch | None = None,
    pixel_noise_scale: float = PIXEL_NOISE_SCALE,
) -> dict:
    """All of the helmet-tracking paper's experiments; print the table beside the paper's,
    optionally write JSON and (with ``out_dir``) a figure of the errors over time.

    Args:
        json_path: where to write the results (JSON); None: not written.
        duration: length of every run, s, in [4, 600] and a multiple of 0.1 s (paper: 120).
        seed: random seed (not one of :data:`CALIBRATION_SEEDS` for held-out numbers).
        out_dir: folder for ``vio_errors.png``; None: no figure.
        workers: threads for the PnP (1: all in the calling thread).
        verbose: print the table.
        mismatch: the model mismatch drawn for the run; None: :class:`Mismatch` defaults
            (``Mismatch.none()``: the estimators told the simulator's truth).
        pixel_noise_scale: the cameras' pixel noise over the presets' (default: calibrated).

    Returns:
        The result dictionary (package docstring; ``pos_m`` / ``att_deg`` of the visual and fused
        rows are RMSEs, of the IMU-only rows the largest errors).
    """
    duration = float(duration)
    if not (4.0 <= duration <= 600.0) or abs(duration * 10 - round(duration * 10)) > 1e-6:
        raise ValueError(f"duration must be in [4, 600] s and a multiple of 0.1 s, got {duration}")
    if not (isinstance(workers, int) and workers >= 1):
        raise ValueError(f"workers must be an int >= 1, got {workers!r}")
    workers = min(workers, os.cpu_count() or 1)
    setup = make_setup(seed, mismatch)
    specs = {c: condition_spec(c, pixel_noise_scale) for c in VISUAL_CONDITIONS}
    noisy_px = NOISY_FACTOR * specs["ideal"].pixel_noise_px
    noisy_spec = camera_spec("low_light", name="noisy", pixel_noise_px=noisy_px)
    noisy_pnp = pnp_params(noisy_spec)
    result: dict = {
        "config": {
            "duration_s": duration,
            "seed": seed,
            "imu": IMU_PRESET,
            "imu_rate_hz": IMU_RATE_HZ,
            "camera_rate_hz": CAMERA_RATE_HZ,
            "rotation_rate_deg_s": ROTATION_RATE_DEG_S,
            "walk": {
                "radius_m": WALK_RADIUS_M,
                "cadence_hz": WALK_CADENCE,
                "speed_m_s": STRIDE_M * WALK_CADENCE,
            },
            "room": "approach, 8 m x 8 m, 96 wall landmarks",
            "window_s": WINDOW_S,
            "pixel_noise_scale": pixel_noise_scale,
            "pixel_noise_px": {c: sp.pixel_noise_px for c, sp in specs.items()},
            "ransac_px": {c: pnp_params(sp).reprojection_px for c, sp in specs.items()},
            "calibration_seeds": list(CALIBRATION_SEEDS),
            "held_out": seed not in CALIBRATION_SEEDS,
            "complex_camera": {
                "condition": "low_light",
                "occluder_fraction": 0.3,
                "match_prob": specs["complex"].match_prob,
            },
            "adaptive_noisy_camera": {
                "condition": "low_light",
                "pixel_noise_px": noisy_px,
                "reprojection_px": noisy_pnp.reprojection_px,
                "switch_s": duration / 2,
            },
            "setup": setup.summary(),
            "errors": "visual/fused pos_m, att_deg: RMSE; imu_only: largest over the run",
        },
        "paper": PAPER,
    }
    # IMU only.
    series: dict = {}
    result["imu_only"] = {}
    for kind in ("static", "rotation"):
        r = imu_only(simulate(kind, duration, seed, setup))
        series[f"imu_{kind}"] = r.pop("_series")
        result["imu_only"][kind] = r
    b = PAPER["imu_only"]["accel_accuracy_m_s2"]
    result["imu_only"]["paper_position_check"] = {
        "accel_accuracy_m_s2": b,
        "duration_s": 120.0,
        "position_from_bias_m": 0.5 * b * 120.0**2,
        "bias_for_0p2_m_m_s2": 2 * 0.2 / 120.0**2,
    }

    # Visual and fused on the walk.
    traj = simulate("walk", duration, seed, setup)
    half = traj.t.size // 2
    caps = {
        c: _capture(traj, specs[c], camera_rng(seed, i), setup, pnp_params(specs[c]), 0)
        for i, c in enumerate(VISUAL_CONDITIONS)
    }
    caps["noisy"] = _capture(traj, noisy_spec, camera_rng(seed, 99), setup, noisy_pnp, half)
    solved = _solve_all(caps, workers)
    runs = {c: _assemble(caps[c], solved[c]) for c in VISUAL_CONDITIONS}
    noisy = _assemble(caps["noisy"], solved["noisy"])
    result["visual_only"] = {c: visual_stats(r, traj) for c, r in runs.items()}
    result["fused"], result["fused_fixed"] = {}, {}
    for c, r in runs.items():
        for name, adaptive in (("fused", "sage_husa"), ("fused_fixed", "fixed")):
            p, q, counters = fuse(traj, r, filter_config(adaptive))
            stats, ser = fused_stats(traj, p, q, counters["start"])
            result[name][c] = {**stats, **counters, "start_s": counters["start"] / IMU_RATE_HZ}
            if c in ("ideal", "complex"):
                series[f"{name}_{c}"] = ser

    # Adaptive vs fixed R: ideal frames before the switch, the noisy camera after it.
    ideal = runs["ideal"]
    first = ideal.sample < half
    mixed = VisualRun.concatenate([ideal.select(first), noisy])
    tuned = visual_stats(ideal.select(first), traj)
    sig_p, sig_a = tuned["pos_clean_m"] / math.sqrt(3), tuned["att_clean_deg"] / math.sqrt(3)
    result["adaptive"] = {
        "switch_s": float(traj.t[half]),
        "tuned_r": {"position_sigma_m": sig_p, "attitude_sigma_deg": sig_a},
        "visual_after_switch": visual_stats(noisy, traj),
    }
    for adaptive in ("fixed", "sage_husa"):
        p, q, counters = fuse(traj, mixed, filter_config(adaptive, sig_p, sig_a))
        after, ser = fused_stats(traj, p, q, counters["start"], lo=half, samples=False)
        overall, _ = fused_stats(traj, p, q, counters["start"], samples=False)
        before, _ = fused_stats(traj, p, q, counters["start"], hi=half, samples=False)
        result["adaptive"][adaptive] = {
            "pos_m": after["pos_m"],
            "att_deg": after["att_deg"],
            "pos_p95_m": after["pos_p95_m"],
            "att_p95_deg": after["att_p95_deg"],
            "overall_pos_m": overall["pos_m"],
            "overall_att_deg": overall["att_deg"],
            "before_pos_m": before["pos_m"],
            "before_att_deg": before["att_deg"],
            **counters,
        }
        series[f"adaptive_{adaptive}"] = ser

    # Targets.
    met = {}
    for c, tgt in TARGETS.items():
        r = result["fused"][c]
        met[f"fused_{c}"] = bool(r["pos_m"] < tgt["pos_m"] and r["att_deg"] < tgt["att_deg"])
        met[f"fused_{c}_bounded"] = bool(
            r["pos_window_max_m"] < tgt["pos_m"] and r["att_window_max_deg"] < tgt["att_deg"]
        )
    a = result["adaptive"]
    met["adaptive_beats_fixed"] = bool(
        a["sage_husa"]["pos_m"] < a["fixed"]["pos_m"]
        and a["sage_husa"]["att_deg"] < a["fixed"]["att_deg"]
    )
    met["fused_beats_visual_ideal"] = bool(
        result["fused"]["ideal"]["pos_m"] < result["visual_only"]["ideal"]["pos_clean_m"]
        and result["fused"]["ideal"]["att_deg"] < result["visual_only"]["ideal"]["att_clean_deg"]
    )
    result["targets"] = TARGETS
    result["targets_met"] = met

    if verbose:
        print(format_table(result))
    if json_path is not None:
        json_path = Path(json_path)
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(_finite(result), indent=2, allow_nan=False))
        if verbose:
            print(f"wrote {json_path}")
    if out_dir is not None:
        path = vio_figure(series, traj.t, Path(out_dir), result["adaptive"]["switch_s"])
        result["figure"] = str(path)
        if verbose:
            print(f"wrote {path}")
    return result


def _finite(x: object) -> object:
    """``x`` with NaN and infinities replaced by None (strict JSON)."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_finite(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x
