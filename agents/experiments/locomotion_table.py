"""Eq (17) against the smooth-locomotion filter (seed 001): distance kept, jerk removed.

Run: ``vrloco experiment locomotion [--json PATH]``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from estimators.locomotion import compare_locomotion


def run_locomotion_table(json_path: Path | None = None, n_steps: int = 20) -> dict:
    """Print the table at the IMU rate (100 Hz) and at the env's control rate (10 Hz)."""
    result = {}
    lines = [f"{n_steps} steps of 0.7 m, detector latency 0.135 s; smooth vs eq (17)",
             f"{'rate':>6} {'cadence':>8} {'dist eq17':>10} {'dist smooth':>12} {'error':>7} "
             f"{'RMS jerk eq17':>14} {'smooth':>8} {'ratio':>7} {'stop':>6}"]  # fmt: skip
    for fs in (100.0, 10.0):
        r = compare_locomotion(n_steps=n_steps, fs=fs)
        result[f"{fs:.0f}hz"] = {k: np.asarray(v).tolist() for k, v in r.items()}
        for i, c in enumerate(r["cadence"]):
            row = {k: v[i] for k, v in r.items()}
            lines.append(
                f"{fs:4.0f}Hz {c:8.1f} {row['distance_eq17']:9.2f}m "
                f"{row['distance_smooth']:11.2f}m {row['distance_error_pct']:+6.2f}% "
                f"{row['rms_jerk_eq17']:12.0f}   {row['rms_jerk_smooth']:8.1f} "
                f"{row['jerk_ratio']:6.0f}x {row['stop_time']:5.2f}s"
            )
    lines.append("jerk in m/s^3 (third difference of the path at that rate); stop: s from the last "
                 "step event until the smooth speed < 1 cm/s")  # fmt: skip
    print("\n".join(lines))
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(result, indent=2))
        print(f"wrote {json_path}")
    return result
