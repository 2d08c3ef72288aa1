"""Figure: a synthetic head-IMU trace of standing, stepping in place and turning, true steps marked.

Run it with ``vrloco demo --out out`` or ``python examples/imu_trace.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from estimators import rotations as rot
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.imu import HeadImu, get_imu_spec
from vrloco_env.user import MotionParams, run_script


def simulate_imu_trace(seed: int = 0, preset: str = "ig500n"):
    """The ``stand_step_turn`` script of one user and its IMU samples.

    Returns:
        (motion record, IMU samples for user 0 as arrays (N, 3)).
    """
    params = MotionParams()
    rng = BatchRng([np.random.default_rng(seed)])
    record = run_script("stand_step_turn", rng, params)
    imu = HeadImu(get_imu_spec(preset), rng, rate_hz=params.imu_rate_hz)
    imu.reset()
    samples = imu.sample(record.quat, record.omega, record.acc, record.pos)
    return record, samples


def run_imu_trace(out_dir: Path, seed: int = 0, preset: str = "ig500n") -> Path:
    """Draw the figure into ``out_dir/imu_trace.png`` and return its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    record, s = simulate_imu_trace(seed, preset)
    t = record.t
    acc, gyr, mag = s.acc[0], s.gyr[0], s.mag[0]
    steps = record.step_times[0]
    fnorm = np.linalg.norm(acc, axis=-1) / rot.GRAVITY

    fig, axes = plt.subplots(4, 1, figsize=(11, 9), sharex=True, constrained_layout=True)
    phases = [
        (0, 3, "standing"),
        (3, 8, "stepping in place"),
        (8, 12, "stepping + turning 45°/s"),
        (12, 15, "stepping"),
        (15, 18, "standing"),
    ]
    for ax in axes:
        for k, (a, b, _) in enumerate(phases):
            if k % 2:
                ax.axvspan(a, b, color="0.93", lw=0)
    for a, b, label in phases:
        axes[0].text(
            (a + b) / 2,
            1.02,
            label,
            transform=axes[0].get_xaxis_transform(),
            ha="center",
            va="bottom",
            fontsize=8,
        )

    axes[0].plot(t, fnorm, lw=0.8, color="k", label="|f| (g)")
    axes[0].plot(
        steps,
        np.interp(steps, t, fnorm),
        "v",
        color="tab:red",
        ms=5,
        label=f"true heel strikes ({steps.size})",
    )
    axes[0].set_ylabel("|specific force| (g)")
    axes[0].legend(loc="upper left", fontsize=8)
    for i, c in enumerate("xyz"):
        axes[1].plot(t, acc[:, i], lw=0.7, label=f"f_{c}")
        axes[2].plot(t, np.rad2deg(gyr[:, i]), lw=0.7, label=f"ω_{c}")
        axes[3].plot(t, mag[:, i], lw=0.7, label=f"m_{c}")
    axes[1].set_ylabel("accelerometer (m/s²)")
    axes[2].set_ylabel("gyroscope (°/s)")
    axes[3].set_ylabel("magnetometer (µT)")
    axes[3].set_xlabel("time (s)")
    for ax in axes[1:]:
        ax.legend(loc="upper left", fontsize=8, ncol=3)
    for ax in axes:
        for st in steps:
            ax.axvline(st, color="tab:red", lw=0.4, alpha=0.35)
    fig.suptitle(f"Synthetic head IMU ({preset}, 100 Hz): stand, step in place, turn — seed {seed}")
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "imu_trace.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
