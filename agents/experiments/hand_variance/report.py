"""The experiments of :mod:`agents.experiments.hand_variance` and their report: Tables 1-4 at rest
(:func:`static_variance`), the accuracy while the hand sweeps (:func:`moving_accuracy`), both with
the real recording's evidence (:func:`run_hand_variance`) and the printed table
(:func:`format_table`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from agents.experiments.hand_variance.recording import recording_jitter, recording_orientation_noise
from agents.experiments.hand_variance.scores import moving_scores, static_scores
from agents.experiments.hand_variance.settings import (
    DEV_MOVING_SEEDS,
    DEV_STATIC_SEEDS,
    FILTERS,
    PAPER_ANGLES_DEG,
    PAPER_REDUCTION,
)
from agents.experiments.hand_variance.trials import filter_outputs, moving_trial, static_trial
from estimators.hand import PAPER_AXIS_NAMES

__all__ = ["format_table", "moving_accuracy", "run_hand_variance", "static_variance"]

_LABELS = {
    "raw": "raw",
    "kalman": "Kalman",
    "kalman_median": "Kalman + median",
    "one_euro": "One Euro",
    "adaptive_kalman": "adaptive Kalman",
}


def static_variance(repeats: int = 10, seconds: float = 10.0, seed: int = 0) -> dict:
    """Tables 1-4 on the synthetic Kinect: reductions (%), the median's share (percentage
    points), RMSE at rest (deg) and variances (deg^2) per pose, for every filter."""
    trial = static_trial(repeats, seed, seconds)
    res = static_scores(trial, filter_outputs(trial))
    red = res["reduction_pct"]
    res["median_share_pp"] = {
        a: red["kalman_median"][a] - red["kalman"][a] for a in PAPER_AXIS_NAMES
    }
    res.update(
        angles_deg=list(PAPER_ANGLES_DEG),
        repeats=repeats,
        seconds=seconds,
        seed=seed,
        paper=PAPER_REDUCTION,
    )
    return res


def moving_accuracy(
    repeats: int = 10, seconds: float = 10.0, rate_deg_s: float = 90.0, seed: int = 1
) -> dict:
    """RMSE (deg) against the truth and lag (ms) while the hand sweeps at ``rate_deg_s``."""
    trial = moving_trial(repeats, seed, seconds, rate_deg_s)
    res = moving_scores(trial, filter_outputs(trial))
    res.update(rate_deg_s=rate_deg_s, repeats=repeats, seed=seed)
    return res


def run_hand_variance(json_path: Path | None = None, repeats: int = 10, seed: int = 0) -> dict:
    """Both experiments (static seed ``seed``, moving seed ``seed + 1``) and the real
    recording; print the tables beside the paper's, optionally write JSON."""
    held_out = seed not in DEV_STATIC_SEEDS and seed + 1 not in DEV_MOVING_SEEDS
    result = static_variance(repeats=repeats, seed=seed)
    result["moving"] = moving_accuracy(repeats=repeats, seed=seed + 1)
    result["label"] = "held-out" if held_out else "in-sample (a development seed)"
    result["development_seeds"] = {
        "static": list(DEV_STATIC_SEEDS),
        "moving": list(DEV_MOVING_SEEDS),
    }
    result["real_recording"] = recording_jitter()
    result["real_orientation_noise"] = recording_orientation_noise()
    print(format_table(result))
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(result, indent=2))
        print(f"wrote {json_path}")
    return result


def format_table(result: dict) -> str:
    """The printed report of :func:`run_hand_variance`'s result."""
    axes = PAPER_AXIS_NAMES
    cols = "".join(f"{a:>8}" for a in axes)
    mv = result["moving"]
    lines = [
        f"Yao 2023 experiment 2 on the synthetic Kinect v2 ({len(result['angles_deg'])} angles x "
        f"{result['repeats']} repeats x {result['seconds']:.0f} s, seed {result['seed']}; moving "
        f"seed {mv['seed']}): {result['label']} (development seeds: static "
        f"{result['development_seeds']['static']}, moving {result['development_seeds']['moving']})",
        f"at rest: variance reduction vs raw (%) {cols}   | RMSE vs truth (deg) {cols}",
    ]
    red, rmse = result["reduction_pct"], result["rmse_deg"]
    for name in FILTERS:
        row = "".join(f"{red[name][a]:8.1f}" for a in axes)
        err = "".join(f"{rmse[name][a]:8.2f}" for a in axes)
        lines.append(f"  {_LABELS[name]:<37}{row}   | {'':19}{err}")
        if name in result["paper"]:
            lines.append(
                f"  {'  paper: ' + _LABELS[name]:<37}"
                + "".join(f"{result['paper'][name][a]:8.1f}" for a in axes)
            )
    lines.append(
        f"  {'median share (K+M minus K), points':<37}"
        + "".join(f"{result['median_share_pp'][a]:8.1f}" for a in axes)
    )
    raw = result["variance_deg2"]["raw"]
    lines.append(
        f"  {'raw variance, deg^2 (mean of poses)':<37}"
        + "".join(f"{np.mean(raw[a]):8.2f}" for a in axes)
    )
    lines.append(
        f"hand sweeping about the forearm at {mv['rate_deg_s']:.0f} deg/s (swept: "
        f"{mv['swept_axis']}): RMSE vs truth (deg) {cols}   lag"
    )
    for name in FILTERS:
        r = mv[name]
        lines.append(
            f"  {_LABELS[name]:<51}"
            + "".join(f"{r['rmse_deg'][a]:8.2f}" for a in axes)
            + f"   {r['lag_ms']:5.0f} ms"
        )
    real = result.get("real_recording")
    if real is None:
        lines.append(
            "real Kinect v2 recording (kinect_laban): not found, skipped (`vrloco data "
            "fetch kinect` downloads it)"
        )
        return "\n".join(lines)
    lines.append(
        f"real Kinect v2 recording {real['file']} ({real['frames']} frames), Holt "
        "smoothing: jitter = RMS 2nd difference"
    )
    for name in ("wrist_right", "hand_right"):
        r = real[name]
        lines.append(
            f"  {name:<12} {r['jitter_raw_mm']:6.1f} -> {r['jitter_smoothed_mm']:5.1f}"
            f" mm   lag {r['lag_ms']:4.0f} ms"
        )
    ori = result["real_orientation_noise"]
    lines.append(f"  still left forearm's orientation ({ori['frame']}): white share of the jitter")
    for name in ("about_forearm", "about_thumb_axis", "about_normal"):
        r = ori[name]
        lines.append(
            f"    {name:<17} std {r['std_deg']:5.2f} deg, white {r['white_share']:5.0%}"
            f", correlated part tau {r['tau_s']:4.2f} s"
        )
    return "\n".join(lines)
