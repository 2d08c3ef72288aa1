"""Eq (17) against the smooth-locomotion filter (the smooth-locomotion paper): distance kept, jerk
removed.

:func:`compare_locomotion` runs both models on the same step events; :func:`run_locomotion_table`
prints its table. Run: ``vrloco experiment locomotion [--json PATH]``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.locomotion import DeadReckoning, SmoothLocomotion, SmoothParams


def _rms_jerk(pos: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
    """RMS over time of |d^3 p / dt^3| by third differences, for paths (B, N, 2)."""
    j = np.diff(pos, n=3, axis=1) / dt**3
    return np.sqrt(np.mean(np.sum(j * j, axis=-1), axis=1))


def compare_locomotion(
    cadences: ArrayLike = (1.2, 1.7, 2.2),
    n_steps: int = 20,
    step_length: float = 0.7,
    fs: float = 100.0,
    turn_deg: float = 0.0,
    latency: float = 0.135,
    params: SmoothParams | None = None,
) -> dict[str, NDArray[np.float64]]:
    """Eq (17) against :class:`SmoothLocomotion` on the same step events (one user per cadence).

    Each user stands 1 s, takes ``n_steps`` steps at its cadence (heel strikes at 1 s + k /
    cadence), and stands 4 s more. The step events reach the locomotion models as the gait
    detector delivers them: ``latency`` s after each heel strike, the first step of the bout
    together with the second. The yaw turns linearly by ``turn_deg`` over the steps. Both models
    update at ``fs``; the jerk is the third difference of the position sampled at ``fs``.

    Args:
        cadences: steps/s, one user each, in [0.5, 3.5].
        n_steps: steps per user, >= 2.
        step_length: SL (m).
        fs: update and sampling rate (Hz), in [10, 1000].
        turn_deg: total heading change over the walk (deg).
        latency: detector latency (s), in [0, 1].
        params: smooth filter parameters.

    Returns:
        Arrays (B,) keyed ``cadence`` (steps/s), ``distance_eq17`` and ``distance_smooth`` (m,
        path length at the end), ``distance_error_pct`` (smooth vs eq 17, %),
        ``end_gap`` (m, distance between the two final positions), ``rms_jerk_eq17`` and
        ``rms_jerk_smooth`` (m/s^3), ``jerk_ratio`` (eq 17 / smooth), ``max_speed_smooth``
        (m/s), ``stop_time`` (s from the last event until the smooth speed is below 1 cm/s).
    """
    c = np.atleast_1d(np.asarray(cadences, dtype=np.float64))
    if c.ndim != 1 or not np.all(np.isfinite(c)) or np.any((c < 0.5) | (c > 3.5)):
        raise ValueError("cadences must be a 1-D array of steps/s in [0.5, 3.5]")
    if not isinstance(n_steps, int | np.integer) or n_steps < 2:
        raise ValueError(f"n_steps must be an integer >= 2, got {n_steps!r}")
    if not (10.0 <= fs <= 1000.0):
        raise ValueError(f"fs must be in [10, 1000] Hz, got {fs!r}")
    if not (0.0 <= latency <= 1.0):
        raise ValueError(f"latency must be in [0, 1] s, got {latency!r}")
    b = c.size
    dt = 1.0 / fs
    walk = (n_steps - 1) / c  # s from the first to the last heel strike
    duration = 1.0 + float(walk.max()) + latency + 4.0
    n = round(duration * fs)
    t = (np.arange(n) + 1) * dt
    strikes = 1.0 + np.arange(n_steps)[None, :] / c[:, None]  # (B, S)
    confirm = strikes + latency
    confirm[:, 0] = confirm[:, 1]  # the first step is released with the second
    idx = np.minimum(np.ceil(confirm * fs - 1e-9).astype(int) - 1, n - 1)
    counts = np.zeros((b, n))
    np.add.at(counts, (np.repeat(np.arange(b), n_steps), idx.ravel()), 1.0)
    frac = np.clip((t[None, :] - 1.0) / walk[:, None], 0.0, 1.0)
    yaw = np.deg2rad(turn_deg) * frac
    eq17 = DeadReckoning(b, step_length)
    smooth = SmoothLocomotion(b, step_length, params=params)
    pe = np.empty((b, n, 2))
    ps = np.empty((b, n, 2))
    speed = np.empty((b, n))
    for k in range(n):  # time loop; every user at once
        pe[:, k] = eq17.update(counts[:, k], yaw[:, k], dt)
        ps[:, k] = smooth.update(counts[:, k], yaw[:, k], dt)
        speed[:, k] = smooth.speed
    d17, dsm = eq17.distance, smooth.distance
    last = confirm.max(axis=1)
    moving = np.abs(speed) >= 0.01
    last_moving = np.where(moving.any(axis=1), n - 1 - np.argmax(moving[:, ::-1], axis=1), 0)
    stop_time = t[last_moving] - last
    jerk17, jerks = _rms_jerk(pe, dt), _rms_jerk(ps, dt)
    return {
        "cadence": c,
        "distance_eq17": d17,
        "distance_smooth": dsm,
        "distance_error_pct": 100.0 * (dsm - d17) / d17,
        "end_gap": np.linalg.norm(ps[:, -1] - pe[:, -1], axis=-1),
        "rms_jerk_eq17": jerk17,
        "rms_jerk_smooth": jerks,
        "jerk_ratio": jerk17 / jerks,
        "max_speed_smooth": speed.max(axis=1),
        "stop_time": stop_time,
    }


def run_locomotion_table(json_path: Path | None = None, n_steps: int = 20) -> dict:
    """Print the table at the IMU rate (100 Hz) and at the env's control rate (10 Hz)."""
    result = {}
    lines = [
        f"{n_steps} steps of 0.7 m, detector latency 0.135 s; smooth vs eq (17)",
        f"{'rate':>6} {'cadence':>8} {'dist eq17':>10} {'dist smooth':>12} {'error':>7} "
        f"{'RMS jerk eq17':>14} {'smooth':>8} {'ratio':>7} {'stop':>6}",
    ]
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
    lines.append(
        "jerk in m/s^3 (third difference of the path at that rate); stop: s from the last "
        "step event until the smooth speed < 1 cm/s"
    )
    print("\n".join(lines))
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(result, indent=2))
        print(f"wrote {json_path}")
    return result
